"""The RC transmitter through the FrSky X8R's SBUS output: frames -> `RcOverride` on rc/override.

`RcInterpreter` is the protocol-free part (frames and the time in, `RcOverride` out): the channel
map (`RcSection`), the link state and the thrust the sticks ask for. `RcReceiverNode` reads the
UART (`sbus_opener` on the boat, `EmulatedX8R.port` in tests and `--emulated` runs), decodes
with `SbusDecoder` and publishes.

Link: "ok" while frames without the frame-lost and failsafe flags arrive; "lost" when none has
for `lost_after_s` (no bytes at all, or every frame flagged lost: a single lost frame, common at
range, does not count); "failsafe" when the latest frame carries the receiver's failsafe flag.
Switch and stick values are taken only from good frames: in failsafe the X8R outputs its
preset failsafe positions, which must not flip the takeover or e-stop switch.

Sticks -> thrust (docs/drivers.md): throttle t, steering s, bow b in [-1, 1];
n1 = n2 = t * n_az_max_rps, alpha1 = alpha2 = -s * alpha_max (the azimuths sit aft: thrust
turned to port turns the bow to starboard), nt = b * n_bow_max_rps (nt > 0 pushes the bow to
starboard). After the takeover switch goes on, the propellers stay neutral until the throttle
and bow sticks have been at neutral once, so a stick left off centre does not jump the boat.
"""

from __future__ import annotations

import math
from typing import Any, Callable

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import RcSection, RcStick, RcSwitch
from lotsen.drivers.sbus import SBUS_BAUDRATE, SbusDecoder, SbusFrame
from lotsen.messages import RcOverride, ThrustCommand, Topic

PortOpener = Callable[[], Any]


def sbus_opener(url: str, timeout_s: float = 0.05) -> PortOpener:
    """Opens the receiver's UART: 100 000 baud, 8E2 (the inversion is done in hardware)."""

    def open_port() -> Any:
        import serial

        try:
            return serial.serial_for_url(url, baudrate=SBUS_BAUDRATE, bytesize=serial.EIGHTBITS,
                                         parity=serial.PARITY_EVEN, stopbits=serial.STOPBITS_TWO, timeout=timeout_s)
        except serial.SerialException as exc:
            raise OSError(str(exc)) from None

    return open_port


def stick_value(stick: RcStick, raw: int) -> float:
    """Raw SBUS value -> [-1, 1], linear on each side of the centre, 0 inside the deadband."""
    if raw >= stick.center_raw:
        x = (raw - stick.center_raw) / (stick.max_raw - stick.center_raw)
    else:
        x = (raw - stick.center_raw) / (stick.center_raw - stick.min_raw)
    x = min(max(x, -1.0), 1.0)
    if abs(x) <= stick.deadband:
        return 0.0
    x = math.copysign((abs(x) - stick.deadband) / (1.0 - stick.deadband), x)  # no step at the deadband edge
    return -x if stick.reverse else x


def stick_raw(stick: RcStick, value: float) -> int:
    """The raw value a transmitter sends for stick position `value` in [-1, 1] (for the twin)."""
    v = min(max(-value if stick.reverse else value, -1.0), 1.0)
    if abs(v) > 0.0:
        v = math.copysign(stick.deadband + abs(v) * (1.0 - stick.deadband), v)
    span = (stick.max_raw - stick.center_raw) if v >= 0 else (stick.center_raw - stick.min_raw)
    return int(round(stick.center_raw + v * span))


def switch_on(switch: RcSwitch, raw: int) -> bool:
    return (raw < switch.on_above_raw) if switch.reverse else (raw > switch.on_above_raw)


def switch_raw(switch: RcSwitch, on: bool, low: int = 172, high: int = 1811) -> int:
    """The raw value of a two-position switch (for the twin)."""
    return (low if on else high) if switch.reverse else (high if on else low)


