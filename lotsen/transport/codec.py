"""Message encoding shared by the MCAP logs and the Zenoh bridge.

Two layers:

* **JSON form** of a `lotsen.messages` dataclass: a plain dict, field by field. Tuples become
  lists, `GnssFixType` its integer, `bytes` base64 text, a nested message a dict; non-finite floats
  become `null` (NaN) or the strings "inf" / "-inf", so the JSON is strict (Foxglove and browsers
  reject bare `NaN`). `from_jsonable` rebuilds the dataclass from the field type hints, so tuples,
  enums, bytes, NaN and nested messages come back as they were. `json_schema(cls)` generates the
  JSON schema that the MCAP channels carry. A field marked `PACKED_FLOATS` (the arrays of a
  `PlannedRoute`) is one base64 text of its float64 values, little endian, and reads back from
  that or from a list of numbers (logs written before).

* **Wire envelope** (format version 1), used on Zenoh, documented in docs/logs.md::

      offset  size  content
      0       3     magic b"LTS"
      3       1     format version (1)
      4       1     encoding: 0 = JSON, 1 = ROS 2 CDR
      5       1     flags (reserved, 0)
      6       1     n = length of the lotsen type name (ASCII), e.g. "ImuSample"
      7       n     type name
      .       1     m = length of the ROS type (CDR only, else 0), e.g. "sensor_msgs/msg/Imu"
      .       m     ROS type name
      .       1     k = length of the origin id (the sending bridge; loop avoidance)
      .       k     origin id
      .       4     payload length p, little endian
      .       p     payload: JSON text (UTF-8) or CDR bytes (with their 4-byte encapsulation header)
      .       rest  CDR only: JSON object of the lotsen fields the ROS type cannot hold (may be empty)

  ROS 2 CDR (via `rosbags`, typestore ROS2_JAZZY, `ros2_types`) is used where a standard message fits:
  `ImuSample` -> sensor_msgs/msg/Imu, `MagSample` -> sensor_msgs/msg/MagneticField,
  `GnssFix` -> sensor_msgs/msg/NavSatFix, `VesselState` -> nav_msgs/msg/Odometry; frames follow
  ROS REP 103 (body FLU, world ENU), so a ROS 2 tool reading the CDR payload sees ROS
  conventions; lotsen converts back to its NED / FRD conventions on decoding.
"""

from __future__ import annotations

import base64
import dataclasses
import enum
import functools
import json
import math
import re
import struct
import types
import typing
from typing import Any

from lotsen import messages as M
from lotsen.errors import DataError
from lotsen.model.angles import wrap_angle
from lotsen.transport import ros2_types

FORMAT_VERSION = 1
MAGIC = b"LTS"
ENC_JSON = 0
ENC_CDR = 1


class DecodeError(DataError):
    """A message cannot be decoded (unknown type, bad envelope, bad payload)."""


# ---------------------------------------------------------------------------- type registry
MESSAGE_TYPES: dict[str, type] = {
    name: getattr(M, name) for name in M.__all__
    if dataclasses.is_dataclass(getattr(M, name, None))
}


def type_name(msg: Any) -> str:
    return type(msg).__name__


def message_class(name: str) -> type:
    try:
        return MESSAGE_TYPES[name]
    except KeyError:
        raise DecodeError(f"unknown message type {name!r} (known: {', '.join(sorted(MESSAGE_TYPES))})") from None


# ---------------------------------------------------------------------------- JSON form
def _float_out(x: float) -> Any:
    if math.isfinite(x):
        return x
    if math.isnan(x):
        return None
    return "inf" if x > 0 else "-inf"


def _float_in(x: Any) -> float:
    if x is None:
        return math.nan
    if isinstance(x, str):
        if x in ("inf", "-inf", "nan"):
            return float(x)
        raise ValueError(f"expected a number, got {x!r}")
    if isinstance(x, bool):
        raise ValueError(f"expected a number, got {x!r}")
    return float(x)


def _value_out(v: Any) -> Any:
    if isinstance(v, float):
        return _float_out(v)
    if isinstance(v, enum.Enum):
        return v.value
    if isinstance(v, bool) or v is None or isinstance(v, (int, str)):
        return v
    if isinstance(v, (tuple, list)):
        return [_value_out(x) for x in v]
    if isinstance(v, (bytes, bytearray)):
        return base64.b64encode(bytes(v)).decode("ascii")
    if isinstance(v, dict):
        return {str(k): _value_out(x) for k, x in v.items()}
    if dataclasses.is_dataclass(v):
        return to_jsonable(v)
    if hasattr(v, "item"):  # numpy scalar
        return _value_out(v.item())
    if hasattr(v, "tolist"):  # numpy array
        return _value_out(v.tolist())
    return str(v)


