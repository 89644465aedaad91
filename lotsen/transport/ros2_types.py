"""ROS 2 message types known to lotsen: the standard ones (rosbags' typestore of ROS 2 Jazzy) plus
the `lotsen_msgs` package, read from its .msg files in `lotsen/transport/lotsen_msgs/msg/` (the single source
of truth: the same files build the package in a ROS 2 workspace).

Names and hashes as ROS 2 uses them on the wire:

* `dds_type_name("sensor_msgs/msg/Imu")` -> `"sensor_msgs::msg::dds_::Imu_"` (the type name in
  rmw_zenoh key expressions and liveliness tokens);
* `type_hash("sensor_msgs/msg/Imu")` -> `"RIHS01_<sha256 hex>"`, the REP-2016 type version hash that
  rosidl generates (computed by rosbags' `hash_rihs01` from the message definitions; the tests
  compare it with published hashes of standard types);
* `message_definition(name)` -> the ros2msg text with its dependencies concatenated, as rosbag2's
  MCAP storage and Foxglove expect it.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

from lotsen.errors import ConfigError

LOTSEN_MSGS = "lotsen_msgs"


def msg_dir() -> Path:
    """`lotsen/transport/lotsen_msgs/msg`: the ROS 2 package's .msg files, shipped inside the lotsen
    package (package data), so an installed wheel on the boat has them too."""
    return Path(__file__).resolve().parent / LOTSEN_MSGS / "msg"


def lotsen_msg_files() -> dict[str, str]:
    """{"lotsen_msgs/msg/<Name>": .msg text} for every file of the package."""
    d = msg_dir()
    files = sorted(d.glob("*.msg")) if d.is_dir() else []
    if not files:
        raise ConfigError(f"ROS 2 messages: no .msg files in {d} (they ship as package data of lotsen.transport)")
    return {f"{LOTSEN_MSGS}/msg/{f.stem}": f.read_text(encoding="utf-8") for f in files}


@functools.lru_cache(maxsize=1)
def typestore() -> Any:
    """rosbags typestore: ROS 2 Jazzy standard types + lotsen_msgs (built once; without the .msg
    files only the standard types: the envelope's CDR needs no more, the ROS 2 bridge checks)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    try:
        files = lotsen_msg_files()
    except ConfigError:  # an install without the source tree: the standard types still work
        files = {}
    types: dict = {}
    for name, text in files.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


def dds_type_name(ros_type: str) -> str:
    """"pkg/msg/Type" -> "pkg::msg::dds_::Type_" (rmw type name of a CDR-encoded type)."""
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"not a ROS 2 type name: {ros_type!r} (expected pkg/msg/Type)")
    return f"{parts[0]}::{parts[1]}::dds_::{parts[2]}_"


def ros_type_of_dds(dds: str) -> str:
    """Inverse of `dds_type_name`."""
    parts = dds.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise ValueError(f"not a DDS type name: {dds!r}")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


@functools.lru_cache(maxsize=None)
def type_hash(ros_type: str) -> str:
    """REP-2016 type hash "RIHS01_<64 hex>" of a known type."""
    return typestore().hash_rihs01(ros_type)


@functools.lru_cache(maxsize=None)
def message_definition(ros_type: str) -> str:
    """The ros2msg definition with every dependency appended (rosbag2 / Foxglove form)."""
    text, fmt = typestore().generate_msgdef(ros_type, ros_version=2)
    return text


def serialize(msg: Any, ros_type: str) -> bytes:
    return bytes(typestore().serialize_cdr(msg, ros_type))


def deserialize(data: bytes, ros_type: str) -> Any:
    return typestore().deserialize_cdr(data, ros_type)
