"""Fault-injection scenarios on the simulated boat (issue: supervisor, failsafes).

Each scenario runs the whole stack (simulated boat, EKF, supervisor with its controllers) on
simulated time, injects one fault, and checks that the documented safe state is reached within
the documented time, that the boat never leaves the navigable area by more than the documented
margin, and that the run's log holds the event. `make test` runs the short version
(tests/runtime/test_fault_injection.py); `make bench` the long one with a results table.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Callable

from lotsen.messages import (
    GnssFixType, ImuSample, LinkStatus, LogEvent, ManualCommand, OperatorCommand, SupervisorStatus,
    ThrustCommand, Topic, VesselState,
)
from lotsen.runtime.config import EnvironmentConfig, LaunchConfig, LoggingSection, NodesSection, SimSection
from lotsen.runtime.executor import Node, NodeContext
from lotsen.runtime.launch import Stack, build_stack

ROUTE = "examples/routes/figure_eight.yaml"
START = (4.0, 20.0, 0.0, 0.0, 0.0, 0.0)  # at the figure eight's harbour, heading north


@dataclass
class Trace:
    """What happened, sampled from the bus."""

    modes: list[tuple[float, str, str]] = field(default_factory=list)  # (t, mode, reason) on change
    events: list[LogEvent] = field(default_factory=list)
    commands: list[tuple[float, ThrustCommand]] = field(default_factory=list)
    max_outside_m: float = 0.0
    max_cte_m: float = 0.0
    max_heading_error_deg: float = 0.0
    truth_finite: bool = True

    def mode_at(self, t: float) -> str:
        m = self.modes[0][1] if self.modes else "MANUAL"
        for tm, mode, _ in self.modes:
            if tm <= t:
                m = mode
        return m

    def first_time(self, pred: Callable[[str, str], bool], after: float) -> float | None:
        for tm, mode, reason in self.modes:
            if tm >= after and pred(mode, reason):
                return tm
        return None


@dataclass(frozen=True)
class Scenario:
    name: str
    fault: str  # what is injected
    expected: str  # the documented safe state and deadline
    deadline_s: float  # from the fault to the safe state
    margin_m: float = 0.5  # allowed excursion outside the navigable area
    start_mode: str = "auto"  # 'auto' or 'manual'
    duration_s: float = 20.0  # fault length (for faults that clear)
    run_after_s: float = 25.0  # simulated time after the fault
    fault_at_s: float = 20.0
    controller: str = "mpc"
    environment: EnvironmentConfig = EnvironmentConfig()
    inject: Callable[["FaultRun"], None] = lambda run: None
    clear: Callable[["FaultRun"], None] | None = None
    check: Callable[["FaultRun"], tuple[bool, float | None, str]] = lambda run: (True, 0.0, "")
    log_contains: str = ""
    area: tuple[tuple[float, float], ...] | None = None  # replaces the route's navigable area


class _Recorder(Node):
    name = "fault_trace"

    def __init__(self, trace: Trace, stack: Stack) -> None:
        self.trace = trace
        self.stack = stack
        self.errors_after_s = math.inf  # tracking errors count from the fault on

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.SUPERVISOR, self._on_status)
        ctx.subscribe(Topic.LOG, self.trace.events.append)
        ctx.subscribe(Topic.SHIP_COMMAND, lambda c: self.trace.commands.append((ctx.now(), c)))
        ctx.subscribe(Topic.TRUTH, self._on_truth)
        ctx.subscribe(Topic.CONTROL_STATUS, self._on_control)

    def _on_status(self, s: SupervisorStatus) -> None:
        modes = self.trace.modes
        if not modes or modes[-1][1] != s.mode or modes[-1][2] != s.reason:
            modes.append((s.stamp_s, s.mode, s.reason))

    def _on_truth(self, s: VesselState) -> None:
        from shapely.geometry import Point

        if not all(math.isfinite(v) for v in s.as_array_tuple()):
            self.trace.truth_finite = False
            return
        sup = self.stack.nodes.get("supervisor")
        route = getattr(sup, "route", None)
        if route is not None:
            d = route.free_region().distance(Point(s.north_m, s.east_m))
            self.trace.max_outside_m = max(self.trace.max_outside_m, d)
        est = self.stack.bus.latest.get(Topic.STATE)
        if est is not None and math.isfinite(est.heading_rad) and s.stamp_s >= self.errors_after_s:
            err = math.degrees(abs((est.heading_rad - s.heading_rad + math.pi) % (2 * math.pi) - math.pi))
            self.trace.max_heading_error_deg = max(self.trace.max_heading_error_deg, err)

    def _on_control(self, s: Any) -> None:
        if math.isfinite(s.cross_track_error_m) and self.stack.nodes["supervisor"].mode.value == "AUTO" \
                and s.stamp_s >= self.errors_after_s:
            self.trace.max_cte_m = max(self.trace.max_cte_m, abs(s.cross_track_error_m))


class _Pilot(Node):
    """An operator at the keyboard: ManualCommand at 10 Hz and LinkStatus at 5 Hz until `cut`."""

    name = "fake_pilot"

    def __init__(self) -> None:
        self.cut_at = math.inf

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.add_timer(0.1, self._tick)

    def _tick(self) -> None:
        t = self.ctx.now()
        if t >= self.cut_at:
            return
        self.ctx.publish(Topic.MANUAL, ManualCommand(stamp_s=t, surge=0.6))
        if round(t * 10) % 2 == 0:
            self.ctx.publish(Topic.LINK, LinkStatus(stamp_s=t, pilot_connected=True, last_heard_s=t))


class FaultRun:
    """One scenario: build, run to the fault, inject, run on, evaluate."""

    def __init__(self, scenario: Scenario, seed: int = 0, log_dir: str | None = None) -> None:
        """`log_dir`: record the run to MCAP there and look for the event in that file (the run's
        log); without it, the events seen on the bus are checked."""
        self.scenario = scenario
        sc = scenario
        cfg = LaunchConfig(seed=seed, route=ROUTE, nodes=NodesSection(fusion="ekf", controller=sc.controller),
                           sim=SimSection(initial_state=START, environment=sc.environment),
                           logging=LoggingSection(enabled=log_dir is not None, directory=log_dir or "logs"))
        cfg = replace(cfg, extra={"failsafes": {}})
        parts = ("state", "supervisor") + (("logs",) if log_dir is not None else ())
        self.stack = build_stack(cfg, realtime=False, parts=parts)
        self.log_path: Any = None
        self.trace = Trace()
        self.recorder = self.stack.add(_Recorder(self.trace, self.stack))
        if sc.area is not None:
            sup = self.supervisor
            sup.route = replace(sup.route, area=sc.area)
        self.pilot = self.stack.add(_Pilot()) if sc.start_mode == "manual" else None
        self.sim = self.stack.simulator
        self.fault_t = sc.fault_at_s
        self.wall_s = 0.0

    @property
    def supervisor(self) -> Any:
        return self.stack.nodes["supervisor"]

    def publish(self, topic: str, msg: Any) -> None:
        self.stack.bus.publish(topic, msg)

    def run(self) -> dict:
        sc, ex = self.scenario, self.stack.executor
        t0 = time.perf_counter()
        ex.run_until(3.0)
        if sc.start_mode == "auto":
            self.publish(Topic.OPERATOR, OperatorCommand(stamp_s=3.0, action="auto"))
        ex.run_until(self.fault_t)
        self.recorder.errors_after_s = self.fault_t
        sc.inject(self)
        end = self.fault_t + sc.run_after_s
        if sc.clear is not None:
            t_clear = self.fault_t + sc.duration_s
            ex.run_until(min(t_clear, end))
            sc.clear(self)
        ex.run_until(end)
        self.wall_s = time.perf_counter() - t0
        ok, t_safe, detail = sc.check(self)
        logged = (not sc.log_contains) or any(sc.log_contains in e.text for e in self._logged_events())
        inside = self.trace.max_outside_m <= sc.margin_m
        return {
            "scenario": sc.name, "fault": sc.fault, "expected": sc.expected,
            "deadline_s": sc.deadline_s, "time_to_safe_s": None if t_safe is None else round(t_safe, 2),
            "safe_state_reached": ok, "max_outside_area_m": round(self.trace.max_outside_m, 3),
            "margin_m": sc.margin_m, "logged": logged, "pass": bool(ok and inside and logged
                                                                    and self.trace.truth_finite),
            "detail": detail, "wall_s": round(self.wall_s, 1),
        }


    def _logged_events(self) -> list[LogEvent]:
        """The LogEvents in the run's MCAP file when recording, else those seen on the bus."""
        rec = self.stack.services.get("recorder")
        if rec is None:
            return self.trace.events
        self.log_path = rec.path
        for close in self.stack.services.get("on_shutdown", []):
            close()
        from lotsen.logs.reader import LogReader

        return [msg for _, msg in LogReader(self.log_path).messages(topics=[Topic.LOG])]


