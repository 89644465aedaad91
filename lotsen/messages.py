"""Typed messages exchanged between nodes, and the topic names (seed Table 3 where one exists).

This module imports nothing from lotsen: sensors in `lotsen.sim`, drivers, fusion, control,
logs and the web all speak these types. `lotsen.messages` re-exports them.
Every message carries `stamp_s`, the time the measurement or command refers to (simulated or
wall seconds of the runtime's clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum


__all__ = [
    "Topic", "ThrustCommand", "ActuatorState", "ImuSample", "MagSample", "MagCalibrated", "GnssFixType",
    "GnssFix", "RpmSample", "RtcmData", "VesselState", "PathMessage", "ControllerStatus", "SupervisorStatus",
    "OperatorCommand", "ManualCommand", "RcOverride", "BatteryStatus", "LogEvent", "RouteMessage", "LinkStatus",
    "OPERATOR_ACTIONS", "ModeName", "MagCalibrationResult", "Alert", "MissionProgress", "PlannedRoute", "EstimatorHealth",
    "ModelInfo", "LATCHED_TOPICS", "CommandAck", "RecorderStatus", "SeaState", "DepthSample", "Sounding",
]


class Topic:
    """Topic names. Seed Table 3 names are kept so people who know the original find their way."""

    SHIP_COMMAND = "ship_command"  # ThrustCommand to the actuators (seed: Ship node)
    # ThrustCommand of an identification experiment (lotsen experiment run): a command source the
    # supervisor forwards in EXPERIMENT mode, as it does the keys in MANUAL
    EXPERIMENT_COMMAND = "experiment/command"
    IMU_RAW = "imu/data_raw"  # ImuSample
    IMU_MAG = "imu/mag"  # MagSample, raw
    IMU_MAG_CALIBRATED = "imu/mag_calibrated"  # MagCalibrated
    MAG_CALIBRATION = "imu/mag_calibration"  # MagCalibrationResult of the one-turn manoeuvre
    GNSS = "gps_chatter"  # GnssFix
    RPM = "rpm_chatter"  # RpmSample
    SENS_FUS = "imu/sens_fus"  # VesselState, the seed's fusion output
    RTCM = "gps_rtk/rtcm_data"  # RtcmData, corrections to the receiver
    STATE = "state/estimate"  # VesselState, the full estimate used by control
    TRUTH = "sim/truth"  # VesselState, ground truth (simulation only)
    ACTUATORS = "actuators/state"  # ActuatorState: achieved values (servo angles, measured rpm), ESCs armed
    ROUTE = "planning/route"  # PlannedRoute: the operator's route, planned once by the planner worker
    ACTIVE_ROUTE = "planning/active_route"  # RouteMessage: read-back of the route the boat holds
    PATH = "planning/path"  # PathMessage
    CONTROL_STATUS = "control/status"  # ControllerStatus
    SUPERVISOR = "supervisor/status"  # SupervisorStatus
    ALERT = "supervisor/alert"  # Alert: refusals, failsafes, warnings for the operator
    PROGRESS = "mission/progress"  # MissionProgress along the active path (AUTO / RETURN)
    OPERATOR = "operator/command"  # OperatorCommand (mode changes, start/stop)
    OPERATOR_ACK = "operator/ack"  # CommandAck: the supervisor's answer to each OperatorCommand with a request_id
    MANUAL = "operator/manual"  # ManualCommand from the keyboard
    LINK = "operator/link"  # LinkStatus: the pilot's connection, published by the web server
    RC = "rc/override"  # RcOverride from the FrSky receiver
    BATTERY = "battery"  # BatteryStatus
    LOG = "log"  # LogEvent
    ESTIMATOR_HEALTH = "fusion/health"  # EstimatorHealth: integrity of the state estimate (docs/fusion.md)
    MODEL = "model/in_use"  # ModelInfo: the model the estimator and controllers use, and its origin
    RECORDER = "logs/status"  # RecorderStatus: the recorder's disk and what it has kept (1 Hz)
    SEA_STATE = "fusion/sea_state"  # SeaState: Hs, Tp, direction from the IMU (every 2 s)
    DEPTH = "depth/raw"  # DepthSample: the echosounder's depth below its transducer, per ping
    SOUNDING = "depth/sounding"  # Sounding: depth below the surface where the transducer was at the ping


#: state a late joiner needs (a recorder, a page, a ROS 2 node started after it was published):
#: kept and handed to every new subscriber (ROS 2: transient-local durability, keep last 1)
LATCHED_TOPICS: tuple[str, ...] = (Topic.PATH, Topic.ACTIVE_ROUTE, Topic.ROUTE, Topic.MODEL)


@dataclass(slots=True, kw_only=True)
class ThrustCommand:
    """Actuator set-points: azimuth angles (rad, + turns thrust to starboard) and signed rev/s."""

    stamp_s: float
    alpha1_rad: float = 0.0
    alpha2_rad: float = 0.0
    n1_rps: float = 0.0
    n2_rps: float = 0.0
    nt_rps: float = 0.0
    source: str = ""

    def as_tuple(self) -> tuple[float, float, float, float, float]:
        return (self.alpha1_rad, self.alpha2_rad, self.n1_rps, self.n2_rps, self.nt_rps)

    def is_finite(self) -> bool:
        return all(math.isfinite(v) for v in self.as_tuple())

    @classmethod
    def from_tuple(cls, stamp_s: float, u: "tuple[float, ...] | list[float]", source: str = "") -> "ThrustCommand":
        return cls(stamp_s=stamp_s, alpha1_rad=float(u[0]), alpha2_rad=float(u[1]), n1_rps=float(u[2]),
                   n2_rps=float(u[3]), nt_rps=float(u[4]), source=source)

    @classmethod
    def neutral(cls, stamp_s: float, source: str = "neutral") -> "ThrustCommand":
        return cls(stamp_s=stamp_s, source=source)


@dataclass(slots=True, kw_only=True)
class ActuatorState:
    """Achieved actuator values (servo angles, propeller speeds)."""

    stamp_s: float
    alpha1_rad: float
    alpha2_rad: float
    n1_rps: float
    n2_rps: float
    nt_rps: float
    escs_armed: bool = True  # the ESCs finished their arming sequence (neutral long enough)

    def as_tuple(self) -> tuple[float, float, float, float, float]:
        return (self.alpha1_rad, self.alpha2_rad, self.n1_rps, self.n2_rps, self.nt_rps)


@dataclass(slots=True, kw_only=True)
class ImuSample:
    """Body frame (x fwd, y stbd, z down). Specific force: at rest level, accel_z = -g."""

    stamp_s: float
    gyro_radps: tuple[float, float, float]
    accel_mps2: tuple[float, float, float]


@dataclass(slots=True, kw_only=True)
class MagSample:
    stamp_s: float
    field_uT: tuple[float, float, float]  # body frame, raw (distorted)


@dataclass(slots=True, kw_only=True)
class MagCalibrated:
    stamp_s: float
    mag_x: float  # calibrated, normalised horizontal field in the body frame
    mag_y: float
    heading_rad: float  # atan2(-mag_y, mag_x), clockwise from magnetic north


@dataclass(slots=True, kw_only=True)
class MagCalibrationResult:
    """Hard iron (center) and soft iron (symmetric matrix) from one full turn; ok=False with a reason."""

    stamp_s: float
    ok: bool
    center: tuple[float, float] = (0.0, 0.0)
    matrix: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    residual: float = float("nan")
    coverage_deg: float = float("nan")
    text: str = ""
    #: the raw horizontal field samples the fit used (decimated, raw units), for the operator's plot
    samples: tuple[tuple[float, float], ...] = ()
    #: "" = a fresh fit, in use and waiting for the operator's review; "accepted"; "rejected" (the
    #: calibration in use before it is back)
    decision: str = ""


class GnssFixType(IntEnum):
    """u-blox NAV-PVT fixType, with carrSoln folded in as RTK_FLOAT / RTK_FIXED."""

    NO_FIX = 0
    DEAD_RECKONING = 1
    FIX_2D = 2
    FIX_3D = 3
    RTK_FLOAT = 4
    RTK_FIXED = 5


@dataclass(slots=True, kw_only=True)
class GnssFix:
    stamp_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    fix_type: GnssFixType
    h_acc_m: float
    v_acc_m: float = float("nan")
    vel_n_mps: float = float("nan")
    vel_e_mps: float = float("nan")
    num_sv: int = 0
    correction_age_s: float = float("nan")

    @property
    def usable(self) -> bool:
        return self.fix_type >= GnssFixType.FIX_3D and math.isfinite(self.lat_deg) and math.isfinite(self.lon_deg)


@dataclass(slots=True, kw_only=True)
class DepthSample:
    """One echosounder ping as the sounder reports it (NMEA 0183 DPT or DBT): the depth below the
    transducer, NaN when it found no bottom (out of range, air under the transducer); `offset_m`
    DPT's transducer offset as sent (positive: transducer to waterline, negative: to keel; NaN in
    DBT); `sentence` the talker and sentence ("SDDPT")."""

    stamp_s: float
    depth_m: float
    offset_m: float = float("nan")
    sentence: str = ""


@dataclass(slots=True, kw_only=True)
class Sounding:
    """A depth below the water surface at a place: a ping's depth plus the transducer's draft, at
    the transducer's position at the ping's time (the boat's estimate then, moved by the lever arm
    from the hull's origin, which itself is the antenna's position less the antenna's offset).
    `position_std_m` is the estimate's horizontal standard deviation then (NaN for the truth)."""

    stamp_s: float
    north_m: float
    east_m: float
    depth_m: float
    position_std_m: float = float("nan")


@dataclass(slots=True, kw_only=True)
class RpmSample:
    stamp_s: float
    n1_rps: float
    n2_rps: float
    nt_rps: float


@dataclass(slots=True, kw_only=True)
class RtcmData:
    stamp_s: float
    data: bytes


@dataclass(slots=True, kw_only=True)
class VesselState:
    """Pose in local NED and body velocities; std fields are NaN for ground truth."""

    stamp_s: float
    north_m: float
    east_m: float
    heading_rad: float
    u_mps: float
    v_mps: float
    r_radps: float
    source: str = ""
    std: tuple[float, ...] = ()  # standard deviations of the six states, when estimated
    gyro_bias_radps: float = 0.0
    # slowly varying disturbance, when the estimator has states for it (zero otherwise):
    current_ne_mps: tuple[float, float] = (0.0, 0.0)  # water current over ground, north / east
    disturbance_tau: tuple[float, float, float] = (0.0, 0.0, 0.0)  # body force X, Y (N), moment N (N m)
    # the wave-frequency displacement the estimator separated out (north m, east m, heading rad; zero
    # without wave states): the state above is the low-frequency motion the controllers act on, the
    # boat is at (north + wave_motion[0], east + wave_motion[1]) heading heading + wave_motion[2];
    # std[0:3] are the uncertainty of that, where the boat is
    wave_motion: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def as_array_tuple(self) -> tuple[float, float, float, float, float, float]:
        return (self.north_m, self.east_m, self.heading_rad, self.u_mps, self.v_mps, self.r_radps)

    @property
    def speed_mps(self) -> float:
        return math.hypot(self.u_mps, self.v_mps)


@dataclass(slots=True, kw_only=True)
class PathMessage:
    """A planned path, decimated for display and logging (the controller holds the full path)."""

    stamp_s: float
    north_m: tuple[float, ...]
    east_m: tuple[float, ...]
    speed_mps: tuple[float, ...]


@dataclass(slots=True, kw_only=True)
class ControllerStatus:
    stamp_s: float
    controller: str
    cross_track_error_m: float = float("nan")
    heading_error_rad: float = float("nan")
    speed_mps: float = float("nan")
    speed_ref_mps: float = float("nan")
    progress_m: float = float("nan")
    solve_time_ms: float = float("nan")
    status: str = "ok"
    predicted_north_m: tuple[float, ...] = ()
    predicted_east_m: tuple[float, ...] = ()
    failures: int = 0


@dataclass(slots=True, kw_only=True)
class SupervisorStatus:
    stamp_s: float
    mode: str
    reason: str = ""
    armed: bool = False  # the operator armed the boat (thrust allowed); disarmed = neutral always
    warnings: tuple[str, ...] = ()
    active_failsafes: tuple[str, ...] = ()
    escs_armed: bool = False  # the actuators report their ESCs ready
    available_actions: tuple[str, ...] = ()  # operator actions that would be accepted now
    blocked_actions: tuple[str, ...] = ()  # "action: why not", for the others
    route_id: str = ""  # id of the route the boat holds ("" = none)


@dataclass(slots=True, kw_only=True)
class Alert:
    """Something the operator must see: a refused request, a failsafe, a warning.

    `code` is machine-readable ("refused:auto", "failsafe:gnss_lost", ...); `active=False` says that
    the condition behind an earlier alert with the same code has cleared."""

    stamp_s: float
    severity: str  # "info" | "warning" | "error" | "critical"
    code: str
    text: str
    source: str = "supervisor"
    active: bool = True


@dataclass(slots=True, kw_only=True)
class MissionProgress:
    """Where the boat is along the path it follows, and when it will arrive at the planned speeds."""

    stamp_s: float
    mode: str
    path_length_m: float
    progress_m: float
    remaining_m: float
    eta_s: float
    next_node: int = -1  # index into the route's nodes; -1 = the harbour or none
    distance_to_next_node_m: float = float("nan")
    route_id: str = ""


OPERATOR_ACTIONS = (
    "auto",  # start / resume following the route
    "hold",  # pause: station keeping where the boat is
    "return",  # plan and follow a route back to the harbour node
    "manual",  # keyboard driving (ManualCommand)
    "arm",  # allow thrust (needs the ESCs armed); every thrusting mode needs it
    "disarm",  # thrusters neutral whatever the mode (not while moving in AUTO/RETURN: use hold first)
    "estop",  # emergency stop: neutral, latched, disarms
    "reset_estop",  # release the latch (to MANUAL, thrusters neutral)
    "calibrate_mag",  # run the one-turn manoeuvre and fit the magnetometer calibration
    "mag_accept", "mag_reject",  # keep the fresh fit, or go back to the calibration in use before it
    "experiment",  # forward the running identification experiment's commands (lotsen experiment run)
    "rtk_start", "rtk_stop",  # RTK corrections on/off
    "logging_on", "logging_off",
)


class ModeName(StrEnum):
    """The supervisor's modes (lotsen.supervisor.modes) by name: `SupervisorStatus.mode`, the log and
    the page carry them as plain strings."""

    MANUAL = "MANUAL"
    AUTO = "AUTO"
    HOLD = "HOLD"
    RETURN = "RETURN"
    CALIBRATE = "CALIBRATE"
    ESTOP = "ESTOP"
    RC = "RC"
    EXPERIMENT = "EXPERIMENT"


@dataclass(slots=True, kw_only=True)
class OperatorCommand:
    """A request from the operator; `action` is one of OPERATOR_ACTIONS."""

    stamp_s: float
    action: str
    source: str = "operator"
    # the sender's id of this request (a page resends an unconfirmed e-stop with the same id): the
    # supervisor answers each id once with a CommandAck and acts on it once
    request_id: str = ""


@dataclass(slots=True, kw_only=True)
class CommandAck:
    """The supervisor's answer to an OperatorCommand with a request_id: accepted (and done) or
    refused with the reason, and the mode after it. A resent request gets the first answer again."""

    stamp_s: float
    request_id: str
    action: str
    accepted: bool
    reason: str = ""
    mode: str = ""
    armed: bool = False


@dataclass(slots=True, kw_only=True)
class SeaState:
    """The sea as the boat's IMU measures it (lotsen.fusion.seastate; docs/fusion.md "Sea state"):
    significant wave height, peak period (true and as met under way), the direction the waves come
    FROM (degrees clockwise from north), the hull's heave, roll and pitch. NaN: not known (too little
    data; no direction without a heading). `valid` False: not enough data yet."""

    stamp_s: float
    valid: bool
    hs_m: float
    tp_s: float
    tp_encounter_s: float
    from_deg: float
    heave_std_m: float
    roll_std_deg: float
    pitch_std_deg: float
    window_s: float = 0.0  # the data the estimate is made from
    source: str = "imu"


@dataclass(slots=True, kw_only=True)
class RecorderStatus:
    """The recorder's state, 1 Hz: where it writes, the free space there, and a write failure with
    what it has kept (the file and its last complete second)."""

    stamp_s: float
    directory: str
    free_bytes: int = -1  # -1: unknown
    total_bytes: int = -1
    recording: bool = False
    file: str = ""  # the file being written ("" = none)
    written_bytes: int = 0  # in that file so far
    error: str = ""  # a write failure ("" = none): the disk full or failing
    kept: str = ""  # after a failure: what is safe on disk, in the operator's words


@dataclass(slots=True, kw_only=True)
class RouteMessage:
    """The operator's route in the YAML schema of docs/planning.md, as a plain dict (the boat's
    read-back on planning/active_route carries the id of the route it holds)."""

    stamp_s: float
    route: dict
    source: str = "operator"
    route_id: str = ""


#: field metadata: a long tuple of floats whose JSON form is the base64 of its float64 values
#: (little endian), not a list of numbers (lotsen.transport.codec; docs/logs.md). A survey's path
#: is ~78 000 points: as lists of numbers its 6.5 MB of JSON took the core's Zenoh thread 0.2 s of
#: json.loads, one C call holding the interpreter lock the control loop needs; packed it is 0.01 s
PACKED_FLOATS = {"packed": "float64le"}


@dataclass(slots=True, kw_only=True)
class PlannedRoute:
    """A route and the path planned from it, planned once (by the planner worker) and sent as is:
    the supervisor checks and follows it without planning again. Arrays at the planner's spacing
    (packed on the wire: `PACKED_FLOATS`)."""

    stamp_s: float
    route_id: str  # lotsen.planning.io.route_id(route): the page compares it with the read-back
    route: dict
    s_m: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    north_m: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    east_m: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    heading_rad: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    curvature_1pm: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    speed_mps: tuple[float, ...] = field(metadata=PACKED_FLOATS)
    node_s_m: tuple[float, ...] = ()  # arc length at each route node (harbour first)
    source: str = "operator"


@dataclass(slots=True, kw_only=True)
class LinkStatus:
    """The operator link as seen by the web server: is a pilot connected, and when was it last heard."""

    stamp_s: float
    pilot_connected: bool
    last_heard_s: float
    viewers: int = 0


@dataclass(slots=True, kw_only=True)
class ManualCommand:
    """Keyboard/joystick driving, each axis in [-1, 1]: surge (fwd +), sway (stbd +), yaw (stbd +)."""

    stamp_s: float
    surge: float = 0.0
    sway: float = 0.0
    yaw: float = 0.0


@dataclass(slots=True, kw_only=True)
class RcOverride:
    """The RC transmitter (seed: can always take over), as the receiver driver reads it.

    active: the takeover switch is on (it wins over every mode); estop: the e-stop switch is on
    (latches the emergency stop); link: "ok", "lost" (no frames, or frames flagged lost, for the
    driver's `lost_after_s`) or "failsafe" (the receiver's failsafe flag). With a link that is
    not "ok" the switches are unknown: `active` repeats the last known takeover state, `estop`
    is False and there is no command."""

    stamp_s: float
    active: bool
    command: ThrustCommand | None = None
    estop: bool = False
    link: str = "ok"


@dataclass(slots=True, kw_only=True)
class BatteryStatus:
    stamp_s: float
    voltage_v: float
    current_a: float = float("nan")
    remaining_frac: float = float("nan")


@dataclass(slots=True, kw_only=True)
class LogEvent:
    stamp_s: float
    level: str  # "info", "warning", "error"
    source: str
    text: str
    data: dict = field(default_factory=dict)


# ---------------------------------------------------------------------------- seed Table 3: the Ship node's
# three command topics. `ship_command` (ThrustCommand) stays the combined form the actuators use;
# `velocity_command` and `angle_command` carry its two halves, as the original ROS system had them.
Topic.VELOCITY_COMMAND = "velocity_command"  # VelocityCommand: propeller speeds (seed Table 3)
Topic.ANGLE_COMMAND = "angle_command"  # AngleCommand: azimuth angles (seed Table 3)


@dataclass(slots=True, kw_only=True)
class VelocityCommand:
    """Propeller speed set-points, signed rev/s (n1, n2: azimuth thrusters; nt: bow thruster)."""

    stamp_s: float
    n1_rps: float = 0.0
    n2_rps: float = 0.0
    nt_rps: float = 0.0
    source: str = ""


@dataclass(slots=True, kw_only=True)
class AngleCommand:
    """Azimuth angle set-points (rad, + turns thrust to starboard), as in ThrustCommand."""

    stamp_s: float
    alpha1_rad: float = 0.0
    alpha2_rad: float = 0.0
    source: str = ""


def split_ship_command(cmd: ThrustCommand) -> tuple[VelocityCommand, AngleCommand]:
    """The two halves of a ship_command (same stamp and source)."""
    return (VelocityCommand(stamp_s=cmd.stamp_s, n1_rps=cmd.n1_rps, n2_rps=cmd.n2_rps, nt_rps=cmd.nt_rps,
                            source=cmd.source),
            AngleCommand(stamp_s=cmd.stamp_s, alpha1_rad=cmd.alpha1_rad, alpha2_rad=cmd.alpha2_rad, source=cmd.source))


def combine(velocity: VelocityCommand, angle: AngleCommand, source: str | None = None) -> ThrustCommand:
    """One ship_command from the two halves; stamp = the older of the two (the combined command is
    only as fresh as its staler half), source = `source` or the velocity command's."""
    return ThrustCommand(stamp_s=min(velocity.stamp_s, angle.stamp_s), alpha1_rad=angle.alpha1_rad,
                         alpha2_rad=angle.alpha2_rad, n1_rps=velocity.n1_rps, n2_rps=velocity.n2_rps,
                         nt_rps=velocity.nt_rps, source=velocity.source if source is None else source)


__all__ += ["VelocityCommand", "AngleCommand", "split_ship_command", "combine"]


@dataclass(slots=True, kw_only=True)
class EstimatorHealth:
    """Integrity of the state estimate (lotsen.fusion.integrity; contract in docs/fusion.md).

    The three flags say whether the position / heading / velocity of the estimate may be used
    for navigation and for the geofence. `faults` are human-readable ("sensor: what, since t"),
    `fault_codes` the same faults machine-readable ("gnss.inconsistent", "gyro.stuck", ...), in
    the same order. Per-sensor figures are parallel tuples indexed like `sensors`."""

    stamp_s: float
    position_ok: bool
    heading_ok: bool
    velocity_ok: bool
    faults: tuple[str, ...] = ()
    fault_codes: tuple[str, ...] = ()
    source: str = ""
    sensors: tuple[str, ...] = ()  # e.g. ("gyro", "accel", "mag", "gnss", "gnss_vel")
    nis: tuple[float, ...] = ()  # windowed mean normalised innovation squared per dof (~1 when consistent)
    used_frac: tuple[float, ...] = ()  # fraction of the window's samples that were used
    last_used_age_s: tuple[float, ...] = ()  # stamp_s minus the stamp of the last used sample (inf: never)
    filter_age_s: float = float("nan")  # stamp_s minus the filter's own time
    position_std_m: float = float("nan")  # the larger of the north / east standard deviations
    heading_std_rad: float = float("nan")
    velocity_std_mps: float = float("nan")  # the larger of the u / v standard deviations
    current_ne_mps: tuple[float, float] = (0.0, 0.0)  # estimated water current (north, east), when estimated
    current_std_mps: tuple[float, float] = (float("nan"), float("nan"))
    event_count: int = 0  # increases with every informational event (re-anchoring, time jump, ...)
    events: tuple[str, ...] = ()  # the most recent events, newest last


@dataclass(slots=True, kw_only=True)
class ModelInfo:
    """The model the estimator, planner and controllers use, and where it came from. Published
    once at start and latched, so every log and every page says which model was in use."""

    stamp_s: float
    source: str  # "default coefficients" or the parameter file
    file_modified_utc: str = ""  # when the parameter file was written (ISO 8601)
    parameters: dict = field(default_factory=dict)  # name -> value (SI, docs/model.md)
    std: dict = field(default_factory=dict)  # name -> 1-sigma, when the file came from identification
    verdict: str = ""  # identification's verdict, when the file carries one
    boat: str = ""  # in simulation: the simulated boat (which is not this model)
