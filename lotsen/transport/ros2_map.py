"""lotsen messages <-> ROS 2 messages (rosbags objects of `ros2_types.typestore()`), for the ROS 2
mode of the Zenoh transport and the ROS 2 bag export.

| lotsen | ROS 2 | notes |
|---|---|---|
| ImuSample | sensor_msgs/msg/Imu | FRD -> FLU (codec), orientation_covariance[0] = -1 |
| MagSample | sensor_msgs/msg/MagneticField | uT -> T, FLU |
| GnssFix | sensor_msgs/msg/NavSatFix | fix type from status on the way back |
| VesselState | nav_msgs/msg/Odometry | frame map (ENU), child base_link (FLU) |
| PathMessage | nav_msgs/msg/Path | ENU poses, yaw along the path; the speed profile is not carried |
| ThrustCommand | lotsen_msgs/msg/ShipCommand | seed conventions |
| VelocityCommand, AngleCommand | lotsen_msgs/msg/VelocityCommand, AngleCommand | seed Table 3 |
| SupervisorStatus | lotsen_msgs/msg/SupervisorStatus | |
| OperatorCommand | lotsen_msgs/msg/OperatorCommand | inbound: authorised by the bridge |
| BatteryStatus | sensor_msgs/msg/BatteryState | NaN where unknown |
| LogEvent | rcl_interfaces/msg/Log | data appended to msg as JSON |
| anything else | lotsen_msgs/msg/JsonMessage | lotsen's JSON form, exact |

Stamps: `header.stamp = stamp_s + stamp_offset_s` (the bridge passes the runtime clock's Unix epoch
at start, so ROS 2 sees wall time; 0 in simulation, where ROS would use sim time).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Any, Callable

from lotsen import messages as M
from lotsen.transport import codec
from lotsen.transport.ros2_types import typestore

JSON_TYPE = "lotsen_msgs/msg/JsonMessage"


def _T() -> Any:
    return typestore().types


def _header(stamp_s: float, frame: str = "") -> Any:
    return codec._header(stamp_s, frame)


def _stamp_s(header: Any) -> float:
    return codec._stamp_s(header)


# ---------------------------------------------------------------------------- converters
def _cdr_to(msg: Any) -> Any:
    return codec._to_ros(msg)[0]


def _cdr_from(name: str) -> Callable[[Any], Any]:
    return lambda ros: codec._from_ros(name, ros, {})


def _state_from(ros: Any) -> M.VesselState:
    st = codec._from_ros("VesselState", ros, {})
    pc, tc = ros.pose.covariance, ros.twist.covariance
    var = [pc[7], pc[0], pc[35], tc[0], tc[7], tc[35]]  # ENU y = north, x = east; twist u, v, r
    if any(v > 0 for v in var):
        st.std = tuple(math.sqrt(max(v, 0.0)) for v in var)
    return st


def _path_to(msg: M.PathMessage) -> Any:
    T = _T()
    n, e = list(msg.north_m), list(msg.east_m)
    poses = []
    for i in range(len(n)):
        j0, j1 = (i, i + 1) if i + 1 < len(n) else (i - 1, i)
        yaw_enu = math.atan2(n[j1] - n[j0], e[j1] - e[j0]) if len(n) > 1 else 0.0
        poses.append(T["geometry_msgs/msg/PoseStamped"](
            header=_header(msg.stamp_s, codec.WORLD_FRAME),
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=float(e[i]), y=float(n[i]), z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw_enu / 2),
                                                              w=math.cos(yaw_enu / 2)))))
    return T["nav_msgs/msg/Path"](header=_header(msg.stamp_s, codec.WORLD_FRAME), poses=poses)


def _path_from(ros: Any) -> M.PathMessage:
    return M.PathMessage(stamp_s=_stamp_s(ros.header), north_m=tuple(p.pose.position.y for p in ros.poses),
                         east_m=tuple(p.pose.position.x for p in ros.poses),
                         speed_mps=tuple(math.nan for _ in ros.poses))


def _ship_to(msg: M.ThrustCommand) -> Any:
    return _T()["lotsen_msgs/msg/ShipCommand"](
        header=_header(msg.stamp_s, codec.BODY_FRAME), alpha1_rad=msg.alpha1_rad, alpha2_rad=msg.alpha2_rad,
        n1_rps=msg.n1_rps, n2_rps=msg.n2_rps, nt_rps=msg.nt_rps, source=msg.source)


def _ship_from(ros: Any) -> M.ThrustCommand:
    return M.ThrustCommand(stamp_s=_stamp_s(ros.header), alpha1_rad=ros.alpha1_rad, alpha2_rad=ros.alpha2_rad,
                           n1_rps=ros.n1_rps, n2_rps=ros.n2_rps, nt_rps=ros.nt_rps, source=ros.source)


def _vel_to(msg: M.VelocityCommand) -> Any:
    return _T()["lotsen_msgs/msg/VelocityCommand"](header=_header(msg.stamp_s, codec.BODY_FRAME), n1_rps=msg.n1_rps,
                                                   n2_rps=msg.n2_rps, nt_rps=msg.nt_rps, source=msg.source)


def _vel_from(ros: Any) -> M.VelocityCommand:
    return M.VelocityCommand(stamp_s=_stamp_s(ros.header), n1_rps=ros.n1_rps, n2_rps=ros.n2_rps, nt_rps=ros.nt_rps,
                             source=ros.source)


def _angle_to(msg: M.AngleCommand) -> Any:
    return _T()["lotsen_msgs/msg/AngleCommand"](header=_header(msg.stamp_s, codec.BODY_FRAME),
                                                alpha1_rad=msg.alpha1_rad, alpha2_rad=msg.alpha2_rad, source=msg.source)


def _angle_from(ros: Any) -> M.AngleCommand:
    return M.AngleCommand(stamp_s=_stamp_s(ros.header), alpha1_rad=ros.alpha1_rad, alpha2_rad=ros.alpha2_rad,
                          source=ros.source)


def _status_to(msg: M.SupervisorStatus) -> Any:
    return _T()["lotsen_msgs/msg/SupervisorStatus"](
        header=_header(msg.stamp_s), mode=msg.mode, reason=msg.reason, armed=bool(msg.armed),
        escs_armed=bool(msg.escs_armed), warnings=list(msg.warnings), active_failsafes=list(msg.active_failsafes),
        available_actions=list(msg.available_actions), blocked_actions=list(msg.blocked_actions),
        route_id=msg.route_id)


def _status_from(ros: Any) -> M.SupervisorStatus:
    return M.SupervisorStatus(stamp_s=_stamp_s(ros.header), mode=ros.mode, reason=ros.reason, armed=bool(ros.armed),
                              warnings=tuple(ros.warnings), active_failsafes=tuple(ros.active_failsafes),
                              escs_armed=bool(ros.escs_armed), available_actions=tuple(ros.available_actions),
                              blocked_actions=tuple(ros.blocked_actions), route_id=ros.route_id)


def _operator_to(msg: M.OperatorCommand) -> Any:
    # never carries a token outwards: the echo of an accepted command must not leak it
    return _T()["lotsen_msgs/msg/OperatorCommand"](header=_header(msg.stamp_s), action=msg.action, pilot_token="",
                                                   client=msg.source)


def _operator_from(ros: Any) -> M.OperatorCommand:
    """Plain decoding (source = the client field); the bridge authorises and sets the source."""
    return M.OperatorCommand(stamp_s=_stamp_s(ros.header), action=ros.action, source=ros.client)


def _battery_to(msg: M.BatteryStatus) -> Any:
    T = _T()
    B = T["sensor_msgs/msg/BatteryState"]
    import numpy as np

    return B(header=_header(msg.stamp_s), voltage=msg.voltage_v, temperature=math.nan, current=msg.current_a,
             charge=math.nan, capacity=math.nan, design_capacity=math.nan, percentage=msg.remaining_frac,
             power_supply_status=B.POWER_SUPPLY_STATUS_UNKNOWN, power_supply_health=B.POWER_SUPPLY_HEALTH_UNKNOWN,
             power_supply_technology=B.POWER_SUPPLY_TECHNOLOGY_UNKNOWN, present=True,
             cell_voltage=np.zeros(0, dtype=np.float32), cell_temperature=np.zeros(0, dtype=np.float32),
             location="", serial_number="")


def _battery_from(ros: Any) -> M.BatteryStatus:
    return M.BatteryStatus(stamp_s=_stamp_s(ros.header), voltage_v=float(ros.voltage), current_a=float(ros.current),
                           remaining_frac=float(ros.percentage))


_LEVELS = {"debug": 10, "info": 20, "warning": 30, "warn": 30, "error": 40, "critical": 50, "fatal": 50}
_LEVEL_NAMES = {10: "debug", 20: "info", 30: "warning", 40: "error", 50: "critical"}


def _log_to(msg: M.LogEvent) -> Any:
    T = _T()
    text = msg.text
    if msg.data:
        text += " " + json.dumps(codec._value_out(msg.data), separators=(",", ":"), allow_nan=False)
    return T["rcl_interfaces/msg/Log"](stamp=codec._stamp(T, msg.stamp_s), level=_LEVELS.get(msg.level.lower(), 20),
                                       name=msg.source, msg=text, file="", function="", line=0)


def _log_from(ros: Any) -> M.LogEvent:
    return M.LogEvent(stamp_s=ros.stamp.sec + ros.stamp.nanosec * 1e-9, level=_LEVEL_NAMES.get(int(ros.level), "info"),
                      source=ros.name, text=ros.msg)


def _json_to(msg: Any) -> Any:
    return _T()[JSON_TYPE](header=_header(getattr(msg, "stamp_s", 0.0)), lotsen_type=type(msg).__name__,
                           json=codec.encode_json(msg).decode("utf-8"))


def _json_from(ros: Any) -> Any:
    return codec.decode_json(ros.lotsen_type, ros.json)


# ---------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class RosMapping:
    ros_type: str
    to_ros: Callable[[Any], Any]
    from_ros: Callable[[Any], Any]


MAPPINGS: dict[type, RosMapping] = {
    M.ImuSample: RosMapping("sensor_msgs/msg/Imu", _cdr_to, _cdr_from("ImuSample")),
    M.MagSample: RosMapping("sensor_msgs/msg/MagneticField", _cdr_to, _cdr_from("MagSample")),
    M.GnssFix: RosMapping("sensor_msgs/msg/NavSatFix", _cdr_to, _cdr_from("GnssFix")),
    M.VesselState: RosMapping("nav_msgs/msg/Odometry", _cdr_to, _state_from),
    M.PathMessage: RosMapping("nav_msgs/msg/Path", _path_to, _path_from),
    M.ThrustCommand: RosMapping("lotsen_msgs/msg/ShipCommand", _ship_to, _ship_from),
    M.VelocityCommand: RosMapping("lotsen_msgs/msg/VelocityCommand", _vel_to, _vel_from),
    M.AngleCommand: RosMapping("lotsen_msgs/msg/AngleCommand", _angle_to, _angle_from),
    M.SupervisorStatus: RosMapping("lotsen_msgs/msg/SupervisorStatus", _status_to, _status_from),
    M.OperatorCommand: RosMapping("lotsen_msgs/msg/OperatorCommand", _operator_to, _operator_from),
    M.BatteryStatus: RosMapping("sensor_msgs/msg/BatteryState", _battery_to, _battery_from),
    M.LogEvent: RosMapping("rcl_interfaces/msg/Log", _log_to, _log_from),
}
JSON_MAPPING = RosMapping(JSON_TYPE, _json_to, _json_from)

# The lotsen topics whose message class is fixed (so a subscription knows its ROS type before any
# message arrives). Topics not listed are published with the type of the messages sent on them.
TOPIC_CLASSES: dict[str, type] = {
    M.Topic.IMU_RAW: M.ImuSample, M.Topic.IMU_MAG: M.MagSample, M.Topic.GNSS: M.GnssFix,
    M.Topic.STATE: M.VesselState, M.Topic.SENS_FUS: M.VesselState, M.Topic.TRUTH: M.VesselState,
    M.Topic.PATH: M.PathMessage, M.Topic.SHIP_COMMAND: M.ThrustCommand, M.Topic.EXPERIMENT_COMMAND: M.ThrustCommand,
    M.Topic.VELOCITY_COMMAND: M.VelocityCommand, M.Topic.ANGLE_COMMAND: M.AngleCommand,
    M.Topic.SUPERVISOR: M.SupervisorStatus, M.Topic.OPERATOR: M.OperatorCommand, M.Topic.BATTERY: M.BatteryStatus,
    M.Topic.LOG: M.LogEvent, M.Topic.IMU_MAG_CALIBRATED: M.MagCalibrated, M.Topic.RPM: M.RpmSample,
    M.Topic.CONTROL_STATUS: M.ControllerStatus, M.Topic.ACTUATORS: M.ActuatorState, M.Topic.ALERT: M.Alert,
    M.Topic.PROGRESS: M.MissionProgress, M.Topic.MANUAL: M.ManualCommand, M.Topic.RC: M.RcOverride,
}


def mapping_for(cls: type) -> RosMapping:
    return MAPPINGS.get(cls, JSON_MAPPING)


def ros_type_for(cls: type) -> str:
    return mapping_for(cls).ros_type


def _shift(msg: Any, dt: float) -> Any:
    if dt == 0.0 or not hasattr(msg, "stamp_s"):
        return msg
    return dataclasses.replace(msg, stamp_s=msg.stamp_s + dt)


def to_ros(msg: Any, stamp_offset_s: float = 0.0) -> tuple[str, Any]:
    """(ROS type, ROS message object) for a lotsen message."""
    m = mapping_for(type(msg))
    return m.ros_type, m.to_ros(_shift(msg, stamp_offset_s))


def from_ros(ros_type: str, ros: Any, stamp_offset_s: float = 0.0) -> Any:
    """The lotsen message for a ROS message of a mapped type (KeyError for another type)."""
    for m in (*MAPPINGS.values(), JSON_MAPPING):
        if m.ros_type == ros_type:
            return _shift(m.from_ros(ros), -stamp_offset_s)
    raise KeyError(f"no lotsen message for ROS type {ros_type}")


def encode(msg: Any, stamp_offset_s: float = 0.0) -> tuple[str, bytes]:
    """(ROS type, CDR bytes with encapsulation header)."""
    rtype, ros = to_ros(msg, stamp_offset_s)
    return rtype, bytes(typestore().serialize_cdr(ros, rtype))


def decode(ros_type: str, data: bytes, stamp_offset_s: float = 0.0) -> Any:
    try:
        ros = typestore().deserialize_cdr(bytes(data), ros_type)
    except Exception as exc:  # rosbags raises several kinds on short / garbled data
        raise codec.DecodeError(f"CDR payload of {ros_type} cannot be decoded: {exc}") from None
    return from_ros(ros_type, ros, stamp_offset_s)
