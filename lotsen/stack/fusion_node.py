"""The state estimate as nodes: the estimator (EKF or the seed's filters) on the sensor topics,
or the simulator's truth republished (`nodes.fusion: truth`).

The node is where the runtime's clock meets the (clock-free) estimator:
- a message stamped in the future of the clock (more than `max_future_s`) is refused, counted
  and reported, never fed: one bad stamp must not drag the filter ahead of every later sample;
- the prediction is driven by the achieved actuator values (actuators/state: servo angles,
  measured propeller speeds, ESCs armed); the set-points (ship_command) drive the estimator's
  model of the actuators between them and where nothing is measured (lotsen.fusion.inputs);
- the estimator's integrity (`health(t)`, docs/fusion.md) is published on fusion/health at
  `health_rate_hz`; every fault it declares or clears and every event it reports is logged;
- input starvation: when no sensor sample has been used by the estimator for longer than
  `starvation_s` (one GNSS period), it says so on the log and in the health it publishes, and the
  supervisor's estimator failsafe acts;
- a frozen output: an estimate that repeats itself exactly (all six states bit-identical) for
  `frozen_s` while samples arrive is a hung estimator, whatever the estimator says of itself;
- samples are taken in at once (the clock check) and fed to the estimator in their order of
  arrival at the next publication: the filter then runs a few predictions and updates back to back,
  with warm caches, instead of one per wake-up of the loop (on the boat's 100 Hz loop each call cost
  2-2.4 x more cold). What leaves the node is unchanged: every estimate and health it publishes is
  computed after every sample that arrived before it, in the same order as before;
- the sea state: the IMU's heave, roll and pitch (levelled by the estimator's tilt where it has one)
  feed a `SeaStateEstimator`, whose estimate goes out on fusion/sea_state every 2 s (the page shows it).
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from typing import Any, Callable

from lotsen.errors import LotsenError
from lotsen.fusion import MagCalibration, calibrated_heading
from lotsen.fusion.seastate import SeaStateConfig, SeaStateEstimator
from lotsen.messages import ImuSample, MagCalibrationResult, MagSample, Topic, VesselState
from lotsen.runtime.executor import Node, NodeContext


class TruthStateNode(Node):
    """fusion: truth — republishes the simulator's ground truth as the state estimate."""

    name = "state_truth"

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.TRUTH, self._on_truth)

    def _on_truth(self, msg: VesselState) -> None:
        est = VesselState(stamp_s=msg.stamp_s, north_m=msg.north_m, east_m=msg.east_m,
                          heading_rad=msg.heading_rad, u_mps=msg.u_mps, v_mps=msg.v_mps, r_radps=msg.r_radps,
                          source="truth")
        self.ctx.publish(Topic.STATE, est)
        self.ctx.publish(Topic.SENS_FUS, est)


