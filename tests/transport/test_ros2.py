"""ROS 2 mode of the Zenoh transport: type hashes, rmw_zenoh key expressions / tokens / attachment,
the lotsen <-> ROS 2 message mapping against independently built rosbags messages, the command
gate, and a two-process exchange with a peer that uses only zenoh and rosbags."""

import json
import math
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import xxhash
import pytest

from lotsen import messages as M
from lotsen.errors import ConfigError, DataError
from lotsen.runtime import SimExecutor
from lotsen.stack.processes import free_port
from lotsen.transport import rmw_zenoh as W
from lotsen.transport import ros2_map, ros2_types
from lotsen.transport.ros2_bridge import CommandGate, Ros2Bridge, Ros2BridgeConfig, source_name

REPO = Path(__file__).resolve().parents[2]

# REP-2016 hashes published by others (not computed here):
PUBLISHED_HASHES = {
    # rmw_zenoh docs/design.md, key expression examples
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    # `ros2 topic info -v` output of a Jazzy system (string[] fields)
    "sensor_msgs/msg/JointState": "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    # as hard-coded by independent ROS 2 / Zenoh client libraries
    "sensor_msgs/msg/Imu": "RIHS01_7d9a00ff131080897a5ec7e26e315954b8eae3353c3f995c55faf71574000b5b",
    "sensor_msgs/msg/MagneticField": "RIHS01_e80f32f56a20486c9923008fc1a1db07bbb273cbbf6a5b3bfa00835ee00e4dff",
    "sensor_msgs/msg/NavSatFix": "RIHS01_62223ab3fe210a15976021da7afddc9e200dc9ec75231c1b6a557fc598a65404",
    "nav_msgs/msg/Odometry": "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
    "nav_msgs/msg/Path": "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b",
    "std_msgs/msg/Bool": "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9",
    "rcl_interfaces/msg/Log": "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
}



# ---------------------------------------------------------------- types and hashes
@pytest.mark.parametrize("ros_type", sorted(PUBLISHED_HASHES))
def test_type_hashes_equal_published_ones(ros_type):
    assert ros2_types.type_hash(ros_type) == PUBLISHED_HASHES[ros_type]


def test_lotsen_msgs_come_from_the_msg_files_and_hash_their_content(tmp_path):
    files = ros2_types.lotsen_msg_files()
    assert {"lotsen_msgs/msg/ShipCommand", "lotsen_msgs/msg/VelocityCommand", "lotsen_msgs/msg/AngleCommand",
            "lotsen_msgs/msg/OperatorCommand", "lotsen_msgs/msg/SupervisorStatus",
            "lotsen_msgs/msg/JsonMessage"} <= set(files)
    cmake = (REPO / "lotsen/transport/lotsen_msgs/CMakeLists.txt").read_text()
    assert all(f'"msg/{n.rsplit("/", 1)[1]}.msg"' in cmake for n in files), "CMakeLists must list every .msg"
    T = ros2_types.typestore().types
    assert [f for f in T["lotsen_msgs/msg/VelocityCommand"].__dataclass_fields__ if f != "__msgtype__"] == \
        ["header", "n1_rps", "n2_rps", "nt_rps", "source"]
    # the hash follows the definition: a renamed field gives another hash; comments do not count
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    def h(text):
        st = get_typestore(Stores.ROS2_JAZZY)
        st.register(get_types_from_msg(text, "lotsen_msgs/msg/VelocityCommand"))
        return st.hash_rihs01("lotsen_msgs/msg/VelocityCommand")
    text = files["lotsen_msgs/msg/VelocityCommand"]
    assert h(text) == ros2_types.type_hash("lotsen_msgs/msg/VelocityCommand")
    assert h(text + "\n# another comment\n") == h(text)
    assert h(text.replace("nt_rps", "n3_rps")) != h(text)
    assert ros2_types.type_hash("lotsen_msgs/msg/VelocityCommand").startswith("RIHS01_")


def test_message_definitions_carry_their_dependencies():
    text = ros2_types.message_definition("lotsen_msgs/msg/SupervisorStatus")
    assert "string[] warnings" in text and "MSG: std_msgs/Header" in text and "MSG: builtin_interfaces/Time" in text


