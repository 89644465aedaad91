"""Estimator integrity monitoring: is the estimate still worth trusting?

An `IntegrityMonitor` sits inside an estimator (`ModelAidedEKF`, `SeedFilters`). The estimator
tells it what happens to every sample; the monitor decides which faults exist and the estimator
turns them into an `EstimatorHealth` message. Pure: time comes only from message stamps and
from the `t` the caller passes to `faults(t)`.

Tests, each with its own persistence (numbers in docs/fusion.md, measured in bench_fusion.py):

- **Windowed innovation test** (per sensor: gyro, accel, mag, gnss, gnss_vel): every gated
  update reports its normalised innovation squared NIS = y' S^-1 y, accepted or not. Over a
  sliding window (time buckets of `bucket_s`) the monitor keeps the fraction of samples the gate
  rejected and the mean of min(NIS, gate) / dof (about 1 for a consistent filter; capping at the
  gate makes one outlier weigh like one rejection, not like a thousand). A sensor is declared
  *inconsistent* when the rejected fraction exceeds `reject_frac_limit` or the mean exceeds its
  `nis_limit`, with at least `min_tests` tests in the window; it is cleared after the window
  has been clean (enough tests, both figures low) for `clear_s`. The window is the persistence.
- **Stuck sensor** (gyro, accel, mag, GNSS, on the raw samples): real sensors are noisy. A
  block of `stuck_block` samples whose standard deviation on any axis the filter uses is below
  `stuck_std` (a tenth of the simulator's noise: 0.003 rad/s, 0.04 m/s^2, 0.3 uT; for GNSS the
  receiver's NED velocity, 2 cm/s noise, tested only while the boat moves) is a stuck block;
  `stuck_blocks_declare` in a row declare the sensor stuck (the estimator stops using it),
  `stuck_blocks_clear` noisy blocks in a row clear it.
- **Frozen heading**: over `frozen_window_s` the bias-corrected gyro integrates to more than
  `frozen_min_turn_rad`, but the heading estimate moved by less than `frozen_ratio` of that.
  Only while the gyro itself is healthy (a stuck gyro is its own fault).
- **Gyro drifting from the compass**: over each `drift_window_s` the bias-corrected gyro's heading
  change and the compass's (an undisturbed field only) differ by more than `drift_min_rad`, in two
  windows in a row with the same sign: a ramp, so an offset on the gyro (a compass disturbance inside
  the field-norm tolerance is a step, seen in one window). The gyro is then faulty: no heading. In a sea
  the wave states take up a gyro offset that the gate would reject in flat water.
- **Starvation and stalling**: no sample of any sensor used for more than `starvation_s` (one
  GNSS period, 0.125 s at 8 Hz), or the filter's time behind the caller's clock by as much; a
  sensor used before but not for `sensor_timeout_s` is reported as unused.

Re-opening a gate: a sensor the gate rejects many times in a row may mean the estimate is wrong
(wrong start, dead reckoning after an outage) or the sensor is (a GNSS jump, a magnetic
disturbance). `reopen_allowed` decides: with policy "always" (gyro, accel) the estimator may
re-open; with policy "reacquire" (gnss, gnss_vel, mag) only when the rejection streak began
without an accepted sample of that sensor in the `reacquire_gap_s` before it (start, or
re-acquisition after an outage: then the estimate is the suspect), after `reset(sensor)` (the
operator), or, if configured, after the sensor has been declared inconsistent for
`reanchor_after_s`. A sensor that jumps away from an estimate it was agreeing with is never
re-opened on its own: it is declared inconsistent, and accepted again only when it comes back
inside the gate and nearer its old agreement than the jump (the estimator's test
y . d < |d|^2 / 2, d its last rejected innovation: the gate widens as the covariance grows in
dead reckoning, and a persistent offset must not be accepted just because it fits inside).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from lotsen.model.angles import wrap_angle

SENSORS = ("gyro", "accel", "mag", "gnss", "gnss_vel")


@dataclass(frozen=True)
class IntegrityConfig:
    bucket_s: float = 0.25  # time resolution of the innovation windows
    window_s: dict = field(default_factory=lambda: {
        "gyro": 1.0, "accel": 2.0, "mag": 1.0, "gnss": 1.0, "gnss_vel": 1.0, "imu": 1.0})
    min_tests: dict = field(default_factory=lambda: {
        "gyro": 40, "accel": 16, "mag": 20, "gnss": 4, "gnss_vel": 4, "imu": 40})
    # windowed mean of min(NIS, gate) / dof; 1 for a consistent filter (limits: docs/fusion.md)
    nis_limit: dict = field(default_factory=lambda: {
        "gyro": 4.0, "accel": 4.0, "mag": 4.0, "gnss": 6.0, "gnss_vel": 6.0, "imu": 6.0})
    reject_frac_limit: float = 0.5
    clear_s: float = 2.0
    # stuck raw samples
    stuck_block: dict = field(default_factory=lambda: {"gyro": 25, "accel": 25, "mag": 13, "gnss": 3})
    # GNSS: the receiver's velocity (noise ~2 cm/s, resolution 1 mm/s) repeated while the boat moves
    stuck_std: dict = field(default_factory=lambda: {"gyro": 3e-4, "accel": 4e-3, "mag": 0.03, "gnss": 1e-4})
    stuck_axes: dict = field(default_factory=lambda: {"gyro": (2,), "accel": (0, 1), "mag": (0, 1), "gnss": (0, 1)})
    stuck_blocks_declare: int = 2
    stuck_blocks_clear: int = 4
    # frozen heading estimate
    frozen_bucket_s: float = 0.5
    frozen_window_s: float = 2.0
    frozen_min_turn_rad: float = math.radians(5.0)  # 2.5 deg/s: the figure eight at 0.5 m/s turns ~4 deg/s
    frozen_ratio: float = 0.25
    # the gyro against the compass (module docstring). Over 1 s the two differ by at most ~6 deg on the
    # figure eight at 1.0 m/s in Hs 10 cm (both hulls; 6.5 deg over 2 s); a 0.3 rad/s offset by 17
    drift_window_s: float = 1.0
    drift_min_rad: float = math.radians(10.0)
    # starvation
    starvation_s: float = 0.125  # one GNSS period at 8 Hz
    sensor_timeout_s: dict = field(default_factory=lambda: {
        "gyro": 0.25, "accel": 0.5, "mag": 0.5, "gnss": 1.5, "gnss_vel": 1.5, "imu": 0.25})
    # what the flags tolerate
    max_position_std_m: float = 1.0
    max_heading_std_rad: float = math.radians(10.0)
    max_velocity_std_mps: float = 0.25
    # re-opening of gates
    reacquire_gap_s: float = 1.0
    reacquire_rejects: int = 4  # a re-acquiring sensor re-opens the gate after this many rejections
    reopen_policy: dict = field(default_factory=lambda: {
        "gyro": "always", "accel": "always", "imu": "always", "mag": "reacquire", "gnss": "reacquire",
        "gnss_vel": "reacquire"})
    reanchor_after_s: float | None = None  # None: only the operator (reset) re-opens a declared sensor
    event_memory: int = 8


class _InnovationWindow:
    """Time-bucketed counts of one sensor's gated tests, and its declared state."""

    __slots__ = ("buckets", "n_buckets", "since", "clean_since", "detail", "last_accept", "streak_gap",
                 "streak_start", "reset_pending")

    def __init__(self, n_buckets: int) -> None:
        self.buckets: deque = deque()  # [bucket index, n, n_rejected, sum of capped NIS / dof]
        self.n_buckets = n_buckets
        self.since: float | None = None  # declared inconsistent at
        self.clean_since: float | None = None
        self.detail = ""
        self.last_accept = -math.inf
        self.streak_start: float | None = None
        self.streak_gap = math.inf  # time without acceptance when the current rejection streak began
        self.reset_pending = False

    def add(self, b: int, nis_norm: float, rejected: bool) -> None:
        bk = self.buckets
        if not bk or bk[-1][0] != b:
            bk.append([b, 0, 0, 0.0])
            while bk and bk[0][0] <= b - self.n_buckets:
                bk.popleft()
        last = bk[-1]
        last[1] += 1
        last[2] += rejected
        last[3] += nis_norm

    def stats(self, b: int) -> tuple[int, int, float]:
        n = rej = 0
        s = 0.0
        for bi, bn, br, bs in self.buckets:
            if bi > b - self.n_buckets:
                n += bn
                rej += br
                s += bs
        return n, rej, s