@functools.lru_cache(maxsize=None)
def _fields(cls: type) -> tuple[tuple[str, Any], ...]:
    hints = typing.get_type_hints(cls)
    return tuple((f.name, hints[f.name]) for f in dataclasses.fields(cls) if f.init)


def _float_field(v: Any) -> Any:
    """`_value_out` of a float field, without its type tests for the usual finite float."""
    return v if type(v) is float and v - v == 0.0 else _value_out(v)  # v - v: NaN for NaN and +-inf


def _floats_field(v: Any) -> Any:
    """`_value_out` of a tuple-of-floats field, likewise."""
    if type(v) is not tuple:
        return _value_out(v)
    return [x if type(x) is float and x - x == 0.0 else _value_out(x) for x in v]


def _str_field(v: Any) -> Any:
    return v if type(v) is str else _value_out(v)


def _packed(cls: type) -> frozenset[str]:
    """The fields of `cls` whose JSON form is packed (`lotsen.messages.PACKED_FLOATS`)."""
    return frozenset(f.name for f in dataclasses.fields(cls) if f.metadata.get("packed") == "float64le")


def _packed_out(v: Any) -> str:
    """A tuple of floats as the base64 of its float64 values, little endian (NaN and inf as they are)."""
    import numpy as np

    return base64.b64encode(np.asarray(v, dtype="<f8").tobytes()).decode("ascii")


def _packed_in(v: Any) -> tuple:
    """A packed field back: base64 text, or a list of numbers (what older writers and logs have)."""
    if isinstance(v, str):
        import numpy as np

        raw = base64.b64decode(v, validate=True)
        if len(raw) % 8:
            raise ValueError(f"packed floats: {len(raw)} bytes is not a whole number of float64")
        return tuple(np.frombuffer(raw, dtype="<f8").tolist())
    if not isinstance(v, (list, tuple)):
        raise ValueError(f"expected base64 text or a list of numbers, got {type(v).__name__}")
    return tuple(_float_in(x) for x in v)


@functools.lru_cache(maxsize=None)
def _field_encoders(cls: type) -> tuple[tuple[str, Any], ...]:
    """Per field, a function giving the JSON form of its value: `_value_out`, with a shortcut for
    the value the type hint names (floats, tuples of floats, text); any other value takes the
    general path, so the JSON is the same whatever a publisher put in the field."""
    out = []
    packed = _packed(cls)
    for name, tp in _fields(cls):
        args = typing.get_args(tp)
        if name in packed:
            enc = _packed_out
        elif tp is float:
            enc = _float_field
        elif tp is str:
            enc = _str_field
        elif typing.get_origin(tp) is tuple and args and all(a is float or a is Ellipsis for a in args):
            enc = _floats_field
        else:
            enc = _value_out
        out.append((name, enc))
    return tuple(out)


def to_jsonable(msg: Any) -> dict:
    """The JSON form of a message dataclass (see module docstring)."""
    return {name: enc(getattr(msg, name)) for name, enc in _field_encoders(type(msg))}


def _ident(v: Any) -> Any:
    return v


def _to_int(v: Any) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ValueError(f"expected an integer, got {v!r}")
    return int(v)


def _to_bytes(v: Any) -> bytes:
    return base64.b64decode(v, validate=True) if isinstance(v, str) else bytes(v)