# ---------------------------------------------------------------- rmw_zenoh wire format
def test_key_expressions_and_tokens_reproduce_rmw_zenoh_examples():
    """The examples of rmw_zenoh's docs/design.md, rebuilt by lotsen's functions."""
    h = PUBLISHED_HASHES["std_msgs/msg/String"]
    assert W.topic_key(0, "/chatter", "std_msgs/msg/String") == f"0/chatter/std_msgs::msg::dds_::String_/{h}"
    assert W.topic_key(0, W.fully_qualified("/robot1", "chatter"), "std_msgs/msg/String") == \
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{h}"
    zid = "aac3178e146ba6f1fc6e6a4085e77f21"
    assert W.node_token(2, zid, 0, "/", "listener") == f"@ros2_lv/2/{zid}/0/0/NN/%/%/listener"
    assert W.entity_token(2, zid, 0, 10, "MS", "/", "listener", "/chatter", "std_msgs/msg/String", W.Qos(depth=10)) == \
        f"@ros2_lv/2/{zid}/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/{h}/::,10:,:,:,,"
    assert W.Qos(depth=7).keyexpr() == "::,7:,:,:,,"
    assert W.Qos(depth=42).keyexpr() == "::,:,:,:,,"  # all rmw_zenoh defaults
    assert W.SENSOR_QOS.keyexpr() == "2::,5:,:,:,,"
    info = W.parse_token(W.entity_token(0, zid, 0, 3, "MP", "/boat", "lotsen", "/boat/imu/data_raw",
                                        "sensor_msgs/msg/Imu", W.SENSOR_QOS))
    assert (info.kind, info.namespace, info.node, info.topic, info.dds_type) == \
        ("MP", "/boat", "lotsen", "/boat/imu/data_raw", "sensor_msgs::msg::dds_::Imu_")
    assert ros2_types.ros_type_of_dds(info.dds_type) == "sensor_msgs/msg/Imu"
    for bad in ("boat/imu", "/boat//imu", "/boat/imu/"):
        with pytest.raises(ValueError):
            W.topic_key(0, bad, "sensor_msgs/msg/Imu")


def test_attachment_is_the_zenoh_serialization_of_seq_stamp_gid():
    import zenoh.ext as ze

    gid = bytes(range(16))
    data = W.encode_attachment(42, 1_700_000_000_123_456_789, gid)
    assert len(data) == W.ATTACHMENT_SIZE == 33
    assert data == ze.z_serialize((ze.Int64(42), ze.Int64(1_700_000_000_123_456_789), gid)).to_bytes()
    att = W.decode_attachment(data)
    assert (att.sequence_number, att.source_timestamp_ns, att.gid) == (42, 1_700_000_000_123_456_789, gid)
    assert W.decode_attachment(None) is None and W.decode_attachment(data[:-1]) is None
    assert W.decode_attachment(data[:16] + b"\x08" + data[17:]) is None
    assert W.gid_for("a") != W.gid_for("b") and len(W.gid_for("a")) == 16


def test_the_gid_is_xxh3_128_of_the_liveliness_key_low_half_first_as_rmw_zenoh():
    # xxHash's reference value of XXH3-128 of no bytes: high64 0x99AA06D3014798D8, low64
    # 0x6001C324468D497F; rmw_zenoh copies low64 then high64 in the machine's (little) byte order
    assert W.gid_for("") == bytes.fromhex("7f498d4624c30160" "d8984701d306aa99")
    key = ("@ros2_lv/0/" + "ab" * 16 + "/0/11/MP/%/%/lotsen_core/%cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_"
           + "0" * 64 + "/::,10:,:,:,,")
    for k in (key, key + "/%" * 40):  # XXH3's 129-240 byte path (a real key) and its long-input path
        assert W.gid_for(k) == xxhash.xxh3_128(k.encode()).digest()[::-1]