class RcInterpreter:
    """Channel map and link state; pure (the time comes in with each call)."""

    def __init__(self, cfg: RcSection) -> None:
        self.cfg = cfg
        self.last_frame: SbusFrame | None = None
        self.last_good: SbusFrame | None = None
        self.last_good_s = -math.inf
        self.takeover = False
        self.estop = False
        self.sticks = (0.0, 0.0, 0.0)  # throttle, steering, bow
        self.thrust_enabled = False  # the throttle and bow sticks were at neutral since the takeover

    def frame(self, f: SbusFrame, now: float) -> None:
        self.last_frame = f
        if f.failsafe or f.frame_lost:
            return
        c = self.cfg
        self.last_good, self.last_good_s = f, now
        takeover = switch_on(c.takeover, f.raw(c.takeover.channel))
        if not takeover:
            self.thrust_enabled = False
        self.takeover = takeover
        self.estop = switch_on(c.estop, f.raw(c.estop.channel))
        self.sticks = (stick_value(c.throttle, f.raw(c.throttle.channel)),
                       stick_value(c.steering, f.raw(c.steering.channel)),
                       stick_value(c.bow, f.raw(c.bow.channel)))
        if takeover and self.sticks[0] == 0.0 and self.sticks[2] == 0.0:
            self.thrust_enabled = True

    def link(self, now: float) -> str:
        if now - self.last_good_s > self.cfg.lost_after_s:
            f = self.last_frame
            return "failsafe" if f is not None and f.failsafe else "lost"
        if self.last_frame is not None and self.last_frame.failsafe:
            return "failsafe"
        return "ok"

    def command(self, now: float) -> ThrustCommand | None:
        if not self.takeover:
            return None
        c = self.cfg
        t, s, b = self.sticks if self.thrust_enabled else (0.0, self.sticks[1], 0.0)
        alpha = -s * math.radians(c.alpha_max_deg)
        n = t * c.n_az_max_rps
        return ThrustCommand(stamp_s=now, alpha1_rad=alpha, alpha2_rad=alpha, n1_rps=n, n2_rps=n,
                             nt_rps=b * c.n_bow_max_rps, source="rc" if self.thrust_enabled else "rc:centre sticks")

    def override(self, now: float) -> RcOverride:
        link = self.link(now)
        if link != "ok":
            return RcOverride(stamp_s=now, active=self.takeover, link=link)
        return RcOverride(stamp_s=now, active=self.takeover, estop=self.estop, link=link, command=self.command(now))


class RcReceiverNode(DriverNode):
    """Publishes `RcOverride` on rc/override at `publish_hz`, and at once when the takeover or
    e-stop switch or the link state changes."""

    name = "rc"
    blocking_poll = True  # thread mode: port.read() blocks up to the port timeout
    period_s = 0.01  # timer mode: the X8R sends a frame every 7-14 ms

    def __init__(self, cfg: RcSection, open_port: PortOpener, threaded: bool = False) -> None:
        super().__init__(threaded)
        self.cfg = cfg
        self.device = f"X8R SBUS {cfg.port}"
        self.health.device = self.device
        self.health.expected_hz = cfg.min_frame_hz
        self._open_port = open_port
        self.port: Any = None
        self.decoder = SbusDecoder()
        self.rc = RcInterpreter(cfg)
        self._last_pub_s = -math.inf
        self._last_key: tuple | None = None
        self._opened_s = -math.inf

    def open(self, now: float) -> None:
        self.port = self._open_port()
        self.decoder.reset()
        self._opened_s = now

    def close(self) -> None:
        if self.port is not None:
            self.port.close()
            self.port = None

    def poll(self, now: float) -> Out:
        out: Out = []
        data = self.read_serial(out, now)
        if data is None:
            self._emit(out, now)  # the link is judged even without a port
            return out
        if data:
            for f in self.decoder.feed(data):
                self.produced(now)
                self.rc.frame(f, now)
            self.count_dropped(out, now, self.decoder.counters, ("bad_frames", "garbage_bytes"))
        self._emit(out, now)
        return out

    def _emit(self, out: Out, now: float) -> None:
        if self.rc.last_frame is None and now - self._opened_s <= self.cfg.lost_after_s:
            return  # just opened: the first frame is on its way, no "lost" yet
        msg = self.rc.override(now)
        key = (msg.active, msg.estop, msg.link, self.rc.thrust_enabled)
        if key != self._last_key:
            if self._last_key is not None and key[2] != self._last_key[2]:
                level = "info" if msg.link == "ok" else "warning"
                self.log(out, now, level, f"RC link {msg.link}", rc_link=msg.link)
        elif now - self._last_pub_s < 1.0 / self.cfg.publish_hz:
            return
        self._last_key = key
        self._last_pub_s = now
        out.append((Topic.RC, msg))

    def detail(self) -> str:
        """For `lotsen check`: link, switches and the raw channels of the map."""
        now = self._last_pub_s
        rc, c = self.rc, self.cfg
        f = rc.last_good
        chans = "" if f is None else ", " + " ".join(
            f"{name} ch{s.channel}={f.raw(s.channel)}" for name, s in
            (("thr", c.throttle), ("steer", c.steering), ("bow", c.bow), ("takeover", c.takeover), ("estop", c.estop)))
        return (f"link {rc.link(now) if math.isfinite(now) else 'never heard'}, takeover {'ON' if rc.takeover else 'off'}, "
                f"e-stop {'ON' if rc.estop else 'off'}{chans}")
