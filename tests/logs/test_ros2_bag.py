"""ROS 2 bag export: a lotsen log becomes a rosbag2 directory (MCAP storage, ros2msg schemas, CDR)
that rosbags reads as a ROS 2 bag using only the definitions stored in it, and whose MCAP the mcap
library reads with the ROS 2 profile and encodings."""

import math

import pytest
import yaml

from lotsen import messages as M
from lotsen.errors import DataError
from lotsen.logs import McapRecorder, RecorderConfig
from lotsen.logs.ros2 import export_ros2
from lotsen.runtime import SimExecutor

MESSAGES = [
    (M.Topic.IMU_RAW, M.ImuSample(stamp_s=0.5, gyro_radps=(0.1, -0.2, 0.3), accel_mps2=(0.05, 0.5, -9.81))),
    (M.Topic.IMU_MAG, M.MagSample(stamp_s=0.5, field_uT=(20.0, -3.0, 40.0))),
    (M.Topic.GNSS, M.GnssFix(stamp_s=0.6, lat_deg=57.69, lon_deg=11.97, height_m=10.0,
                             fix_type=M.GnssFixType.RTK_FIXED, h_acc_m=0.02)),
    (M.Topic.STATE, M.VesselState(stamp_s=0.7, north_m=1.0, east_m=2.0, heading_rad=0.5, u_mps=0.3, v_mps=0.0,
                                  r_radps=0.01, source="ekf", std=(0.1,) * 6)),
    (M.Topic.PATH, M.PathMessage(stamp_s=0.7, north_m=(0.0, 5.0, 10.0), east_m=(0.0, 1.0, 0.0),
                                 speed_mps=(0.5, 0.5, 0.5))),
    (M.Topic.SHIP_COMMAND, M.ThrustCommand(stamp_s=0.8, alpha1_rad=0.1, n1_rps=20.0, source="mpc")),
    (M.Topic.VELOCITY_COMMAND, M.VelocityCommand(stamp_s=0.8, n1_rps=20.0, source="mpc")),
    (M.Topic.ANGLE_COMMAND, M.AngleCommand(stamp_s=0.8, alpha1_rad=0.1, source="mpc")),
    (M.Topic.SUPERVISOR, M.SupervisorStatus(stamp_s=0.9, mode="AUTO", warnings=("gnss",))),
    (M.Topic.OPERATOR, M.OperatorCommand(stamp_s=0.9, action="hold", source="web")),
    (M.Topic.BATTERY, M.BatteryStatus(stamp_s=0.9, voltage_v=7.4)),
    (M.Topic.LOG, M.LogEvent(stamp_s=1.0, level="warning", source="test", text="hello", data={"k": 1})),
    (M.Topic.CONTROL_STATUS, M.ControllerStatus(stamp_s=1.0, controller="mpc", cross_track_error_m=0.25)),
    (M.Topic.IMU_RAW, M.ImuSample(stamp_s=1.5, gyro_radps=(0.0, 0.0, 0.0), accel_mps2=(0.0, 0.0, -9.81))),
]
EXPECTED_TYPES = {
    "/boat/imu/data_raw": "sensor_msgs/msg/Imu", "/boat/imu/mag": "sensor_msgs/msg/MagneticField",
    "/boat/gps_chatter": "sensor_msgs/msg/NavSatFix", "/boat/state/estimate": "nav_msgs/msg/Odometry",
    "/boat/planning/path": "nav_msgs/msg/Path", "/boat/ship_command": "lotsen_msgs/msg/ShipCommand",
    "/boat/velocity_command": "lotsen_msgs/msg/VelocityCommand", "/boat/angle_command": "lotsen_msgs/msg/AngleCommand",
    "/boat/supervisor/status": "lotsen_msgs/msg/SupervisorStatus",
    "/boat/operator/command": "lotsen_msgs/msg/OperatorCommand", "/boat/battery": "sensor_msgs/msg/BatteryState",
    "/boat/log": "rcl_interfaces/msg/Log", "/boat/control/status": "lotsen_msgs/msg/JsonMessage",
}


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    d = tmp_path_factory.mktemp("ros2bag")
    ex = SimExecutor()
    rec = McapRecorder(RecorderConfig(fsync=False, geo_origin=(57.69, 11.97, 10.0)), clock=ex.clock.now).attach(ex.bus)
    src = d / "run.mcap"
    rec.start(str(src))
    for topic, msg in MESSAGES:
        ex.run_until(msg.stamp_s)
        ex.bus.publish(topic, msg)
    rec.close()
    result = export_ros2(src, d / "run_ros2", namespace="/boat")
    return src, result