class FusionNode(Node):
    """Runs an estimator on the sensor topics and publishes state/estimate and imu/sens_fus at
    `rate_hz`, imu/mag_calibrated per sample, and the estimator's health (when it has one)."""

    name = "fusion"
    SENSOR_TOPICS = (Topic.IMU_RAW, Topic.IMU_MAG, Topic.GNSS)

    def __init__(self, estimator: Any, calibration: Any, rate_hz: float = 20.0, max_future_s: float = 0.05,
                 starvation_s: float = 0.125, health_rate_hz: float = 5.0, frozen_s: float = 0.5,
                 sea_state: SeaStateConfig | None = SeaStateConfig()) -> None:
        self.estimator = estimator
        self.sea = SeaStateEstimator(sea_state) if sea_state is not None else None
        self.calibration = calibration
        self._before_review: Any = None  # the calibration in use before a fit under review
        self.period_s = 1.0 / rate_hz
        self.max_future_s = max_future_s
        self.starvation_s = starvation_s
        self.health_period_s = 1.0 / health_rate_hz
        self.counters = {"future": 0, "dropped": 0, "fed": 0}
        self._used_total = -1
        self._last_use_s: float | None = None
        self._starved = False
        self._last_future_log_s = -math.inf
        self._last_health_s = -math.inf
        self.frozen_s = frozen_s
        self._last_output: tuple[float, ...] | None = None
        self._output_since_s = 0.0
        self._frozen = False
        self._codes: set[str] = set()  # fault codes of the last published health
        self._event_count = 0
        self._pending: deque[tuple[Callable[[Any], None], Any]] = deque()

    #: samples held for the next publication at most (a stalled timer must not hold memory)
    MAX_PENDING = 512

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        est = self.estimator
        ctx.subscribe(Topic.IMU_RAW, self._checked(self._on_imu))
        ctx.subscribe(Topic.IMU_MAG, self._on_mag)
        ctx.subscribe(Topic.GNSS, self._checked(est.on_gnss))
        ctx.subscribe(Topic.ACTUATORS, self._checked(est.on_command))
        ctx.subscribe(Topic.SHIP_COMMAND, self._checked(est.on_command))
        self._on_mag_checked = self._checked(est.on_mag)
        ctx.subscribe(Topic.MAG_CALIBRATION, self._on_calibration)
        ctx.add_timer(self.period_s, self._publish)

    def _checked(self, fn: Any) -> Any:
        """Clock check on arrival, then held for the estimator (`_feed`)."""

        def call(msg: Any) -> None:
            now = self.ctx.now()
            stamp = msg.stamp_s
            if not (isinstance(stamp, (int, float)) and math.isfinite(stamp)) or stamp > now + self.max_future_s:
                self.counters["future"] += 1
                if now - self._last_future_log_s > 1.0:  # one event a second is enough
                    self._last_future_log_s = now
                    self.ctx.log("warning", f"fusion refused a {type(msg).__name__} stamped {stamp!r} at clock "
                                            f"{now:.3f} s (future or not finite): not fed to the estimator",
                                 refused_future=self.counters["future"])
                return
            self._pending.append((fn, msg))
            if len(self._pending) > self.MAX_PENDING:
                self._feed()
        return call

    def _feed(self) -> None:
        """The held samples to the estimator, in their order of arrival; a message that upsets the
        filter is counted and dropped, never fatal."""
        pending = self._pending
        while pending:
            fn, msg = pending.popleft()
            try:
                fn(msg)
                self.counters["fed"] += 1
            except (ValueError, ArithmeticError, LotsenError) as exc:
                self.counters["dropped"] += 1
                self.ctx.log("warning", f"fusion dropped a {type(msg).__name__}: {exc}")

    def _on_imu(self, msg: ImuSample) -> None:
        self.estimator.on_imu(msg)
        if self.sea is not None:
            tilt = getattr(self.estimator, "tilt", None)
            self.sea.on_imu(msg, tilt.level(msg.accel_mps2) if tilt is not None else None)

    def _on_mag(self, msg: MagSample) -> None:
        self._on_mag_checked(msg)
        if all(math.isfinite(v) for v in msg.field_uT[:2]):
            self.ctx.publish(Topic.IMU_MAG_CALIBRATED, calibrated_heading(msg, self.calibration))

    def _on_calibration(self, result: MagCalibrationResult) -> None:
        """A fresh fit is used at once; the operator's rejection brings back the one before it."""
        if not result.ok:
            return
        self._feed()  # the samples before the new calibration with the one they came with
        if result.decision == "accepted":
            self._before_review = None
            return
        if result.decision == "rejected":
            if self._before_review is None:
                return
            cal, self._before_review = self._before_review, None
        else:
            if self._before_review is None:
                self._before_review = self.calibration
            cal = MagCalibration(center=result.center, matrix=result.matrix,
                                 residual_rms=result.residual, coverage_deg=result.coverage_deg)
        self._set_calibration(cal)

    def _set_calibration(self, cal: MagCalibration) -> None:
        self.calibration = cal
        self.estimator.calibration = cal
        if hasattr(self.estimator, "set_calibration"):
            self.estimator.set_calibration(cal)

    # -- input starvation --------------------------------------------------------------------
    def samples_used(self) -> int:
        counters = getattr(self.estimator, "counters", None)
        used = getattr(counters, "used", None)
        if not isinstance(used, dict):
            return self.counters["fed"]
        return sum(v for k, v in used.items() if k != "command")

    def _check_starvation(self, t: float) -> None:
        used = self.samples_used()
        if used != self._used_total:
            self._used_total, self._last_use_s = used, t
        if self._last_use_s is None:
            self._last_use_s = t
        starved = t - self._last_use_s > self.starvation_s
        if starved and not self._starved:
            self.ctx.log("error", f"fusion: no sensor sample used for {t - self._last_use_s:.2f} s "
                                  f"(refused future stamps {self.counters['future']}, "
                                  f"dropped {self.counters['dropped']})")
        elif self._starved and not starved:
            self.ctx.log("info", "fusion: sensor samples used again")
        self._starved = starved

    def _check_frozen(self, t: float, est: VesselState) -> None:
        out = est.as_array_tuple()
        if out != self._last_output:
            self._last_output, self._output_since_s = out, t
        frozen = t - self._output_since_s >= self.frozen_s and not self._starved
        if frozen and not self._frozen:
            self.ctx.log("error", f"fusion: the estimate has not changed for {t - self._output_since_s:.2f} s "
                                  "(a hung estimator)")
        self._frozen = frozen

    def _publish(self) -> None:
        t = self.ctx.now()
        self._feed()
        self._check_starvation(t)
        try:
            est = self.estimator.estimate(t)
        except (ValueError, ArithmeticError) as exc:
            self.ctx.log("error", f"fusion estimate failed: {exc}")
            return
        if est is not None:
            self._check_frozen(t, est)
            self.ctx.publish(Topic.STATE, est)
            self.ctx.publish(Topic.SENS_FUS, est)
            if self.sea is not None:
                self.sea.on_state(est)
                sea = self.sea.estimate(t)
                if sea is not None:
                    self.ctx.publish(Topic.SEA_STATE, sea)
                set_w = getattr(self.estimator, "set_wave_frequency", None)
                if set_w is not None:
                    # the wave model at the frequency the boat met the sea's peak over the sea state's
                    # window (following seas at 1 m/s: 2.9 rad/s where the 8-s heave mean said 5.3)
                    set_w(self.sea.encounter_frequency_radps())
        if t - self._last_health_s >= self.health_period_s - 1e-9:
            self._last_health_s = t
            self._publish_health(t)

    def _publish_health(self, t: float) -> None:
        topic = getattr(Topic, "ESTIMATOR_HEALTH", None)
        health = getattr(self.estimator, "health", None)
        if topic is None or health is None:
            return
        h = health(t)
        node_faults, node_codes = [], []
        if self._starved:
            node_faults.append(f"inputs: no sensor sample used for {t - self._last_use_s:.2f} s")
            node_codes.append("node.starved")
        if self._frozen:
            node_faults.append(f"output: the estimate has not changed for {t - self._output_since_s:.2f} s")
            node_codes.append("node.output_frozen")
        if node_faults:
            h = dataclasses.replace(h, position_ok=False, heading_ok=False, velocity_ok=False,
                                    faults=tuple(node_faults) + tuple(h.faults),
                                    fault_codes=tuple(node_codes) + tuple(h.fault_codes))
        self._log_integrity(h)
        self.ctx.publish(topic, h)

    def _log_integrity(self, h: Any) -> None:
        """Every fault the estimator declares or clears, and its informational events (gate
        re-opened, time jump, ...), as log events: the run's log says what the monitor saw."""
        codes = dict(zip(h.fault_codes, h.faults))
        for code in codes.keys() - self._codes:
            self.ctx.log("warning", f"fusion integrity: {codes[code]}", fault=code)
        for code in self._codes - codes.keys():
            self.ctx.log("info", f"fusion integrity: {code} cleared", fault=code)
        self._codes = set(codes)
        new = h.event_count - self._event_count
        if new > 0:
            for text in h.events[-min(new, len(h.events)):] if h.events else ():
                self.ctx.log("info", f"fusion: {text}")
        self._event_count = h.event_count