# ---------------------------------------------------------------------------- checks
def _mode_within(mode: str, reason_part: str = "") -> Callable[[FaultRun], tuple[bool, float | None, str]]:
    def check(run: FaultRun) -> tuple[bool, float | None, str]:
        t = run.trace.first_time(lambda m, r: m == mode and reason_part in r, run.fault_t)
        if t is None:
            return False, None, f"never reached {mode}; modes {run.trace.modes[-3:]}"
        dt = t - run.fault_t
        return dt <= run.scenario.deadline_s, dt, f"{mode} after {dt:.2f} s"
    return check


def _neutral_within(run: FaultRun) -> tuple[bool, float | None, str]:
    for t, c in run.trace.commands:
        if t >= run.fault_t and c.as_tuple() == (0.0, 0.0, 0.0, 0.0, 0.0):
            dt = t - run.fault_t
            # and it must stay neutral afterwards
            later = [cc for tt, cc in run.trace.commands if tt >= t]
            if all(cc.as_tuple() == (0.0,) * 5 for cc in later):
                return dt <= run.scenario.deadline_s, dt, f"neutral after {dt:.2f} s"
    return False, None, "thrusters never went neutral"


def _continues(max_cte_m: float, max_heading_deg: float = 10.0):  # type: ignore[no-untyped-def]
    def check(run: FaultRun) -> tuple[bool, float | None, str]:
        mode = run.trace.mode_at(run.stack.executor.clock.now())
        ok = mode in ("AUTO", "HOLD") and run.trace.max_cte_m <= max_cte_m \
            and run.trace.max_heading_error_deg <= max_heading_deg \
            and not any(r.startswith("stopped") for _, _, r in run.trace.modes)
        return ok, 0.0, (f"mode {mode}, max cross-track {run.trace.max_cte_m:.2f} m, "
                         f"max heading error {run.trace.max_heading_error_deg:.1f} deg")
    return check