@functools.lru_cache(maxsize=None)
def _decoder(tp: Any) -> Any:
    """A function turning the JSON form of type `tp` back into the value (built once per type)."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is float:
        return _float_in
    if tp is int:
        return _to_int
    if tp is bool:
        return bool
    if tp is str:
        return str
    if tp is bytes:
        return _to_bytes
    if tp is Any:
        return _ident
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return tp
    if origin in (typing.Union, types.UnionType):
        options = [_decoder(a) for a in args if a is not type(None)]
        nullable = type(None) in args

        def union(v: Any) -> Any:
            if v is None and nullable:
                return None
            for dec in options:
                try:
                    return dec(v)
                except (TypeError, ValueError, KeyError, DecodeError):
                    continue
            raise ValueError(f"{v!r} matches none of {tp}")
        return union
    if origin is tuple:
        if args and args[-1] is not Ellipsis:
            decs = [_decoder(a) for a in args]
            n = len(decs)

            def fixed(v: Any) -> tuple:
                if len(v) != n:
                    raise ValueError(f"expected {n} values, got {len(v)}")
                return tuple(d(x) for d, x in zip(decs, v))
            return fixed
        inner = _decoder(args[0]) if args else _ident
        return lambda v: tuple(inner(x) for x in v)
    if origin is list:
        inner = _decoder(args[0]) if args else _ident
        return lambda v: [inner(x) for x in v]
    if origin is dict or tp is dict:
        return dict
    if dataclasses.is_dataclass(tp):
        return lambda v: from_jsonable(tp, v)
    return _ident


@functools.lru_cache(maxsize=None)
def _field_decoders(cls: type) -> tuple[tuple[str, Any], ...]:
    packed = _packed(cls)
    return tuple((name, _packed_in if name in packed else _decoder(tp)) for name, tp in _fields(cls))


def from_jsonable(cls: type | str, data: dict) -> Any:
    """Rebuild a message from its JSON form; unknown keys are ignored (newer writers), missing keys
    take the dataclass default (older writers)."""
    if isinstance(cls, str):
        cls = message_class(cls)
    if not isinstance(data, dict):
        raise DecodeError(f"{cls.__name__}: expected a JSON object, got {type(data).__name__}")
    kwargs = {}
    for name, dec in _field_decoders(cls):
        if name in data:
            try:
                kwargs[name] = dec(data[name])
            except (TypeError, ValueError) as exc:
                raise DecodeError(f"{cls.__name__}.{name}: bad value {data[name]!r}: {exc}") from None
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise DecodeError(f"{cls.__name__}: {exc}") from None


_JSON_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False)  # json.dumps's, made once


def encode_json(msg: Any) -> bytes:
    return _JSON_ENCODER.encode(to_jsonable(msg)).encode("utf-8")


def decode_json(cls: type | str, data: bytes | str) -> Any:
    try:
        obj = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        name = cls if isinstance(cls, str) else cls.__name__
        raise DecodeError(f"{name}: payload is not valid JSON: {exc}") from None
    return from_jsonable(cls, obj)


# ---------------------------------------------------------------------------- JSON schema
_NUMBER = {"type": ["number", "null", "string"]}  # null = NaN, "inf"/"-inf"
_PACKED_SCHEMA = {"type": "string", "contentEncoding": "base64",
                  "description": "float64 values, little endian (older writers: an array of numbers)"}


def _schema_of(tp: Any) -> dict:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is float:
        return dict(_NUMBER)
    if tp is int:
        return {"type": "integer"}
    if tp is bool:
        return {"type": "boolean"}
    if tp is str:
        return {"type": "string"}
    if tp is bytes:
        return {"type": "string", "contentEncoding": "base64"}
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return {"type": "integer", "enum": [m.value for m in tp],
                "description": ", ".join(f"{m.value}={m.name}" for m in tp)}
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [({"type": "null"} if a is type(None) else _schema_of(a)) for a in args]}
    if origin is tuple:
        if args and args[-1] is not Ellipsis:
            return {"type": "array", "items": [_schema_of(a) for a in args], "minItems": len(args),
                    "maxItems": len(args)}
        return {"type": "array", "items": _schema_of(args[0]) if args else {}}
    if origin is list:
        return {"type": "array", "items": _schema_of(args[0]) if args else {}}
    if origin is dict or tp is dict:
        return {"type": "object"}
    if dataclasses.is_dataclass(tp):
        return json_schema(tp)
    return {}


@functools.lru_cache(maxsize=None)
def _json_schema_cached(cls: type) -> str:
    packed = _packed(cls)
    props = {name: _PACKED_SCHEMA if name in packed else _schema_of(tp) for name, tp in _fields(cls)}
    required = [f.name for f in dataclasses.fields(cls) if f.init and f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING]
    doc = (cls.__doc__ or "").strip().splitlines()
    schema = {"title": f"lotsen.{cls.__name__}", "type": "object", "properties": props, "required": required}
    if doc and not doc[0].startswith(cls.__name__ + "("):
        schema["description"] = doc[0]
    return json.dumps(schema)


def json_schema(cls: type) -> dict:
    """JSON schema of a message dataclass's JSON form."""
    return json.loads(_json_schema_cached(cls))


def schema_name(cls: type) -> str:
    return f"lotsen.{cls.__name__}"


