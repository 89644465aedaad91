"""ArduPilot SITL's JSON physics protocol, both directions, as bytes (pure: no sockets).

The flight controller's side (here: lotsen) sends one binary **servo packet** per frame
(little-endian, ArduPilot's libraries/SITL/SIM_JSON.cpp and examples/JSON/readme.md):

    uint16 magic        18458 (16 channels) or 29569 (32 channels)
    uint16 frame_rate   the time step the physics should take, 1 / frame_rate s
    uint32 frame_count  +1 per frame; the same count again is a retransmission (do not step
                        twice), a smaller count a restart (reset the vehicle)
    uint16 pwm[16|32]   servo outputs in microseconds (0 on a channel nobody drives)

The physics answers every servo packet with one line of **JSON** ("\\n{...}\\n"):

    timestamp           s, the physics time (absolute, not the step)
    imu.gyro            [roll, pitch, yaw] rates, rad/s, body frame
    imu.accel_body      [x, y, z] specific force, m/s^2, body frame (z = -9.8 at rest)
    position            [north, east, down], m, earth frame
    velocity            [north, east, down], m/s, earth frame
    attitude            [roll, pitch, yaw], rad   -- or --
    quaternion          [q1, q2, q3, q4] (q1 the scalar part)
    battery             optional {"voltage": V, "current": A}

lotsen's extensions (ignored by ArduPilot, optional for a physics):

    "lotsen": {"actuators": [alpha1, alpha2, n1, n2, nt]}   achieved actuator values now (rad,
              "actuators_mean": [...]}                       rev/s), and their mean over the step
    {"lotsen": {"place": [N, E, psi, u, v, r]}}              a JSON line lotsen sends before its
                                                             first frame: put the boat there at
                                                             rest and answer with its state

Anything that is not one of these is a `ProtocolError` (the caller counts and drops it).
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass
from typing import Any, Sequence

from lotsen.errors import LotsenError

SERVO_MAGIC_16 = 18458
SERVO_MAGIC_32 = 29569
SERVO_16 = struct.Struct("<HHI16H")  # 40 bytes
SERVO_32 = struct.Struct("<HHI32H")  # 72 bytes
#: a reply longer than this is not a state line (ArduPilot's own buffer is a few kB)
MAX_REPLY_BYTES = 16384


class ProtocolError(LotsenError):
    """Bytes that are not a valid servo packet or state line; the message says what is wrong."""


@dataclass(frozen=True)
class ServoPacket:
    frame_rate_hz: int
    frame_count: int
    pwm_us: tuple[int, ...]  # 16 or 32 values


def encode_servo(packet: ServoPacket) -> bytes:
    n = len(packet.pwm_us)
    if n == 16:
        return SERVO_16.pack(SERVO_MAGIC_16, packet.frame_rate_hz, packet.frame_count, *packet.pwm_us)
    if n == 32:
        return SERVO_32.pack(SERVO_MAGIC_32, packet.frame_rate_hz, packet.frame_count, *packet.pwm_us)
    raise ProtocolError(f"a servo packet has 16 or 32 channels, not {n}")


def decode_servo(data: bytes) -> ServoPacket:
    if len(data) == SERVO_16.size:
        fields, magic = SERVO_16.unpack(data), SERVO_MAGIC_16
    elif len(data) == SERVO_32.size:
        fields, magic = SERVO_32.unpack(data), SERVO_MAGIC_32
    else:
        raise ProtocolError(f"servo packet of {len(data)} bytes (expected {SERVO_16.size} or {SERVO_32.size})")
    if fields[0] != magic:
        raise ProtocolError(f"servo packet magic {fields[0]} (expected {magic} for {len(fields) - 3} channels)")
    return ServoPacket(frame_rate_hz=fields[1], frame_count=fields[2], pwm_us=tuple(fields[3:]))


@dataclass(frozen=True)
class PhysicsState:
    """One state line of the physics."""

    timestamp_s: float
    gyro_radps: tuple[float, float, float]
    accel_body_mps2: tuple[float, float, float]
    position_ned_m: tuple[float, float, float]
    velocity_ned_mps: tuple[float, float, float]
    attitude_rad: tuple[float, float, float]  # roll, pitch, yaw (from the quaternion if that was sent)
    actuators: tuple[float, ...] | None = None  # lotsen extension: achieved (alpha1, alpha2, n1, n2, nt)
    actuators_mean: tuple[float, ...] | None = None  # lotsen extension: their mean over the last step
    battery: tuple[float, float] | None = None  # (voltage V, current A)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "timestamp": self.timestamp_s,
            "imu": {"gyro": list(self.gyro_radps), "accel_body": list(self.accel_body_mps2)},
            "position": list(self.position_ned_m), "velocity": list(self.velocity_ned_mps),
            "attitude": list(self.attitude_rad)}
        ext: dict[str, Any] = {}
        if self.actuators is not None:
            ext["actuators"] = list(self.actuators)
        if self.actuators_mean is not None:
            ext["actuators_mean"] = list(self.actuators_mean)
        if ext:
            out["lotsen"] = ext
        if self.battery is not None:
            out["battery"] = {"voltage": self.battery[0], "current": self.battery[1]}
        return out


def encode_state(state: PhysicsState) -> bytes:
    """The reply datagram: the JSON line between newlines, as ArduPilot's examples send it."""
    return ("\n" + json.dumps(state.to_json(), separators=(",", ":")) + "\n").encode()


