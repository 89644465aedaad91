"""What every driver node shares: a `poll(now)` that reads the device and returns the messages to
publish, run either by an executor timer (simulated time, emulated devices: deterministic) or by
a reader thread that hands the messages to the executor thread (`call_soon_threadsafe`), so a
blocking serial or I2C read never stalls the control loop. Plus health counters and rate
measurement for `lotsen check`.

`poll` never raises: device errors (OSError from I2C, SerialException, decode errors) are counted,
reported as `LogEvent`s (rate-limited), and the node goes on; a missing device is reopened
every `reopen_s`.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from lotsen.messages import LogEvent, Topic
from lotsen.runtime.executor import Node, NodeContext

Out = list[tuple[str, Any]]


@dataclass
class DeviceHealth:
    """One row of `lotsen check`."""

    name: str
    device: str
    opened: bool = False
    messages: int = 0
    errors: int = 0  # read/decode errors
    dropped: int = 0  # garbage bytes, bad checksums, overflowed samples
    rate_hz: float = 0.0
    expected_hz: float = 0.0
    detail: str = ""
    counters: dict[str, int] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.opened and self.rate_hz >= 0.8 * self.expected_hz and self.messages > 0


class RateMeter:
    """Messages per second over the last `window_s` of stamps."""

    def __init__(self, window_s: float = 2.0) -> None:
        self.window_s = window_s
        self._stamps: deque[float] = deque()
        self.count = 0

    def tick(self, now: float) -> None:
        self.count += 1
        self._stamps.append(now)
        while self._stamps and now - self._stamps[0] > self.window_s:
            self._stamps.popleft()

    def rate(self, since_s: float = -math.inf) -> float:
        """1 / median interval: a burst (a late reader catching up) does not fake a high rate.
        `since_s`: only the intervals that end at or after it (`lotsen check` leaves out the
        devices' opening, when what queued during the GNSS configuration or a late start arrives
        in bursts: in a 2-s check those were most of the intervals, and the GNSS read 24 Hz for 8)."""
        s = list(self._stamps)
        gaps = sorted(b - a for a, b in zip(s, s[1:]) if b >= since_s)
        if not gaps or sum(gaps) <= 0.0:
            return 0.0
        mid = gaps[len(gaps) // 2]
        return 1.0 / mid if mid > 0 else len(gaps) / sum(gaps)


class DriverNode(Node):
    """Base of the device nodes. Subclasses implement `open(now)`, `poll(now) -> Out`, `close()`."""

    name = "driver"
    device = ""
    period_s = 0.01
    blocking_poll = False  # True: poll() blocks on I/O itself (serial read with timeout)
    reopen_s = 2.0

    def __init__(self, threaded: bool = False) -> None:
        self.threaded = threaded
        self.health = DeviceHealth(self.name, self.device, expected_hz=1.0 / self.period_s)
        self.rate = RateMeter()
        self._next_open_s = 0.0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_error = ""
        self._dropped_seen: dict[str, int] = {}  # count_dropped: each decoder counter as last reported

    # -- to implement -----------------------------------------------------------------------
    def open(self, now: float) -> None:
        """Open the device; raise OSError (or any Exception) when it is missing."""

    def poll(self, now: float) -> Out:
        return []

    def close(self) -> None:
        pass

    # -- shared machinery -------------------------------------------------------------------
    def _try_open(self, now: float, out: Out) -> bool:
        if self.health.opened:
            return True
        if now < self._next_open_s:
            return False
        self._next_open_s = now + self.reopen_s
        try:
            self.open(now)
        except Exception as exc:  # noqa: BLE001 - a missing device is reported, never fatal
            self.health.detail = f"cannot open {self.device}: {exc}"
            if self.health.counters.get("open_failures", 0) == 0:
                self.log(out, now, "error", self.health.detail)
            self.count("open_failures")
            return False
        self.health.opened = True
        self.health.detail = ""
        self.log(out, now, "info", f"{self.device} opened")
        return True

    def read_serial(self, out: Out, now: float) -> bytes | None:
        """What the serial `self.port` holds now (thread mode: block for the first byte up to the
        port's timeout, then take the rest). None when the read failed: reported, the port marked
        closed and reopened after `reopen_s` (an unplugged adapter, EIO)."""
        try:
            waiting = self.port.in_waiting
            data = self.port.read(waiting if waiting else (1 if self.threaded else 0))
            if self.threaded and data:
                more = self.port.in_waiting
                if more:
                    data += self.port.read(more)
        except Exception as exc:  # noqa: BLE001 - a lost device is reported, never fatal
            self.error(out, now, "read_errors", f"{self.device}: read failed: {exc}")
            self.health.opened = False
            self._next_open_s = now + self.reopen_s
            return None
        return bytes(data)

    def count_dropped(self, out: Out, now: float, counters: Any, keys: tuple[str, ...]) -> None:
        """Report what a decoder's cumulative `counters` (attributes `keys`) counted since the last
        call: each new drop in `health.dropped` and as an error of that kind."""
        seen = self._dropped_seen
        for key in keys:
            new = getattr(counters, key) - seen.get(key, 0)
            if new:
                seen[key] = seen.get(key, 0) + new
                self.health.dropped += new
                self.error(out, now, key, f"{self.device}: {new} {key.replace('_', ' ')}")

    def count(self, key: str, n: int = 1) -> None:
        self.health.counters[key] = self.health.counters.get(key, 0) + n

    def error(self, out: Out, now: float, kind: str, text: str) -> None:
        """Count an error; report the 1st, 10th, 100th, 1000th and then every 1000th as a LogEvent
        (a stream of garbage must not flood the log)."""
        self.health.errors += 1
        self.count(kind)
        k = self.health.counters[kind]
        self._last_error = text
        if k in (1, 10, 100) or k % 1000 == 0:
            self.log(out, now, "warning", f"{text} ({kind} #{k})", kind=kind, count=k)

    def log(self, out: Out, now: float, level: str, text: str, **data: Any) -> None:
        out.append((Topic.LOG, LogEvent(stamp_s=now, level=level, source=self.name, text=text, data=data)))

    def produced(self, now: float) -> None:
        self.health.messages += 1
        self.rate.tick(now)

    def refresh_health(self, since_s: float = -math.inf) -> DeviceHealth:
        self.health.rate_hz = self.rate.rate(since_s)
        return self.health

    def step(self, now: float) -> Out:
        out: Out = []
        if not self._try_open(now, out):
            return out
        try:
            out.extend(self.poll(now))
        except Exception as exc:  # noqa: BLE001 - last resort: a driver bug must not stop the boat
            self.error(out, now, "poll_exceptions", f"{self.device}: {exc!r}")
        return out

    # -- Node -------------------------------------------------------------------------------
    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self.on_start(ctx)
        if self.threaded:
            self._thread = threading.Thread(target=self._run_thread, name=f"lotsen-{self.name}", daemon=True)
            self._thread.start()
        else:
            ctx.add_timer(self.period_s, lambda: self._publish(self.step(ctx.now())))

    def on_start(self, ctx: NodeContext) -> None:
        """Subscriptions and extra timers (runs on the executor thread)."""

    def _publish(self, out: Out) -> None:
        for topic, msg in out:
            self.ctx.publish(topic, msg)

    def _run_thread(self) -> None:
        clock = self.ctx.clock
        call = self.ctx.executor.call_soon_threadsafe  # type: ignore[attr-defined]
        next_t = time.monotonic()
        while not self._stop.is_set():
            out = self.step(clock.now())
            if out:
                call(lambda out=out: self._publish(out))
            if not self.health.opened:
                self._stop.wait(0.2)
                continue
            if not self.blocking_poll:
                next_t += self.period_s
                delay = next_t - time.monotonic()
                if delay < -self.period_s:  # fell behind: do not burst
                    next_t = time.monotonic()
                    delay = 0.0
                if delay > 0:
                    self._stop.wait(delay)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        try:
            self.close()
        except Exception:  # noqa: BLE001 - shutting down
            pass