def _geofence_check(run: FaultRun) -> tuple[bool, float | None, str]:
    breach = [e.stamp_s for e in run.trace.events if "failsafe geofence:" in e.text]
    if not breach:
        return False, None, f"no geofence breach (max outside {run.trace.max_outside_m:.2f} m)"
    t = run.trace.first_time(lambda m, r: m == "HOLD" and "geofence" in r, breach[0])
    if t is None:
        return False, None, "breach without HOLD"
    sup = run.supervisor
    from shapely.geometry import Point

    target = sup.hold_target
    inside = sup.route.free_region().contains(Point(target.north_m, target.east_m))
    return inside and t - breach[0] <= run.scenario.deadline_s, t - breach[0], (
        f"breach at {breach[0]:.1f} s, HOLD at a point {'inside' if inside else 'OUTSIDE'} the area after "
        f"{t - breach[0]:.2f} s")


def _gnss_60_check(run: FaultRun) -> tuple[bool, float | None, str]:
    ok1, t1, d1 = _mode_within("HOLD", "GNSS lost")(run)
    fs = run.supervisor.config.failsafes
    t_stop = run.trace.first_time(lambda m, r: m == "MANUAL" and "GNSS lost for more" in r, run.fault_t)
    if t_stop is None:
        return False, t1, d1 + "; never stopped"
    dt = t_stop - run.fault_t
    ok2 = dt <= fs.gnss_lost_s + fs.gnss_stop_after_s + 1.0
    return ok1 and ok2, dt, d1 + f"; stopped after {dt:.1f} s"


