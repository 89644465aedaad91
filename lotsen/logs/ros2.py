"""Export a lotsen MCAP log as a ROS 2 bag that `ros2 bag info / play` accept.

    from lotsen.logs.ros2 import export_ros2
    result = export_ros2("logs/2026-11-22_run003.mcap", "bags/run003", namespace="/boat")
    # bags/run003/metadata.yaml + bags/run003/run003.mcap

The bag is a rosbag2 directory written by rosbags' rosbag2 writer with the MCAP storage plugin
(what `ros2 bag record -s mcap` produces): `metadata.yaml` (rosbag2 metadata version 8, storage
identifier `mcap`) and one MCAP file with profile `ros2`, one schema per ROS type (encoding
`ros2msg`, name `pkg/msg/Type`, the definition with every dependency appended after
`====...` / `MSG: pkg/Type` separators), channels with message encoding `cdr` and an
`offered_qos_profiles` entry, and a `rosbag2` metadata record. Foxglove reads the same file
natively (ros2msg + cdr).

Messages: every lotsen channel of the source log, converted by `lotsen.transport.ros2_map`
(sensor_msgs/Imu, MagneticField, NavSatFix, BatteryState; nav_msgs/Odometry, Path;
rcl_interfaces/Log; lotsen_msgs/ShipCommand, VelocityCommand, AngleCommand, SupervisorStatus,
OperatorCommand; lotsen_msgs/JsonMessage for the rest, in lotsen's exact JSON form). The
Foxglove view channels of the source (protobuf, `foxglove/...`) are not copied: the ROS types
carry the same information and Foxglove draws them.

Times: bag timestamp = the MCAP log time of the source (receipt time as Unix ns); header stamps
= `stamp_s` + the log's epoch offset (`publish_time - stamp_s` of its first message), so they
are Unix times as in a ROS 2 recording.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable

from lotsen.errors import DataError, LotsenError
from lotsen.logs.reader import LogReader
from lotsen.messages import LATCHED_TOPICS
from lotsen.transport import ros2_map, ros2_types
from lotsen.transport.rmw_zenoh import fully_qualified

ROSBAG2_VERSION = 8  # rosbag2 metadata version read by Jazzy and later
ROS_DISTRO = "jazzy"  # the distribution the bags and the live ROS 2 mode target (rmw_zenoh binaries)


@dataclass
class Ros2ExportResult:
    bag_dir: Path
    mcap_path: Path
    topics: dict[str, tuple[str, int]] = field(default_factory=dict)  # ROS topic -> (ROS type, messages)
    skipped_channels: dict[str, int] = field(default_factory=dict)  # source topics not lotsen-decodable
    messages: int = 0
    errors: int = 0  # messages that could not be converted (counted, not fatal)


def export_ros2(src_mcap: str | os.PathLike, out_dir: str | os.PathLike, namespace: str = "",
                topics: list[str] | None = None) -> Ros2ExportResult:
    """Write the ROS 2 bag directory `out_dir` (must not exist) from the lotsen log `src_mcap`.

    `namespace` prefixes every topic (`"/boat"` -> `/boat/imu/data_raw`, as the live ROS 2 mode
    names them); `topics` limits the export to these lotsen topics (None = all). A failed export
    leaves no half-written bag."""
    src, out = Path(src_mcap), Path(out_dir)
    if not src.is_file():
        raise DataError(f"{src}: no such log file")
    if out.exists() or out.is_symlink():
        raise DataError(f"{out}: exists already; a ROS 2 bag is written into a new directory")
    if not out.parent.is_dir():
        raise DataError(f"{out}: cannot write the ROS 2 bag: the folder {out.parent} does not exist")
    reader = LogReader(src)
    try:
        return _write_bag(reader, out, namespace, topics)
    except LotsenError:
        shutil.rmtree(out, ignore_errors=True)
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' own errors (a name it refuses, a full disk): no half bag
        shutil.rmtree(out, ignore_errors=True)
        raise DataError(f"{out}: cannot write the ROS 2 bag: {type(exc).__name__}: {str(exc)[:200]}") from None


def _write_bag(reader: LogReader, out: Path, namespace: str, topics: Iterable[str] | None) -> Ros2ExportResult:
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = ros2_types.typestore()
    result = Ros2ExportResult(bag_dir=out, mcap_path=out / f"{out.name}.mcap")
    connections: dict[tuple[str, str], object] = {}
    offset_s: float | None = None
    wanted = set(topics) if topics is not None else None
    with Writer(out, version=ROSBAG2_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        for rec in reader.read(topics, raw=True):
            if not rec.schema.startswith("lotsen.") or isinstance(rec.message, (bytes, bytearray, memoryview)):
                if wanted is None or rec.topic in wanted:
                    result.skipped_channels[rec.topic] = result.skipped_channels.get(rec.topic, 0) + 1
                continue
            msg = rec.message
            if offset_s is None:
                offset_s = rec.publish_time_ns * 1e-9 - msg.stamp_s if hasattr(msg, "stamp_s") else 0.0
            try:
                rtype, data = ros2_map.encode(msg, offset_s)
            except Exception:  # noqa: BLE001 - one odd message must not stop the export
                result.errors += 1
                continue
            ros_topic = fully_qualified(namespace, rec.topic)
            conn = connections.get((ros_topic, rtype))
            if conn is None:
                conn = connections[(ros_topic, rtype)] = writer.add_connection(
                    ros_topic, rtype, typestore=store, offered_qos_profiles=[offered_qos(rec.topic)])
            writer.write(conn, rec.log_time_ns, data)
            _, n = result.topics.get(ros_topic, (rtype, 0))
            result.topics[ros_topic] = (rtype, n + 1)
            result.messages += 1
    _name_the_distribution(out / "metadata.yaml")
    return result


def offered_qos(topic: str) -> object:
    """The QoS a ROS 2 publisher of `topic` offers (as the live ROS 2 mode does): transient local,
    keep last 1 for the latched state a late joiner needs; reliable, volatile, keep last 10 else."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    latched = topic in LATCHED_TOPICS
    never = QosTime(sec=0x7FFFFFFF, nsec=0xFFFFFFFF)  # rosbag2's "infinite" duration
    return Qos(history=QosHistory.KEEP_LAST, depth=1 if latched else 10, reliability=QosReliability.RELIABLE,
               durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
               deadline=never, lifespan=never, liveliness=QosLiveliness.AUTOMATIC,
               liveliness_lease_duration=never, avoid_ros_namespace_conventions=False)


def _name_the_distribution(metadata: Path) -> None:
    """rosbags writes `ros_distro: rosbags`; `ros2 bag info` shows the distribution the bag targets."""
    text = metadata.read_text(encoding="utf-8")
    metadata.write_text(text.replace("ros_distro: rosbags", f"ros_distro: {ROS_DISTRO}"), encoding="utf-8")