# ---------------------------------------------------------------------------- ROS 2 CDR
def _typestore():
    # one typestore for every ROS 2 use in lotsen: ROS 2 Jazzy's standard types + lotsen_msgs
    # (the CDR of the four types below is the same in Humble, Jazzy and Kilted)
    return ros2_types.typestore()


ROS_TYPE_OF = {
    "ImuSample": "sensor_msgs/msg/Imu",
    "MagSample": "sensor_msgs/msg/MagneticField",
    "GnssFix": "sensor_msgs/msg/NavSatFix",
    "VesselState": "nav_msgs/msg/Odometry",
}
BODY_FRAME = "base_link"  # ROS body frame: x forward, y LEFT, z up (FLU); lotsen's body is FRD
WORLD_FRAME = "map"  # ENU: x east, y north, z up; lotsen's world is NED


def _stamp(T: Any, stamp_s: float) -> Any:
    if not math.isfinite(stamp_s):
        stamp_s = 0.0
    sec = math.floor(stamp_s)
    nsec = min(int(round((stamp_s - sec) * 1e9)), 999_999_999)
    return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _header(stamp_s: float, frame: str) -> Any:
    T = _typestore().types
    return T["std_msgs/msg/Header"](stamp=_stamp(T, stamp_s), frame_id=frame)


def _stamp_s(header: Any) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _cov(diag: list[float], n: int) -> Any:
    import numpy as np

    c = np.zeros(n * n)
    for i, d in enumerate(diag):
        c[i * n + i] = d
    return c


def _to_ros(msg: Any) -> tuple[Any, dict]:
    """(ROS message, extension dict of lotsen fields ROS cannot hold)."""
    import numpy as np

    T = _typestore().types
    V3 = T["geometry_msgs/msg/Vector3"]
    Q = T["geometry_msgs/msg/Quaternion"]
    name = type(msg).__name__
    if name == "ImuSample":
        g, a = msg.gyro_radps, msg.accel_mps2
        cov_unknown = np.zeros(9)
        orient_cov = np.zeros(9)
        orient_cov[0] = -1.0  # REP 145: no orientation estimate
        ros = T["sensor_msgs/msg/Imu"](
            header=_header(msg.stamp_s, BODY_FRAME), orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=orient_cov,
            angular_velocity=V3(x=g[0], y=-g[1], z=-g[2]), angular_velocity_covariance=cov_unknown,
            linear_acceleration=V3(x=a[0], y=-a[1], z=-a[2]), linear_acceleration_covariance=cov_unknown.copy())
        return ros, {}
    if name == "MagSample":
        f = msg.field_uT
        ros = T["sensor_msgs/msg/MagneticField"](
            header=_header(msg.stamp_s, BODY_FRAME),
            magnetic_field=V3(x=f[0] * 1e-6, y=-f[1] * 1e-6, z=-f[2] * 1e-6),  # tesla, FLU
            magnetic_field_covariance=np.zeros(9))
        return ros, {}
    if name == "GnssFix":
        St = T["sensor_msgs/msg/NavSatStatus"]
        ft = M.GnssFixType(msg.fix_type)
        status = (St.STATUS_NO_FIX if ft < M.GnssFixType.FIX_2D else
                  St.STATUS_GBAS_FIX if ft >= M.GnssFixType.RTK_FLOAT else St.STATUS_FIX)
        known = math.isfinite(msg.h_acc_m)
        v_acc = msg.v_acc_m if math.isfinite(msg.v_acc_m) else 0.0
        ros = T["sensor_msgs/msg/NavSatFix"](
            header=_header(msg.stamp_s, "gnss"), status=St(status=status, service=St.SERVICE_GPS),
            latitude=msg.lat_deg, longitude=msg.lon_deg, altitude=msg.height_m,
            position_covariance=_cov([msg.h_acc_m ** 2, msg.h_acc_m ** 2, v_acc ** 2] if known else [], 3),
            position_covariance_type=(T["sensor_msgs/msg/NavSatFix"].COVARIANCE_TYPE_DIAGONAL_KNOWN if known
                                      else T["sensor_msgs/msg/NavSatFix"].COVARIANCE_TYPE_UNKNOWN))
        ext = {"fix_type": int(ft), "h_acc_m": msg.h_acc_m, "v_acc_m": msg.v_acc_m, "vel_n_mps": msg.vel_n_mps,
               "vel_e_mps": msg.vel_e_mps, "num_sv": msg.num_sv, "correction_age_s": msg.correction_age_s}
        return ros, ext
    if name == "VesselState":
        yaw_enu = math.pi / 2 - msg.heading_rad
        std = list(msg.std) if len(msg.std) >= 6 else []
        var = [s * s for s in std]
        pose_cov = _cov([var[1], var[0], 0, 0, 0, var[2]] if var else [], 6)
        twist_cov = _cov([var[3], var[4], 0, 0, 0, var[5]] if var else [], 6)
        ros = T["nav_msgs/msg/Odometry"](
            header=_header(msg.stamp_s, WORLD_FRAME), child_frame_id=BODY_FRAME,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=T["geometry_msgs/msg/Pose"](
                    position=T["geometry_msgs/msg/Point"](x=msg.east_m, y=msg.north_m, z=0.0),
                    orientation=Q(x=0.0, y=0.0, z=math.sin(yaw_enu / 2), w=math.cos(yaw_enu / 2))),
                covariance=pose_cov),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=V3(x=msg.u_mps, y=-msg.v_mps, z=0.0),
                                                   angular=V3(x=0.0, y=0.0, z=-msg.r_radps)),
                covariance=twist_cov))
        # heading kept exactly (the quaternion wraps it), std exactly (covariance squares it), and the
        # fields Odometry has no place for (the current, the body force, the wave displacement)
        ext = {"heading_rad": msg.heading_rad, "source": msg.source, "std": list(msg.std),
               "gyro_bias_radps": msg.gyro_bias_radps, "current_ne_mps": list(msg.current_ne_mps),
               "disturbance_tau": list(msg.disturbance_tau), "wave_motion": list(msg.wave_motion)}
        return ros, ext
    raise DecodeError(f"no ROS 2 type for {name}")