def test_export_names_topics_types_and_counts(bag):
    _, result = bag
    assert {t: ty for t, (ty, _) in result.topics.items()} == EXPECTED_TYPES
    assert result.topics["/boat/imu/data_raw"][1] == 2 and result.messages == len(MESSAGES) and result.errors == 0
    assert any(t.startswith("foxglove/") for t in result.skipped_channels)  # the protobuf views are not copied
    meta = yaml.safe_load((result.bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == "mcap" and meta["version"] == 8
    assert meta["relative_file_paths"] == [result.mcap_path.name] and meta["message_count"] == len(MESSAGES)
    assert {t["topic_metadata"]["name"]: t["topic_metadata"]["type"] for t in meta["topics_with_message_count"]} == \
        EXPECTED_TYPES


def test_mcap_has_the_ros2_profile_schemas_and_encodings(bag):
    from mcap.reader import make_reader
    from mcap.well_known import MessageEncoding, Profile, SchemaEncoding

    _, result = bag
    with open(result.mcap_path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == Profile.ROS2
        summary = reader.get_summary()
        assert summary.statistics.message_count == len(MESSAGES)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        n = sum(1 for _ in reader.iter_messages())  # the data reads back (chunk CRCs checked)
    assert n == len(MESSAGES) and "serialized_metadata" in metadata["rosbag2"]
    for ch in summary.channels.values():
        schema = summary.schemas[ch.schema_id]
        assert (schema.encoding, ch.message_encoding) == (SchemaEncoding.ROS2, MessageEncoding.CDR)
        assert schema.name == EXPECTED_TYPES[ch.topic] and "offered_qos_profiles" in ch.metadata
        # every nested type is defined in the schema itself (what Foxglove and ros2 bag play need)
        text = schema.data.decode()
        defined = {schema.name.replace("/msg/", "/")} | {line[5:] for line in text.splitlines() if line.startswith("MSG: ")}
        for block in text.split("=" * 80):
            for line in block.splitlines():
                if not line or line.startswith(("#", "MSG: ")) or "=" in line.split()[-1]:
                    continue
                ftype = line.split()[0].split("[")[0].split("<=")[0]
                if "/" in ftype:
                    assert ftype in defined, (schema.name, ftype)


def test_rosbags_reads_it_as_a_ros2_bag_from_the_stored_definitions(bag):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    _, result = bag
    # an empty default typestore: every type, lotsen_msgs included, must come from the bag itself
    with AnyReader([result.bag_dir], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == EXPECTED_TYPES
        got = {}
        for conn, timestamp, raw in reader.messages():
            got.setdefault(conn.topic, []).append((timestamp, reader.deserialize(raw, conn.msgtype)))
    t0, imu = got["/boat/imu/data_raw"][0]
    assert imu.linear_acceleration.z == pytest.approx(9.81) and imu.angular_velocity.y == pytest.approx(0.2)
    assert t0 > 1.6e18  # bag time: Unix ns
    assert abs(imu.header.stamp.sec + imu.header.stamp.nanosec * 1e-9 - t0 * 1e-9) < 1.0  # header stamps: Unix time too
    fix = got["/boat/gps_chatter"][0][1]
    assert (fix.latitude, fix.status.status) == (57.69, 2)
    odom = got["/boat/state/estimate"][0][1]
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (2.0, 1.0)
    assert [p.pose.position.y for p in got["/boat/planning/path"][0][1].poses] == [0.0, 5.0, 10.0]
    ship = got["/boat/ship_command"][0][1]
    assert (ship.alpha1_rad, ship.n1_rps, ship.source) == (0.1, 20.0, "mpc")
    assert got["/boat/supervisor/status"][0][1].warnings == ["gnss"]
    assert got["/boat/operator/command"][0][1].pilot_token == ""
    assert got["/boat/log"][0][1].level == 30 and got["/boat/log"][0][1].msg.startswith("hello")
    js = got["/boat/control/status"][0][1]
    assert js.lotsen_type == "ControllerStatus" and '"cross_track_error_m":0.25' in js.json
    assert math.isclose(got["/boat/battery"][0][1].voltage, 7.4, rel_tol=1e-6)


def test_export_refuses_to_overwrite_and_missing_input(bag, tmp_path):
    src, result = bag
    with pytest.raises(DataError, match="exists already"):
        export_ros2(src, result.bag_dir)
    with pytest.raises(DataError, match="no such log"):
        export_ros2(tmp_path / "nope.mcap", tmp_path / "out")


def test_the_export_command_writes_the_bag(bag, tmp_path, capsys):
    """`lotsen export RUN.mcap --ros2 OUT/` (the command the docs name) writes a bag rosbags opens."""
    from rosbags.rosbag2 import Reader

    from lotsen.cli.main import main

    src = bag[0]
    assert main(["export", str(src), "--ros2", str(tmp_path / "bag"), "--namespace", "/boat"]) == 0
    out = capsys.readouterr().out
    assert "/boat/imu/data_raw" in out and "sensor_msgs/msg/Imu" in out
    with Reader(tmp_path / "bag") as reader:
        assert reader.message_count > 0 and "/boat/imu/data_raw" in {c.topic for c in reader.connections}


def test_the_bag_offers_the_path_transient_local_and_names_its_distribution(bag):
    """A late joiner's state (the planned path) is offered transient-local, keep last 1, as the live
    ROS 2 mode publishes it; other topics reliable and volatile; metadata names ROS 2 Jazzy."""
    import yaml

    _, result = bag
    meta = yaml.safe_load((result.bag_dir / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["ros_distro"] == "jazzy"
    qos = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
           for t in meta["topics_with_message_count"]}
    path_qos = yaml.safe_load(qos["/boat/planning/path"])[0]
    state_qos = yaml.safe_load(qos["/boat/state/estimate"])[0]
    assert path_qos["durability"] == 1 and path_qos["depth"] == 1  # rmw: 1 = transient local
    assert state_qos["durability"] == 2 and state_qos["reliability"] == 1  # volatile, reliable
