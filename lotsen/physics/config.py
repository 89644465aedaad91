"""`extra.physics`: where the external physics is and how lotsen's five actuators map onto its
servo channels (docs/physics.md).

    extra:
      physics:
        address: udp:127.0.0.1:9002      # the physics server (lotsen sends, it answers)
        servos:                          # the channel map
          channels: {alpha1: 1, alpha2: 2, n1: 3, n2: 4, nt: 5}   # SERVOn, 1-based
          pwm_min_us: 1000               # PWM at full negative deflection / astern
          pwm_neutral_us: 1500           # azimuth straight ahead, propeller stopped
          pwm_max_us: 2000               # full positive deflection / ahead
          alpha_full_deg: 45             # azimuth angle at pwm_max_us (minus at pwm_min_us)
          n_full_rps: 100                # propeller speed at pwm_max_us (azimuths)
          nt_full_rps: 80                # bow thruster speed at pwm_max_us
          reversed: []                   # actuators whose PWM runs the other way, e.g. [alpha2]
        timeout_s: 1.0                   # on simulated time: one frame's wait for its reply
        realtime_timeout_s: 0.02         # at wall-clock pace (lotsen run): the wait holds up the loop
        lost_after_s: 2.0                # no reply this long (wall clock): the physics is lost
        connect_timeout_s: 10            # the first state must come within this at the start
        gnss_antenna_m: [0.0, 0.0]       # the antenna on the physics's hull (body x, y)
        gnss_antenna_height_m: 0.0       # its height above the roll and pitch centre

The command line's `--physics udp:HOST:PORT` sets `address`. Angles follow lotsen's sign
convention (alpha > 0 turns a unit's thrust to starboard), speeds are signed rev/s (negative:
astern), mapped linearly on each side of the neutral PWM.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Sequence

from lotsen.errors import ConfigError
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.settings import value_range as _r

ACTUATORS = ("alpha1", "alpha2", "n1", "n2", "nt")


@dataclass(frozen=True)
class ChannelMap:
    """Which servo channel carries which actuator, and what a PWM value means."""

    channels: dict[str, int] = field(default_factory=lambda: {"alpha1": 1, "alpha2": 2, "n1": 3, "n2": 4, "nt": 5})
    pwm_min_us: int = field(default=1000, metadata=_r(500, 2500))
    pwm_neutral_us: int = field(default=1500, metadata=_r(500, 2500))
    pwm_max_us: int = field(default=2000, metadata=_r(500, 2500))
    alpha_full_deg: float = field(default=45.0, metadata=_r(1.0, 180.0))
    n_full_rps: float = field(default=100.0, metadata=_r(1.0, 1000.0))
    nt_full_rps: float = field(default=80.0, metadata=_r(1.0, 1000.0))
    reversed: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        where = "extra.physics.servos"
        unknown = sorted(set(self.channels) - set(ACTUATORS))
        missing = [a for a in ACTUATORS if a not in self.channels]
        if unknown or missing:
            raise ConfigError(f"{where}.channels: " + "; ".join(
                ([f"unknown actuator(s) {unknown}"] if unknown else []) + ([f"missing {missing}"] if missing else []))
                + f" (the actuators are {', '.join(ACTUATORS)})")
        for name in ACTUATORS:
            c = self.channels[name]
            if isinstance(c, bool) or not isinstance(c, int) or not 1 <= c <= 32:
                raise ConfigError(f"{where}.channels.{name}: {c!r} is not a servo channel (1-32)")
        used = list(self.channels.values())
        dup = sorted({c for c in used if used.count(c) > 1})
        if dup:
            raise ConfigError(f"{where}.channels: channel(s) {dup} carry more than one actuator")
        if not self.pwm_min_us < self.pwm_neutral_us < self.pwm_max_us:
            raise ConfigError(f"{where}: pwm_min_us < pwm_neutral_us < pwm_max_us must hold "
                              f"(got {self.pwm_min_us}, {self.pwm_neutral_us}, {self.pwm_max_us})")
        bad = [r for r in self.reversed if r not in ACTUATORS]
        if bad:
            raise ConfigError(f"{where}.reversed: {bad} not among the actuators {', '.join(ACTUATORS)}")

    @property
    def channel_count(self) -> int:
        """16, or 32 when a channel above 16 is used (ArduPilot's SERVO_32_ENABLE)."""
        return 32 if max(self.channels.values()) > 16 else 16

    def full_scale(self) -> tuple[float, ...]:
        a = math.radians(self.alpha_full_deg)
        return (a, a, self.n_full_rps, self.n_full_rps, self.nt_full_rps)

    def to_pwm(self, u: Sequence[float]) -> tuple[int, ...]:
        """The servo outputs (16 or 32, 0 on unused channels) for u = (alpha1, alpha2, n1, n2, nt)."""
        pwm = [0] * self.channel_count
        lo, mid, hi = self.pwm_min_us, self.pwm_neutral_us, self.pwm_max_us
        for name, value, full in zip(ACTUATORS, u, self.full_scale()):
            f = max(-1.0, min(1.0, value / full)) if math.isfinite(value) else 0.0
            if name in self.reversed:
                f = -f
            pwm[self.channels[name] - 1] = int(round(mid + f * ((hi - mid) if f >= 0 else (mid - lo))))
        return tuple(pwm)

    def from_pwm(self, pwm: Sequence[int]) -> tuple[float, ...]:
        """The actuator set-points a servo packet carries (a physics server's side): a channel at 0
        (not driven) or missing is neutral, values beyond the range are clipped."""
        lo, mid, hi = self.pwm_min_us, self.pwm_neutral_us, self.pwm_max_us
        out = []
        for name, full in zip(ACTUATORS, self.full_scale()):
            i = self.channels[name] - 1
            p = pwm[i] if i < len(pwm) else 0
            if p <= 0:
                out.append(0.0)
                continue
            p = min(max(p, lo), hi)
            f = (p - mid) / (hi - mid) if p >= mid else (p - mid) / (mid - lo)
            out.append((-f if name in self.reversed else f) * full)
        return tuple(out)

    def limits(self, base: ActuatorLimits = DEFAULT_LIMITS) -> ActuatorLimits:
        """`base` with the angle and speed limits the channels can carry."""
        return replace(base, alpha_max_rad=math.radians(self.alpha_full_deg), n_az_max_rps=self.n_full_rps,
                       n_bow_max_rps=self.nt_full_rps)


@dataclass(frozen=True)
class PhysicsConfig:
    """`extra.physics` (module docstring). `address` None: lotsen's own simulated boat."""

    address: str | None = None
    servos: ChannelMap = field(default_factory=ChannelMap)
    timeout_s: float = field(default=1.0, metadata=_r(0.001, 60.0))
    realtime_timeout_s: float = field(default=0.02, metadata=_r(0.001, 0.25))
    lost_after_s: float = field(default=2.0, metadata=_r(0.01, 60.0))
    connect_timeout_s: float = field(default=10.0, metadata=_r(0.1, 600.0))
    gnss_antenna_m: tuple[float, float] = (0.0, 0.0)
    gnss_antenna_height_m: float = field(default=0.0, metadata=_r(0.0, 3.0))  # above the roll/pitch centre

    def __post_init__(self) -> None:
        if self.address is not None:
            parse_address(self.address, "extra.physics.address")
        if self.lost_after_s < max(self.timeout_s, self.realtime_timeout_s):
            raise ConfigError(f"extra.physics.lost_after_s: {self.lost_after_s:g} s is shorter than a frame's wait "
                              f"(timeout_s {self.timeout_s:g} s)")
        if max(abs(v) for v in self.gnss_antenna_m) > 2.0:
            raise ConfigError(f"extra.physics.gnss_antenna_m: {list(self.gnss_antenna_m)} is more than 2 m from "
                              "the hull's origin")

    @property
    def host_port(self) -> tuple[str, int]:
        if self.address is None:
            raise ConfigError("extra.physics.address: not set (udp:HOST:PORT)")
        return parse_address(self.address, "extra.physics.address")


def address_flag(text: str) -> str:
    """argparse `type=` of `--physics udp:HOST:PORT`: a malformed or empty address is refused at
    once, as a number flag's out-of-range value is (`lotsen.settings.Number`)."""
    import argparse

    try:
        parse_address(text, "")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc).strip()) from None
    return text


def parse_address(text: str, what: str = "--physics") -> tuple[str, int]:
    """'udp:HOST:PORT' -> (host, port); a ConfigError naming `what` otherwise."""
    scheme, _, rest = text.partition(":")
    host, _, port = rest.rpartition(":")
    if scheme != "udp" or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"{what} {text!r}: expected udp:HOST:PORT, e.g. udp:127.0.0.1:9002")
    return host.strip("[]"), int(port)