def _vector(obj: Any, key: str, n: int, where: str) -> tuple[float, ...]:
    if not isinstance(obj, dict) or key not in obj:
        raise ProtocolError(f"{where}{key}: missing")
    v = obj[key]
    if not isinstance(v, list) or len(v) != n:
        raise ProtocolError(f"{where}{key}: expected a list of {n} numbers, got {str(v)[:60]}")
    out = []
    for i, a in enumerate(v):
        if isinstance(a, bool) or not isinstance(a, (int, float)) or not math.isfinite(a):
            raise ProtocolError(f"{where}{key}[{i}]: {a!r} is not a finite number")
        out.append(float(a))
    return tuple(out)


def quaternion_to_euler(q: Sequence[float]) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of the unit quaternion q = (q1, q2, q3, q4), q1 the scalar part (ZYX)."""
    w, x, y, z = q
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not norm > 1e-9:
        raise ProtocolError(f"quaternion {list(q)} has no length")
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def _last_json_line(data: bytes) -> dict[str, Any]:
    if len(data) > MAX_REPLY_BYTES:
        raise ProtocolError(f"reply of {len(data)} bytes (at most {MAX_REPLY_BYTES})")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ProtocolError("reply is not UTF-8 text") from None
    lines = [line.strip() for line in text.split("\n") if line.strip()]
    if not lines:
        raise ProtocolError("empty reply")
    try:
        obj = json.loads(lines[-1])
    except ValueError as exc:
        raise ProtocolError(f"reply is not JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise ProtocolError("reply is not a JSON object")
    return obj


def decode_state(data: bytes) -> PhysicsState:
    """The last complete JSON line of a reply datagram as a state, or ProtocolError."""
    obj = _last_json_line(data)
    t = obj.get("timestamp")
    if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
        raise ProtocolError(f"timestamp: {t!r} is not a finite number")
    imu = obj.get("imu")
    if not isinstance(imu, dict):
        raise ProtocolError("imu: missing")
    gyro = _vector(imu, "gyro", 3, "imu.")
    accel = _vector(imu, "accel_body", 3, "imu.")
    pos = _vector(obj, "position", 3, "")
    vel = _vector(obj, "velocity", 3, "")
    if "quaternion" in obj:  # ArduPilot: the quaternion wins when both are sent
        att = quaternion_to_euler(_vector(obj, "quaternion", 4, ""))
    elif "attitude" in obj:
        att = _vector(obj, "attitude", 3, "")
    else:
        raise ProtocolError("attitude or quaternion: missing")
    ext = obj.get("lotsen")
    acts = acts_mean = None
    if ext is not None:
        if not isinstance(ext, dict):
            raise ProtocolError("lotsen: expected an object")
        if "actuators" in ext:
            acts = _vector(ext, "actuators", 5, "lotsen.")
        if "actuators_mean" in ext:
            acts_mean = _vector(ext, "actuators_mean", 5, "lotsen.")
    battery = None
    if "battery" in obj:
        b = obj["battery"]
        battery = (_scalar(b, "voltage", "battery."), _scalar(b, "current", "battery."))
    return PhysicsState(float(t), gyro, accel, pos, vel, att, acts, acts_mean, battery)  # type: ignore[arg-type]


def _scalar(obj: Any, key: str, where: str) -> float:
    if not isinstance(obj, dict):
        raise ProtocolError(f"{where[:-1]}: expected an object")
    v = obj.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ProtocolError(f"{where}{key}: {v!r} is not a finite number")
    return float(v)


def encode_place(x: Sequence[float]) -> bytes:
    """lotsen's request to put the boat at x = [N, E, psi, u, v, r] before the first frame."""
    return ("\n" + json.dumps({"lotsen": {"place": [float(v) for v in x]}}) + "\n").encode()


def decode_place(data: bytes) -> tuple[float, ...] | None:
    """The pose of a place request, or None if `data` is not one (a servo packet, anything else)."""
    if not data.lstrip()[:1] == b"{":
        return None
    try:
        obj = _last_json_line(data)
        return _vector(obj.get("lotsen"), "place", 6, "lotsen.")
    except ProtocolError:
        return None