def _controller_check(run: FaultRun) -> tuple[bool, float | None, str]:
    for t, c in run.trace.commands:
        if t >= run.fault_t and c.source == run.supervisor.config.failsafes.fallback_controller:
            dt = t - run.fault_t
            return dt <= run.scenario.deadline_s, dt, f"fallback {c.source} after {dt:.2f} s"
    return False, None, "no fallback controller"


def _nan_check(run: FaultRun) -> tuple[bool, float | None, str]:
    guard = run.stack.nodes["sim_boat"].guard
    acts = run.sim.actuators.state
    ok = guard.counters.non_finite > 0 and all(math.isfinite(a) for a in acts) and run.trace.truth_finite
    return ok, 0.0, f"guard replaced {guard.counters.non_finite} non-finite commands; actuators finite"


# ---------------------------------------------------------------------------- injections
def _gnss_outage(run: FaultRun) -> None:
    run.sim.gnss.outage = True


def _gnss_restore(run: FaultRun) -> None:
    run.sim.gnss.outage = False


def _rtk_float_then_none(run: FaultRun) -> None:
    run.sim.set_gnss_fix_type(GnssFixType.RTK_FLOAT)

    class Later(Node):
        name = "rtk_none_later"

        def start(self, ctx: NodeContext) -> None:
            self.ctx = ctx
            self.timer = ctx.add_timer(1.0, self.tick, phase_s=8.0)

        def tick(self) -> None:
            run.sim.set_gnss_fix_type(GnssFixType.NO_FIX)
            run.rtk_none_t = self.ctx.now()
            self.timer.cancel()

    run.stack.add(Later())


def _rtk_check(run: FaultRun) -> tuple[bool, float | None, str]:
    t_none = getattr(run, "rtk_none_t", None)
    if t_none is None:
        return False, None, "fix never degraded to none"
    float_ok = run.trace.mode_at(t_none - 0.5) == "AUTO"
    t = run.trace.first_time(lambda m, r: m == "HOLD", t_none)
    if t is None:
        return False, None, "no HOLD after the fix was lost"
    dt = t - t_none
    return float_ok and dt <= run.scenario.deadline_s, dt, (
        f"RTK float: {'continued' if float_ok else 'did not continue'}; HOLD {dt:.2f} s after no fix")


def _mag_disturb(run: FaultRun) -> None:
    run.sim.mag.disturbance_uT = (12.0, -9.0)  # e.g. motor currents, a steel pontoon nearby


def _mag_restore(run: FaultRun) -> None:
    run.sim.mag.disturbance_uT = (0.0, 0.0)


def _imu_spikes(run: FaultRun) -> None:
    run.sim.imu.spike_probability = 0.02


def _imu_restore(run: FaultRun) -> None:
    run.sim.imu.spike_probability = 0.0


def _fail_azimuth(run: FaultRun) -> None:
    run.sim.actuators.set_faults(failed_units={0})


def _cut_link(run: FaultRun) -> None:
    assert run.pilot is not None
    run.pilot.cut_at = run.stack.executor.clock.now()


def _overrun(run: FaultRun) -> None:
    follower = run.supervisor.follower
    original = follower.update

    def slow_update(t: float, state: VesselState) -> Any:
        time.sleep(run.supervisor.period_s)  # a controller step longer than the control period
        return original(t, state)

    follower.update = slow_update  # type: ignore[method-assign]


def _inject_nan(run: FaultRun) -> None:
    class Rogue(Node):
        name = "rogue"

        def start(self, ctx: NodeContext) -> None:
            self.ctx = ctx
            self.n = 0
            ctx.add_timer(0.05, self.tick, phase_s=0.025)

        def tick(self) -> None:
            if self.n < 20:
                self.n += 1
                self.ctx.publish(Topic.SHIP_COMMAND, ThrustCommand(stamp_s=self.ctx.now(), n1_rps=float("nan"),
                                                                  n2_rps=60.0, source="rogue"))
                self.ctx.publish(Topic.IMU_RAW, ImuSample(stamp_s=self.ctx.now(), gyro_radps=(0, 0, float("nan")),
                                                          accel_mps2=(float("nan"), 0, -9.81)))

    run.stack.add(Rogue())