# ---------------------------------------------------------------- mapping
SAMPLES = [
    M.ImuSample(stamp_s=1.25, gyro_radps=(0.1, -0.2, 0.3), accel_mps2=(0.05, 0.5, -9.81)),
    M.MagSample(stamp_s=2.0, field_uT=(20.5, -3.25, 40.0)),
    M.GnssFix(stamp_s=3.5, lat_deg=57.6905, lon_deg=11.976, height_m=10.0, fix_type=M.GnssFixType.RTK_FIXED,
              h_acc_m=0.05),
    M.VesselState(stamp_s=4.0, north_m=1.0, east_m=-2.0, heading_rad=0.5, u_mps=1.2, v_mps=0.1, r_radps=-0.2,
                  std=(0.1, 0.2, 0.03, 0.04, 0.05, 0.006)),
    M.PathMessage(stamp_s=0.0, north_m=(0.0, 1.0, 2.0), east_m=(0.0, 0.5, 0.5), speed_mps=(0.5, 0.5, 0.5)),
    M.ThrustCommand(stamp_s=5.0, alpha1_rad=0.1, alpha2_rad=-0.2, n1_rps=30.0, n2_rps=-3.0, nt_rps=1.5, source="mpc"),
    M.VelocityCommand(stamp_s=5.0, n1_rps=30.0, n2_rps=-3.0, nt_rps=1.5, source="mpc"),
    M.AngleCommand(stamp_s=5.0, alpha1_rad=0.1, alpha2_rad=-0.2, source="mpc"),
    M.SupervisorStatus(stamp_s=1.0, mode="AUTO", reason="r", armed=True, warnings=("gnss", "battery"),
                       available_actions=("hold",), blocked_actions=("auto: no route",), route_id="abc"),
    M.BatteryStatus(stamp_s=3.0, voltage_v=7.5, current_a=2.5, remaining_frac=0.5),
    M.ControllerStatus(stamp_s=1.0, controller="mpc", predicted_north_m=(1.0, 2.0)),  # JSON carrier
    M.RtcmData(stamp_s=1.0, data=b"\xd3\x00\x13abc"),  # JSON carrier
]


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_mapping_round_trip(msg, same):
    rtype, data = ros2_map.encode(msg, stamp_offset_s=1.7e9)
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR little endian encapsulation header
    out = ros2_map.decode(rtype, data, stamp_offset_s=1.7e9)
    assert type(out) is type(msg) and out.stamp_s == pytest.approx(msg.stamp_s, abs=1e-6)
    if isinstance(msg, (M.ThrustCommand, M.VelocityCommand, M.AngleCommand, M.SupervisorStatus, M.ControllerStatus,
                        M.RtcmData)):
        assert same(out, type(msg)(**{**{f: getattr(msg, f) for f in msg.__slots__}, "stamp_s": out.stamp_s}))
    if isinstance(msg, M.PathMessage):
        assert out.north_m == msg.north_m and out.east_m == msg.east_m
    if isinstance(msg, M.VesselState):
        assert out.std == pytest.approx(msg.std) and out.heading_rad == pytest.approx(msg.heading_rad)


def test_wire_against_independently_built_rosbags_messages():
    """lotsen -> ROS: read with a plain rosbags typestore (Kilted); ROS -> lotsen: built with one (Humble)."""
    from rosbags.typesys import Stores, get_typestore

    kilted = get_typestore(Stores.ROS2_KILTED)
    rtype, data = ros2_map.encode(SAMPLES[0])
    imu = kilted.deserialize_cdr(data, rtype)
    assert (imu.linear_acceleration.z, imu.angular_velocity.y, imu.header.frame_id) == \
        (pytest.approx(9.81), pytest.approx(0.2), "base_link")
    rtype, data = ros2_map.encode(SAMPLES[4])
    path = kilted.deserialize_cdr(data, rtype)
    assert rtype == "nav_msgs/msg/Path" and [p.pose.position.x for p in path.poses] == [0.0, 0.5, 0.5]

    humble = get_typestore(Stores.ROS2_HUMBLE)
    T = humble.types
    V3 = T["geometry_msgs/msg/Vector3"]
    ros = T["sensor_msgs/msg/Imu"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=10, nanosec=500_000_000),
                                        frame_id="imu"),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9), angular_velocity=V3(x=0.1, y=0.2, z=0.3),
        angular_velocity_covariance=np.zeros(9), linear_acceleration=V3(x=1.0, y=2.0, z=9.8),
        linear_acceleration_covariance=np.zeros(9))
    out = ros2_map.decode("sensor_msgs/msg/Imu", humble.serialize_cdr(ros, "sensor_msgs/msg/Imu"), stamp_offset_s=10.0)
    assert out == M.ImuSample(stamp_s=0.5, gyro_radps=(0.1, -0.2, -0.3), accel_mps2=(1.0, -2.0, -9.8))
    with pytest.raises(DataError, match="cannot be decoded"):
        ros2_map.decode("sensor_msgs/msg/Imu", b"\x00\x01\x00\x00\x01")


