"""The ROS 2 wire format on Zenoh, as `rmw_zenoh_cpp` (the ROS 2 RMW for Zenoh: Tier 1 in Kilted,
binary packages for Jazzy) documents it in its docs/design.md (rmw_zenoh 0.2+ on Zenoh 1.x):

* **Data key expression** of a topic: `<domain_id>/<fully qualified name without the leading
  slash>/<DDS type name>/<type hash>`, e.g.
  `0/boat/imu/data_raw/sensor_msgs::msg::dds_::Imu_/RIHS01_7d9a00ff...`.
* **Payload**: the CDR serialized message *with* its 4-byte encapsulation header (what rosbags'
  `serialize_cdr` produces).
* **Attachment** of each put: sequence number (int64 little endian), source timestamp (ns since
  the Unix epoch, int64 little endian), publisher GID length (1 byte, 16) and the 16 GID bytes
  (the Zenoh serialization of `(int64, int64, [u8; 16])`).
* **Liveliness tokens** (the ROS graph: `ros2 node list`, `ros2 topic list`):
  `@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>`
  for a node (kind NN, entity id = node id), with
  `/<topic>/<DDS type>/<type hash>/<qos>` appended for a publisher (MP) or subscription (MS);
  names "mangled" (`/` -> `%`; an empty namespace or enclave is `%`); QoS in rmw_zenoh's compact
  form, fields left empty where they equal rmw_zenoh's defaults (reliable, volatile, keep last 42,
  infinite deadline / lifespan / lease, automatic liveliness).

The GID in the attachment is, as rmw_zenoh makes it, XXH3-128 of the entity's liveliness key
expression, its low 64 bits then its high 64 bits, each little endian: a ROS 2 tool that
compares the GID with the one it derives from the liveliness token sees the same publisher.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import xxhash

from lotsen.transport.ros2_types import dds_type_name, type_hash

ADMIN_SPACE = "@ros2_lv"
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE


def _check_name(name: str, what: str) -> str:
    if not name.startswith("/") or "//" in name or (len(name) > 1 and name.endswith("/")):
        raise ValueError(f"{what} {name!r} is not a fully qualified ROS name (e.g. /boat/imu/data_raw)")
    return name


def fully_qualified(namespace: str, topic: str) -> str:
    """'/boat' + 'imu/data_raw' -> '/boat/imu/data_raw' (a topic starting with '/' is absolute)."""
    if topic.startswith("/"):
        return _check_name(topic, "topic")
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return _check_name(f"{ns}/{topic.strip('/')}", "topic")


def topic_key(domain_id: int, fq_topic: str, ros_type: str, hash_: str | None = None) -> str:
    """Data key expression of a topic; `hash_="*"` for a subscription accepting any version."""
    _check_name(fq_topic, "topic")
    return f"{int(domain_id)}/{fq_topic.strip('/')}/{dds_type_name(ros_type)}/{hash_ or type_hash(ros_type)}"


def mangle(name: str) -> str:
    return name.replace("/", "%") if name else "%"


@dataclass(frozen=True)
class Qos:
    """The QoS policies rmw_zenoh puts in liveliness tokens (rmw enum values)."""

    reliability: int = 1  # 1 reliable, 2 best effort
    durability: int = 2  # 1 transient local, 2 volatile
    history: int = 1  # 1 keep last, 2 keep all
    depth: int = 10

    def keyexpr(self) -> str:
        """rmw_zenoh's compact form: fields equal to its defaults are left empty."""
        rel = "" if self.reliability == 1 else str(self.reliability)
        dur = "" if self.durability == 2 else str(self.durability)
        hist = "" if self.history == 1 else str(self.history)
        depth = "" if self.depth == 42 else str(self.depth)
        return f"{rel}:{dur}:{hist},{depth}:,:,:,,"


SENSOR_QOS = Qos(reliability=2, depth=5)  # rclcpp's SensorDataQoS
DEFAULT_QOS = Qos()  # rclcpp's default: reliable, volatile, keep last 10
LATCHED_QOS = Qos(durability=1, depth=1)  # a latched topic: reliable, transient local, keep last 1


def node_token(domain_id: int, session_id: str, node_id: int, namespace: str, node: str, enclave: str = "/") -> str:
    return (f"{ADMIN_SPACE}/{int(domain_id)}/{session_id}/{node_id}/{node_id}/NN/{mangle(enclave)}/"
            f"{mangle(namespace)}/{mangle(node)}")


def entity_token(domain_id: int, session_id: str, node_id: int, entity_id: int, kind: str, namespace: str,
                 node: str, fq_topic: str, ros_type: str, qos: Qos = DEFAULT_QOS, enclave: str = "/") -> str:
    if kind not in ("MP", "MS"):
        raise ValueError(f"entity kind {kind!r}: expected MP or MS")
    return (f"{ADMIN_SPACE}/{int(domain_id)}/{session_id}/{node_id}/{entity_id}/{kind}/{mangle(enclave)}/"
            f"{mangle(namespace)}/{mangle(node)}/{mangle(fq_topic)}/{dds_type_name(ros_type)}/"
            f"{type_hash(ros_type)}/{qos.keyexpr()}")


@dataclass(frozen=True)
class TokenInfo:
    """What a liveliness token says (enough for a graph view and for tests)."""

    domain_id: int
    session_id: str
    kind: str
    namespace: str
    node: str
    topic: str = ""
    dds_type: str = ""
    type_hash: str = ""
    qos: str = ""


def parse_token(key: str) -> TokenInfo:
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE:
        raise ValueError(f"not an rmw_zenoh liveliness token: {key!r}")

    def demangle(s: str) -> str:
        return s.replace("%", "/")
    info = TokenInfo(int(parts[1]), parts[2], parts[5], demangle(parts[7]), demangle(parts[8]))
    if len(parts) >= 13:
        info = TokenInfo(info.domain_id, info.session_id, info.kind, info.namespace, info.node,
                         demangle(parts[9]), parts[10], parts[11], parts[12])
    return info


def gid_for(token_key: str) -> bytes:
    """The publisher's 16-byte GID: XXH3-128 of its liveliness key, low then high half, little
    endian (see module docstring)."""
    return xxhash.xxh3_128_intdigest(token_key.encode("utf-8")).to_bytes(GID_SIZE, "little")


def encode_attachment(sequence_number: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    if len(gid) != GID_SIZE:
        raise ValueError(f"GID must be {GID_SIZE} bytes, got {len(gid)}")
    return struct.pack("<qqB", sequence_number, source_timestamp_ns, GID_SIZE) + gid


@dataclass(frozen=True)
class Attachment:
    sequence_number: int
    source_timestamp_ns: int
    gid: bytes


def decode_attachment(data: bytes | None) -> Attachment | None:
    """None when absent or not in rmw_zenoh's form (a sample from a non-ROS publisher)."""
    if data is None or len(data) != ATTACHMENT_SIZE or data[16] != GID_SIZE:
        return None
    seq, ts = struct.unpack_from("<qq", data, 0)
    return Attachment(seq, ts, bytes(data[17:]))