def _from_ros(name: str, ros: Any, ext: dict) -> Any:
    if name == "ImuSample":
        g, a = ros.angular_velocity, ros.linear_acceleration
        return M.ImuSample(stamp_s=_stamp_s(ros.header), gyro_radps=(g.x, -g.y, -g.z), accel_mps2=(a.x, -a.y, -a.z))
    if name == "MagSample":
        f = ros.magnetic_field
        return M.MagSample(stamp_s=_stamp_s(ros.header), field_uT=(f.x * 1e6, -f.y * 1e6, -f.z * 1e6))
    if name == "GnssFix":
        base = {"stamp_s": _stamp_s(ros.header), "lat_deg": ros.latitude, "lon_deg": ros.longitude,
                "height_m": ros.altitude}
        if "fix_type" not in ext:  # a plain ROS NavSatFix: infer what we can
            ext = {"fix_type": int(M.GnssFixType.NO_FIX if ros.status.status < 0 else
                                   M.GnssFixType.RTK_FIXED if ros.status.status == 2 else M.GnssFixType.FIX_3D),
                   "h_acc_m": math.sqrt(ros.position_covariance[0]) if ros.position_covariance_type else None}
        return from_jsonable(M.GnssFix, {**ext, **base})
    if name == "VesselState":
        p = ros.pose.pose
        q = p.orientation
        yaw_enu = 2 * math.atan2(q.z, q.w)
        tw = ros.twist.twist
        base = {"stamp_s": _stamp_s(ros.header), "north_m": p.position.y, "east_m": p.position.x,
                "heading_rad": wrap_angle(math.pi / 2 - yaw_enu), "u_mps": tw.linear.x,
                "v_mps": -tw.linear.y, "r_radps": -tw.angular.z}
        return from_jsonable(M.VesselState, {**base, **ext})
    raise DecodeError(f"no ROS 2 type for {name}")


def encode_cdr(msg: Any) -> tuple[str, bytes, dict]:
    """(ROS type name, CDR bytes, extension dict)."""
    ros, ext = _to_ros(msg)
    rtype = ROS_TYPE_OF[type(msg).__name__]
    return rtype, bytes(_typestore().serialize_cdr(ros, rtype)), ext


def decode_cdr(name: str, rtype: str, data: bytes, ext: dict | None = None) -> Any:
    try:
        ros = _typestore().deserialize_cdr(data, rtype)
    except Exception as exc:  # rosbags raises several kinds on short/garbled data
        raise DecodeError(f"{name}: CDR payload of {rtype} cannot be decoded: {exc}") from None
    return _from_ros(name, ros, ext or {})


# ---------------------------------------------------------------------------- envelope
@dataclasses.dataclass(frozen=True)
class Envelope:
    version: int
    encoding: int
    type_name: str
    ros_type: str
    origin: str
    payload: bytes
    extension: bytes