def test_split_and_combine_ship_command():
    cmd = M.ThrustCommand(stamp_s=2.0, alpha1_rad=0.1, alpha2_rad=-0.2, n1_rps=30.0, n2_rps=-3.0, nt_rps=1.5,
                          source="mpc")
    vel, ang = M.split_ship_command(cmd)
    assert (vel.n1_rps, vel.n2_rps, vel.nt_rps, ang.alpha1_rad, ang.alpha2_rad) == (30.0, -3.0, 1.5, 0.1, -0.2)
    assert M.combine(vel, ang) == cmd
    older = M.AngleCommand(stamp_s=1.0, alpha1_rad=0.3)
    assert M.combine(vel, older, source="x").stamp_s == 1.0 and M.combine(vel, older, source="x").source == "x"


# ---------------------------------------------------------------- authorisation
def test_command_gate_rules():
    g = CommandGate("s3cret", rate_hz=1.0, burst=2, max_failures=3, failure_window_s=60.0, lockout_s=30.0)
    assert g.check(0.0, "a", "s3cret", "hold") is None
    assert "unknown action" in g.check(0.0, "a", "s3cret", "self_destruct")
    assert g.check(0.1, "a", "s3cret", "hold") is None
    assert "rate limited" in g.check(0.2, "a", "s3cret", "hold")  # burst of 2 used up
    assert g.check(0.2, "b", "s3cret", "hold") is None  # per sender
    assert g.check(1.3, "a", "s3cret", "hold") is None  # refilled at 1/s
    for i, sender in enumerate("xyz"):  # three wrong tokens from three forged senders
        assert g.check(2.0 + i, sender, "guess", "arm") == "wrong pilot token"
    assert "locked out" in g.check(5.0, "a", "s3cret", "hold")  # everyone, the right token too
    assert g.check(35.0, "a", "s3cret", "hold") is None  # the lockout ends
    assert "no pilot token" in CommandGate(None).check(0.0, "a", "", "hold")
    assert "no pilot token" in CommandGate("").check(0.0, "a", "", "hold")
    assert source_name("shore tool!/../x", None) == "ros2:shoretoolx"
    assert source_name("", bytes.fromhex("0a0b0c0d") + bytes(12)) == "ros2:0a0b0c0d"


def test_bridge_config_errors():
    with pytest.raises(ConfigError, match="both published and subscribed"):
        Ros2Bridge(Ros2BridgeConfig(publish=("imu/data_raw",), subscribe=("imu/data_raw",)))
    with pytest.raises(ConfigError, match="not known"):
        Ros2Bridge(Ros2BridgeConfig(subscribe=("no/such/topic",)))
    for topic in (M.Topic.SHIP_COMMAND, M.Topic.VELOCITY_COMMAND, M.Topic.ANGLE_COMMAND, M.Topic.MANUAL):
        with pytest.raises(ConfigError, match="drive the boat"):
            Ros2Bridge(Ros2BridgeConfig(subscribe=(topic,)))


# ---------------------------------------------------------------- two processes
def _pump(ex, until, timeout_s):
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        ex.run_for(0.02)
        if until():
            return True
        time.sleep(0.01)
    return False