class _StuckDetector:
    __slots__ = ("buf", "stuck_blocks", "good_blocks", "since", "value", "first_t")

    def __init__(self) -> None:
        self.buf: list = []
        self.stuck_blocks = 0
        self.good_blocks = 0
        self.since: float | None = None
        self.value: tuple = ()
        self.first_t: float | None = None


class _Latch:
    """A fault that is declared at once and cleared after `clear_s` without it (frozen heading, drifting gyro)."""

    def __init__(self) -> None:
        self.since: float | None = None
        self.clean_since: float | None = None
        self.detail = ""

    def step(self, t: float, fault: bool, detail: str, clear_s: float) -> None:
        if fault:
            self.clean_since = None
            if self.since is None:
                self.since, self.detail = t, detail
        elif self.since is not None:
            if self.clean_since is None:
                self.clean_since = t
            elif t - self.clean_since >= clear_s:
                self.since = self.clean_since = None

    def reset(self) -> None:
        self.since = self.clean_since = None


class IntegrityMonitor:
    """Integrity tests of one estimator (see the module docstring)."""

    def __init__(self, config: IntegrityConfig = IntegrityConfig(), sensors: tuple[str, ...] = SENSORS) -> None:
        self.config = config
        self.sensors = tuple(sensors)
        c = config
        self._win = {s: _InnovationWindow(max(1, int(round(c.window_s.get(s, 1.0) / c.bucket_s))))
                     for s in self.sensors}
        self._stuck = {s: _StuckDetector() for s in ("gyro", "accel", "mag", "gnss") if s in c.stuck_block}
        self.last_used: dict[str, float] = {}
        self._frozen_buckets: deque = deque()  # [bucket index, gyro integral, heading change]
        self._frozen_prev: tuple[float, float] | None = None  # (t, psi)
        # the gyro against the compass: the gyro's integrated turn, the open window's start
        # (t, compass heading, gyro turn) and the last closed window's difference
        self._gyro_turn = 0.0
        self._drift_start: tuple[float, float, float] | None = None
        self._drift_last = 0.0
        self._drift = _Latch()
        self._frozen = _Latch()
        self.events: deque = deque(maxlen=c.event_memory)
        self.event_count = 0
        self._gates: dict[str, float] = {}

    # -- what the estimator reports ----------------------------------------------------------
    def test(self, sensor: str, t: float, nis: float, dof: int, gate: float, accepted: bool) -> None:
        """One gated innovation test (accepted or rejected by the gate)."""
        w = self._win.get(sensor)
        if w is None or not math.isfinite(t):
            return
        c = self.config
        nis_norm = (min(nis, gate) if math.isfinite(nis) else gate) / dof
        if accepted:
            w.last_accept = t
            w.streak_start = None
        elif w.streak_start is None:
            w.streak_start = t
            w.streak_gap = t - w.last_accept
        if not accepted and self.reacquiring(sensor):
            return  # the estimate is the suspect: the re-opened gate will settle it, no sensor fault
        w.add(int(math.floor(t / c.bucket_s)), nis_norm, not accepted)
        self._evaluate(sensor, w, t)

    def _evaluate(self, sensor: str, w: _InnovationWindow, t: float) -> None:
        c = self.config
        n, rej, s = w.stats(int(math.floor(t / c.bucket_s)))
        enough = n >= c.min_tests.get(sensor, 4)
        frac = rej / n if n else 0.0
        mean = s / n if n else 0.0
        limit = c.nis_limit.get(sensor, 4.0)
        bad = enough and (frac > c.reject_frac_limit or mean > limit)
        if w.since is None:
            if bad:
                w.since = t
                w.clean_since = None
                w.detail = f"{rej} of {n} samples rejected in {c.window_s.get(sensor, 1.0):g} s, mean NIS {mean:.3g}"
        else:
            clean = enough and frac <= 0.5 * c.reject_frac_limit and mean <= limit
            if not clean:
                w.clean_since = None
            elif w.clean_since is None:
                w.clean_since = t
            elif t - w.clean_since >= c.clear_s:
                w.since = None
                w.clean_since = None
                self.event(t, f"{sensor}: consistent again")

    def raw(self, sensor: str, t: float, values: tuple[float, ...], active: bool = True) -> None:
        """A raw sample (all axes) for the stuck test; `active=False` (e.g. GNSS velocity while
        the boat is still: a receiver may hold it) restarts the block instead."""
        d = self._stuck.get(sensor)
        if d is None:
            return
        c = self.config
        if not active:
            d.buf = []
            d.first_t = None
            return
        for ax in c.stuck_axes[sensor]:
            if not math.isfinite(values[ax]):
                return  # a NaN sample is unusable, not stuck (the estimator skips it)
        if d.first_t is None:
            d.first_t = t
        d.buf.append(values)
        if len(d.buf) < c.stuck_block[sensor]:
            return
        buf = d.buf
        n = len(buf)
        low = False
        for ax in c.stuck_axes[sensor]:
            m = sum(v[ax] for v in buf) / n
            var = sum((v[ax] - m) ** 2 for v in buf) / n
            if math.sqrt(var) < c.stuck_std[sensor]:
                low = True
                break
        block_t0 = d.first_t
        d.buf = []
        d.first_t = None
        if low:
            d.stuck_blocks += 1
            d.good_blocks = 0
            if d.since is None and d.stuck_blocks >= c.stuck_blocks_declare:
                d.since = t
                d.value = tuple(buf[-1][ax] for ax in c.stuck_axes[sensor])
                self.event(t, f"{sensor}: stuck (samples constant since {block_t0:.2f} s)")
        else:
            d.good_blocks += 1
            d.stuck_blocks = 0
            if d.since is not None and d.good_blocks >= c.stuck_blocks_clear:
                d.since = None
                self.event(t, f"{sensor}: noisy again, used again")

    def used(self, sensor: str, t: float) -> None:
        if math.isfinite(t):
            prev = self.last_used.get(sensor, -math.inf)
            if t > prev:
                self.last_used[sensor] = t

    def heading(self, t: float, psi: float, rate_radps: float) -> None:
        """The heading estimate after a gyro sample, and the bias-corrected gyro rate."""
        c = self.config
        if self.stuck("gyro") or self.inconsistent("gyro") or not (math.isfinite(psi) and math.isfinite(rate_radps)):
            self._frozen_buckets.clear()
            self._frozen_prev = None
            return
        prev = self._frozen_prev
        self._frozen_prev = (t, psi)
        if prev is None or t <= prev[0]:
            return
        if t - prev[0] > c.frozen_bucket_s:  # a gap in the gyro (stuck, lost): start again
            self._frozen_buckets.clear()
            return
        dt = t - prev[0]
        dpsi = wrap_angle(psi - prev[1])
        b = int(math.floor(t / c.frozen_bucket_s))
        fb = self._frozen_buckets
        K = max(1, int(round(c.frozen_window_s / c.frozen_bucket_s)))
        if fb and fb[-1][0] != b:
            self._evaluate_frozen(t, K)
        if not fb or fb[-1][0] != b:
            fb.append([b, 0.0, 0.0])
            while fb and fb[0][0] <= b - K:
                fb.popleft()
        fb[-1][1] += rate_radps * dt
        fb[-1][2] += dpsi
        self._gyro_turn += rate_radps * dt

    def compass(self, t: float, psi: float) -> None:
        """A compass heading from an undisturbed field (its norm within tolerance): the gyro-drift test."""
        c = self.config
        if not math.isfinite(psi) or self.stuck("gyro") or self.inconsistent("gyro"):
            self._drift_start = None
            return
        start = self._drift_start
        if start is None or t < start[0] or t - start[0] > 2.0 * c.drift_window_s:  # a gap: start again
            self._drift_start, self._drift_last = (t, psi, self._gyro_turn), 0.0
            return
        if t - start[0] < c.drift_window_s:
            return
        d = wrap_angle(psi - start[1]) - (self._gyro_turn - start[2])
        prev, self._drift_last = self._drift_last, d
        self._drift_start = (t, psi, self._gyro_turn)
        self._drift.step(t, abs(d) > c.drift_min_rad and abs(prev) > c.drift_min_rad and d * prev > 0.0,
                         f"the compass turned {math.degrees(prev):+.0f} and {math.degrees(d):+.0f} deg more than the "
                         f"gyro in two {c.drift_window_s:g}-s windows", c.clear_s)

    def _evaluate_frozen(self, t: float, K: int) -> None:
        c = self.config
        fb = self._frozen_buckets
        if len(fb) < K:
            return
        g = sum(x[1] for x in fb)
        h = sum(x[2] for x in fb)
        self._frozen.step(t, abs(g) >= c.frozen_min_turn_rad and abs(h) < c.frozen_ratio * abs(g),
                          f"moved {math.degrees(h):.1f} deg in {c.frozen_window_s:g} s while the gyro "
                          f"turned {math.degrees(g):.1f} deg", c.clear_s)

    def event(self, t: float, text: str) -> None:
        """An informational event (kept for EstimatorHealth.events)."""
        self.events.append(f"{text} at {t:.2f} s")
        self.event_count += 1

    # -- what the estimator asks ---------------------------------------------------------------
    def stuck(self, sensor: str) -> bool:
        d = self._stuck.get(sensor)
        return d is not None and d.since is not None

    def inconsistent(self, sensor: str) -> bool:
        w = self._win.get(sensor)
        return w is not None and w.since is not None

    def faulty(self, sensor: str) -> bool:
        return self.stuck(sensor) or self.inconsistent(sensor) or (sensor == "gyro" and self.drift_since is not None)

    @property
    def frozen_since(self) -> float | None:
        """When the heading estimate was declared frozen (None: it is not)."""
        return self._frozen.since

    @property
    def drift_since(self) -> float | None:
        """When the gyro was declared drifting from the compass (None: it is not)."""
        return self._drift.since

    def reacquiring(self, sensor: str) -> bool:
        """The sensor's current rejection streak began without an accepted sample in the
        `reacquire_gap_s` before it (start, after an outage), or after an operator reset, under
        policy "reacquire": the estimate, not the sensor, is the suspect."""
        w = self._win.get(sensor)
        if w is None or self.config.reopen_policy.get(sensor, "always") != "reacquire" or w.streak_start is None:
            return False
        return w.reset_pending or w.streak_gap > self.config.reacquire_gap_s

    def rejecting(self, sensor: str) -> bool:
        """The sensor is in a rejection streak that began while it agreed with the estimate."""
        w = self._win.get(sensor)
        return w is not None and w.streak_start is not None and not self.reacquiring(sensor)

    def streak_start(self, sensor: str) -> float | None:
        """When the sensor's current rejection streak began (None: its last test was accepted)."""
        w = self._win.get(sensor)
        return w.streak_start if w is not None else None

    def reopen_allowed(self, sensor: str, t: float) -> bool:
        """May the estimator re-open its gate for `sensor` after a streak of rejections?"""
        c = self.config
        if self.stuck(sensor):
            return False
        policy = c.reopen_policy.get(sensor, "always")
        if policy == "always":
            return True
        w = self._win.get(sensor)
        if w is None:
            return True
        if w.reset_pending:
            return True
        if w.streak_gap > c.reacquire_gap_s:
            return True  # re-acquisition (start, after an outage): the estimate is the suspect
        if c.reanchor_after_s is not None and w.since is not None and t - w.since >= c.reanchor_after_s:
            return True
        return False

    def reopened(self, sensor: str, t: float, text: str) -> None:
        w = self._win.get(sensor)
        if w is not None:
            w.reset_pending = False
        self.event(t, text)

    def reset(self, t: float, sensor: str | None = None) -> None:
        """Operator: forget the declared inconsistency of `sensor` (all if None) and let its gate
        re-open at the next rejection streak."""
        for s, w in self._win.items():
            if sensor is None or s == sensor:
                w.since = None
                w.clean_since = None
                w.buckets.clear()
                w.reset_pending = True
                w.streak_gap = math.inf
        self._frozen.reset()
        if sensor is None or sensor == "gyro":
            self._drift.reset()
            self._drift_start = None
        self.event(t, f"integrity reset ({sensor or 'all sensors'})")

    def window_figures(self, sensor: str, t: float) -> tuple[float, float]:
        """(mean capped NIS / dof, fraction of tests accepted) over the sensor's window; NaN without tests."""
        w = self._win.get(sensor)
        if w is None:
            return math.nan, math.nan
        n, rej, s = w.stats(int(math.floor(t / self.config.bucket_s)))
        return (s / n, 1.0 - rej / n) if n else (math.nan, math.nan)

    def faults(self, t: float, filter_t: float | None, state_finite: bool = True) -> list[tuple[str, str]]:
        """[(code, text)] of every fault present at time t."""
        c = self.config
        out: list[tuple[str, str]] = []
        if not state_finite:
            out.append(("fusion.non_finite", "fusion: non-finite state, re-initialisation needed"))
        last_any = max(self.last_used.values(), default=-math.inf)
        if t - last_any > c.starvation_s:
            since = last_any if math.isfinite(last_any) else t
            out.append(("fusion.starved", f"fusion: no sensor sample used for {t - last_any:.2f} s, since {since:.2f} s"
                        if math.isfinite(last_any) else "fusion: no sensor sample used yet"))
        if filter_t is not None and t - filter_t > c.starvation_s:
            out.append(("fusion.stalled", f"fusion: filter time {filter_t:.2f} s is {t - filter_t:.2f} s behind"))
        if self._drift.since is not None:
            out.append(("gyro.drifting", f"gyro: drifting from the compass ({self._drift.detail}), since "
                                         f"{self._drift.since:.2f} s"))
        if self._frozen.since is not None:
            out.append(("heading.frozen", f"heading: estimate frozen ({self._frozen.detail}), since "
                                          f"{self._frozen.since:.2f} s"))
        for s, d in self._stuck.items():
            if d.since is not None:
                val = ", ".join(f"{v:.4g}" for v in d.value)
                out.append((f"{s}.stuck", f"{s}: stuck at ({val}), not used, since {d.since:.2f} s"))
        for s in self.sensors:
            w = self._win[s]
            if w.since is not None:
                out.append((f"{s}.inconsistent", f"{s}: inconsistent with the estimate ({w.detail}), "
                                                 f"since {w.since:.2f} s"))
            lu = self.last_used.get(s)
            timeout = c.sensor_timeout_s.get(s)
            if lu is not None and timeout is not None and t - lu > timeout and w.since is None \
                    and not self.stuck(s):
                out.append((f"{s}.unused", f"{s}: no sample used for {t - lu:.2f} s, since {lu:.2f} s"))
        return out