SCENARIOS: tuple[Scenario, ...] = (
    Scenario("gnss_outage_10s", "no GNSS fixes for 10 s during AUTO", "HOLD on dead reckoning within 2.5 s",
             2.5, duration_s=10.0, run_after_s=15.0, inject=_gnss_outage, clear=_gnss_restore,
             check=_mode_within("HOLD", "GNSS lost"), log_contains="failsafe gnss_lost"),
    Scenario("gnss_outage_60s", "no GNSS fixes for 60 s during AUTO",
             "HOLD within 2.5 s, then stop (neutral) after 20 s more", 2.5, duration_s=60.0, run_after_s=30.0,
             inject=_gnss_outage, clear=_gnss_restore, check=_gnss_60_check, log_contains="GNSS lost for more"),
    Scenario("rtk_fixed_float_none", "RTK fixed -> float (8 s) -> no fix", "AUTO continues on float; HOLD within "
             "2.5 s of losing the fix", 2.5, run_after_s=15.0, inject=_rtk_float_then_none, check=_rtk_check,
             log_contains="failsafe gnss_lost"),
    Scenario("mag_disturbance", "magnetometer offset by 15 uT for 20 s", "AUTO continues (EKF gates the "
             "magnetometer), cross-track < 0.5 m, heading error < 10 deg", 0.0, duration_s=20.0, run_after_s=22.0,
             inject=_mag_disturb, clear=_mag_restore, check=_continues(0.5)),
    Scenario("imu_spikes", "2 % of IMU samples with large spikes for 20 s", "AUTO continues, cross-track < 0.5 m",
             0.0, duration_s=20.0, run_after_s=22.0, inject=_imu_spikes, clear=_imu_restore,
             check=_continues(0.5)),
    Scenario("azimuth_failure", "starboard azimuth motor fails", "thruster failsafe: HOLD within 2.5 s", 2.5,
             run_after_s=15.0, inject=_fail_azimuth, check=_mode_within("HOLD", "thruster"),
             log_contains="failsafe thruster"),
    Scenario("link_lost_manual", "pilot's link lost while driving manually", "thrusters neutral within 2 s", 2.0,
             start_mode="manual", run_after_s=6.0, inject=_cut_link, check=_neutral_within, margin_m=5.0,
             log_contains="failsafe link_lost"),
    Scenario("controller_overrun", "MPC steps take longer than the control period",
             "fallback controller (LOS) within 1.0 s", 1.0, run_after_s=6.0, inject=_overrun,
             check=_controller_check, log_contains="failsafe controller"),
    Scenario("nan_injected", "NaN thrust commands and NaN IMU samples injected for 1 s",
             "non-finite commands replaced by neutral at the actuators; the boat stays finite", 0.0, run_after_s=8.0,
             inject=_inject_nan, check=_nan_check),
    Scenario("current_toward_geofence", "0.5 m/s current toward the east edge, 0.4 m beyond the route",
             "never more than 1 m outside; geofence HOLD inside within 0.5 s of a breach", 0.5, margin_m=1.0,
             fault_at_s=5.0, run_after_s=80.0, area=((0.0, 0.0), (40.0, 0.0), (40.0, 34.4), (0.0, 34.4)),
             environment=EnvironmentConfig(current_speed_mps=0.5, current_to_deg=90.0),
             check=_geofence_check, log_contains="failsafe geofence"),
)


def run_scenarios(names: tuple[str, ...] | None = None, seed: int = 0, log_dir: str | None = None) -> list[dict]:
    rows = []
    for sc in SCENARIOS:
        if names is None or sc.name in names:
            rows.append(FaultRun(sc, seed=seed, log_dir=log_dir).run())
    return rows