def test_two_processes_ros2_peer_without_lotsen(same):
    """The boat (this process) and a ROS 2 node made of zenoh + rosbags only (ros2_peer.py)."""
    ep = f"tcp/127.0.0.1:{free_port()}"
    ex = SimExecutor()
    # the boat listens; the peer process and a second bridge ("/rosbot", the reverse direction) connect as
    # Zenoh clients, so the boat forwards between them (two Zenoh peers without gossip would not route)
    boat = Ros2Bridge(Ros2BridgeConfig(namespace="/boat", listen=(ep,), pilot_token="correct-horse",
                                       publish=(M.Topic.IMU_RAW, M.Topic.GNSS, M.Topic.STATE),
                                       subscribe=(M.Topic.OPERATOR,)))
    rosbot = Ros2Bridge(Ros2BridgeConfig(namespace="/rosbot", node_name="lotsen_in", mode="client", connect=(ep,),
                                         subscribe=(M.Topic.IMU_RAW, M.Topic.GNSS), local_prefix="ros/"))
    ex.add_node(boat)
    ex.add_node(rosbot)
    commands, imus, fixes, logs = [], [], [], []
    ex.bus.subscribe(M.Topic.OPERATOR, commands.append)
    ex.bus.subscribe("ros/" + M.Topic.IMU_RAW, imus.append)
    ex.bus.subscribe("ros/" + M.Topic.GNSS, fixes.append)
    ex.bus.subscribe(M.Topic.LOG, logs.append)
    peer = subprocess.Popen([sys.executable, str(Path(__file__).with_name("ros2_peer.py")), ep, "correct-horse",
                             str(ros2_types.msg_dir())], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=lambda: [lines.put(json.loads(s)) for s in peer.stdout], daemon=True).start()
    said: dict = {}

    def heard():
        while not lines.empty():
            said.update(lines.get())
        return said

    imu = M.ImuSample(stamp_s=1.25, gyro_radps=(0.1, -0.2, 0.3), accel_mps2=(0.05, 0.5, -9.81))
    fix = SAMPLES[2]
    try:
        assert _pump(ex, lambda: "ready" in heard(), 20), "peer did not start"
        assert said["modules"] == [], "the peer must not import lotsen"

        def exchange():
            ex.bus.publish(M.Topic.IMU_RAW, imu)
            ex.bus.publish(M.Topic.GNSS, fix)
            return "have_data" in heard() and any(c.action == "hold" for c in commands) and imus and fixes
        assert _pump(ex, exchange, 30), f"exchange incomplete: peer said {said}, {len(commands)} commands, rosbot {rosbot.stats}"
        peer.stdin.write("stop\n")
        peer.stdin.flush()
        assert _pump(ex, lambda: "done" in heard(), 15)
    finally:
        if peer.poll() is None:
            peer.stdin.close()
        try:
            code = peer.wait(20)
        except subprocess.TimeoutExpired:
            peer.kill()
            code = peer.wait(5)
        boat.close()
        rosbot.close()
    assert code == 0
    # the peer found the boat in the ROS graph and read its IMU and GNSS as ROS 2 messages
    assert said["graph"]["/boat/imu/data_raw"][:2] == ["sensor_msgs::msg::dds_::Imu_",
                                                        PUBLISHED_HASHES["sensor_msgs/msg/Imu"]]
    assert said["graph"]["/boat/imu/data_raw"][2] == "2::,5:,:,:,,"  # SensorDataQoS
    got = said["imu"][0]
    assert got["accel"] == pytest.approx([0.05, -0.5, 9.81]) and got["gyro"] == pytest.approx([0.1, 0.2, -0.3])
    assert got["stamp"] == [1, 250_000_000] and got["frame"] == "base_link" and got["orientation_cov0"] == -1.0
    assert got["gid_len"] == 16 and got["ts_ns"] > 1.6e18
    assert [i["seq"] for i in said["imu"]] == sorted(i["seq"] for i in said["imu"]) and said["imu"][0]["seq"] >= 1
    g = said["gnss"][0]
    assert (g["lat"], g["lon"], g["status"]) == (57.6905, 11.976, 2) and g["cov0"] == pytest.approx(0.05 ** 2)
    # the peer's commands: the wrong token refused, the right one on the bus with a ros2: source
    assert [c.source for c in commands if c.action == "hold"][0] == "ros2:shore_tool"
    assert not any(c.action == "arm" for c in commands)
    assert boat.stats.commands_refused >= 1 and "intruder" in boat.stats.last_refusal
    assert any("ROS 2 command refused" in e.text and "wrong pilot token" in e.text for e in logs)
    # the reverse direction: rosbags-serialized sensor messages decoded into lotsen types (FLU -> FRD)
    assert same(imus[0], M.ImuSample(stamp_s=12.5, gyro_radps=(0.01, -0.02, -0.03), accel_mps2=(0.1, 0.2, -9.8)))
    assert (fixes[0].lat_deg, fixes[0].fix_type, fixes[0].h_acc_m) == (57.7, M.GnssFixType.FIX_3D, 0.5)
    assert math.isfinite(fixes[0].stamp_s)