def _short(s: str, what: str) -> bytes:
    b = s.encode("utf-8")
    if len(b) > 255:
        raise ValueError(f"{what} longer than 255 bytes: {s[:40]!r}...")
    return bytes([len(b)]) + b


def encode(msg: Any, encoding: str = "auto", origin: str = "") -> bytes:
    """Envelope bytes for `msg`. encoding: "json", "cdr" (ValueError if no ROS type fits) or
    "auto" (CDR where a ROS type fits, else JSON)."""
    name = type(msg).__name__
    if name not in MESSAGE_TYPES:
        raise DecodeError(f"cannot encode {name}: not a lotsen.messages type")
    use_cdr = encoding == "cdr" or (encoding == "auto" and name in ROS_TYPE_OF)
    if use_cdr:
        if name not in ROS_TYPE_OF:
            raise ValueError(f"no ROS 2 type for {name}; use JSON")
        rtype, payload, ext = encode_cdr(msg)
        ext_b = json.dumps({k: _value_out(v) for k, v in ext.items()}, separators=(",", ":"),
                           allow_nan=False).encode() if ext else b""
    else:
        rtype, payload, ext_b = "", encode_json(msg), b""
    return b"".join([_envelope_head(ENC_CDR if use_cdr else ENC_JSON, name, rtype, origin),
                     struct.pack("<I", len(payload)), payload, ext_b])


@functools.lru_cache(maxsize=1024)
def _envelope_head(encoding: int, name: str, rtype: str, origin: str) -> bytes:
    """The envelope up to the payload length: the same for every message of a type from a sender."""
    return b"".join([MAGIC, bytes([FORMAT_VERSION, encoding, 0]), _short(name, "type name"),
                     _short(rtype, "ROS type"), _short(origin, "origin")])


def parse_envelope(data: bytes) -> Envelope:
    data = bytes(data)
    if len(data) < 7 or data[:3] != MAGIC:
        raise DecodeError(f"not a lotsen envelope (magic {data[:3]!r}, {len(data)} bytes)")
    version, enc = data[3], data[4]
    if version != FORMAT_VERSION:
        raise DecodeError(f"envelope format version {version} not supported (this lotsen reads {FORMAT_VERSION})")
    pos = 6
    fields = []
    try:
        for _ in range(3):
            n = data[pos]
            fields.append(data[pos + 1:pos + 1 + n].decode("utf-8"))
            pos += 1 + n
        (plen,) = struct.unpack_from("<I", data, pos)
    except (IndexError, struct.error, UnicodeDecodeError):
        raise DecodeError(f"truncated envelope header at byte {pos} of {len(data)}") from None
    pos += 4
    if pos + plen > len(data):
        raise DecodeError(f"envelope payload claims {plen} bytes, only {len(data) - pos} present")
    return Envelope(version, enc, fields[0], fields[1], fields[2], data[pos:pos + plen], data[pos + plen:])


def decode(data: bytes) -> tuple[Any, Envelope]:
    """(message, envelope) from envelope bytes; DecodeError names what is wrong."""
    env = parse_envelope(data)
    return decode_envelope(env), env


def decode_envelope(env: Envelope) -> Any:
    """The message an envelope carries; DecodeError names what is wrong."""
    if env.encoding == ENC_JSON:
        return decode_json(env.type_name, env.payload)
    if env.encoding == ENC_CDR:
        try:
            ext = json.loads(env.extension) if env.extension else {}
        except ValueError as exc:
            raise DecodeError(f"{env.type_name}: bad extension JSON: {exc}") from None
        message_class(env.type_name)
        return decode_cdr(env.type_name, env.ros_type, env.payload, ext)
    raise DecodeError(f"unknown envelope encoding {env.encoding}")


_FIRST_STAMP = re.compile(rb'\{"stamp_s":([^,}]*)')


def json_stamp_s(payload: bytes) -> float:
    """`stamp_s` of a message's JSON form without decoding the rest; NaN when it has none or it is
    not finite (its JSON form is then null, "inf" or "-inf"). Every message's first field is its
    stamp, so this reads only the first value; any other layout is parsed in full."""
    first = _FIRST_STAMP.match(payload)
    if first is None:
        try:
            value = json.loads(payload).get("stamp_s")
        except (ValueError, AttributeError):
            return math.nan
        return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else math.nan
    token = first.group(1)
    try:
        return float(token)  # null, "inf" and "-inf" are not float literals
    except ValueError:
        return math.nan
