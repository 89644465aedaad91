"""The supervisor: modes, transitions and failsafes (docs/failsafes.md).

Modes (ArduPilot's pattern: a class per mode with enter/update, predicates like
`requires_position`):

| mode      | what the thrusters do                                  | entered by                          |
|-----------|--------------------------------------------------------|-------------------------------------|
| MANUAL    | keyboard ManualCommand -> thrust allocation            | start, 'manual', 'reset_estop', stop failsafes |
| AUTO      | follow the planned route; HOLD at its end              | 'auto' (needs a route and a position) |
| HOLD      | station keeping at a target pose                       | 'hold', end of route/return, GNSS/geofence failsafes |
| RETURN    | plan to the harbour inside the area and follow it      | 'return', low battery               |
| CALIBRATE | spin on the bow thruster one turn, fit the magnetometer | 'calibrate_mag'                     |
| ESTOP     | neutral, latched until 'reset_estop'                    | 'estop' from any mode               |
| RC        | the RC transmitter's command (or neutral)              | RcOverride.active: wins over all    |

"Stop" in the failsafe table means MANUAL with neutral thrusters and the reason shown: the
operator can still drive by keyboard, the boat does not move by itself.

The supervisor owns the controllers and publishes the only ship_command in the stack, so
exactly one thing decides what the thrusters do. Every command leaving it is checked for
non-finite values (neutral instead), and the actuator guard downstream checks again.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Callable

from lotsen.errors import LotsenError
from lotsen.messages import (
    OPERATOR_ACTIONS, BatteryStatus, ControllerStatus, GnssFix, LinkStatus, MagCalibrationResult,
    MagSample, ManualCommand, OperatorCommand, PathMessage, RcOverride, RouteMessage, RpmSample,
    SupervisorStatus, ThrustCommand, Topic, VesselState,
)
from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, VesselModel
from lotsen.runtime.executor import Node, NodeContext
from lotsen.runtime.failsafes import FailsafeConfig, FailsafeState, PersistentCondition


class Mode(str, Enum):
    MANUAL = "MANUAL"
    AUTO = "AUTO"
    HOLD = "HOLD"
    RETURN = "RETURN"
    CALIBRATE = "CALIBRATE"
    ESTOP = "ESTOP"
    RC = "RC"


@dataclass(frozen=True)
class SupervisorConfig:
    control_rate_hz: float = 10.0
    controller: str = "mpc"
    # manual driving: full key deflection means this generalized force
    manual_surge_N: float = 5.0
    manual_sway_N: float = 1.5
    manual_yaw_Nm: float = 1.2
    # magnetometer calibration manoeuvre
    calibration_bow_rps: float = 60.0
    calibration_turn_deg: float = 400.0
    calibration_timeout_s: float = 90.0
    path_message_points: int = 400
    failsafes: FailsafeConfig = field(default_factory=FailsafeConfig)


def _neutral(t: float, source: str) -> ThrustCommand:
    return ThrustCommand.neutral(t, source=source)


class SupervisorNode(Node):
    name = "supervisor"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: SupervisorConfig = SupervisorConfig(), control_config: Any = None,
                 mag_calibrator: Callable[[list[tuple[float, float]]], Any] | None = None) -> None:
        from lotsen.control import ControlConfig, ThrustAllocator, make_path_follower, make_station_keeper

        self.model = model or VesselModel()
        self.limits = limits
        self.config = config
        fs = config.failsafes
        self.control_config = control_config or ControlConfig(controller=config.controller)
        self._make_follower = lambda name: make_path_follower(
            _with_controller(self.control_config, name), self.model, limits)
        self.follower = self._make_follower(self.control_config.controller)
        self.fallback = None
        self.station_keeper = make_station_keeper(self.control_config, self.model, limits)
        self.allocator = ThrustAllocator(self.model, limits)
        self.mag_calibrator = mag_calibrator
        self.period_s = 1.0 / config.control_rate_hz
        # inputs
        self.state: VesselState | None = None
        self.route: Any = None
        self.path: Any = None
        self.manual: ManualCommand | None = None
        self.manual_arrival_s = -math.inf
        self.link: LinkStatus | None = None
        self.link_arrival_s = -math.inf
        self.rc: RcOverride | None = None
        self.last_usable_fix_s: float | None = None
        self.last_fix: GnssFix | None = None
        self.battery: BatteryStatus | None = None
        # mode
        self.mode = Mode.MANUAL
        self.reason = "start"
        self.stopped = ""  # non-empty: a failsafe stopped the boat (MANUAL, neutral until new keys)
        self.hold_target: Any = None
        self.active_path: Any = None  # the path AUTO/RETURN is following
        self.mode_before_rc = Mode.MANUAL
        # failsafes
        self.failsafes = FailsafeState()
        self._gnss_lost = PersistentCondition(0.0, 1.0)
        self._gnss_degraded = PersistentCondition(fs.gnss_degraded_s, 2.0)
        self._geofence = PersistentCondition(fs.geofence_persist_s, 2.0)
        self._battery_low = PersistentCondition(fs.battery_persist_s, 10.0)
        self._battery_critical = PersistentCondition(fs.battery_persist_s, 10.0)
        self._thruster_fault = PersistentCondition(fs.thruster_persist_s, 2.0)
        self._last_command: ThrustCommand | None = None
        self._rpm_mismatch: str = ""
        self._controller_failures = 0
        self._controller_overruns = 0
        self._gnss_lost_since: float | None = None
        self._low_battery_handled = False
        self.counters = {"non_finite_commands": 0, "refused_requests": 0, "controller_fallbacks": 0}
        # calibration manoeuvre
        self._cal_samples: list[tuple[float, float]] = []
        self._cal_heading_travel = 0.0
        self._cal_last_heading: float | None = None
        self._cal_start_s = 0.0
        self.last_status: ControllerStatus | None = None

    # ------------------------------------------------------------------ wiring
    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        ctx.subscribe(Topic.MANUAL, self._on_manual)
        ctx.subscribe(Topic.LINK, self._on_link)
        ctx.subscribe(Topic.RC, self._on_rc)
        ctx.subscribe(Topic.STATE, self._on_state)
        ctx.subscribe(Topic.GNSS, self._on_gnss)
        ctx.subscribe(Topic.BATTERY, self._on_battery)
        ctx.subscribe(Topic.ROUTE, self._on_route)
        ctx.subscribe(Topic.IMU_MAG, self._on_mag)
        ctx.subscribe(Topic.RPM, self._on_rpm)
        ctx.add_timer(self.period_s, self._tick)

    def _on_manual(self, msg: ManualCommand) -> None:
        vals = (msg.surge, msg.sway, msg.yaw)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            self.counters["refused_requests"] += 1
            return
        self.manual = ManualCommand(stamp_s=msg.stamp_s, surge=_clip1(msg.surge), sway=_clip1(msg.sway),
                                    yaw=_clip1(msg.yaw))
        self.manual_arrival_s = self.ctx.now()
        if any(vals) and self.stopped and self.mode == Mode.MANUAL:
            self.stopped = ""  # the operator takes over after a failsafe stop

    def _on_link(self, msg: LinkStatus) -> None:
        self.link = msg
        self.link_arrival_s = self.ctx.now()

    def _on_rc(self, msg: RcOverride) -> None:
        if msg.active and self.mode != Mode.RC:
            self.mode_before_rc = self.mode
            self._set_mode(Mode.RC, "RC transmitter override")
        elif not msg.active and self.mode == Mode.RC:
            if self._position_ok():
                self._enter_hold("RC override released")
            else:
                self._set_mode(Mode.MANUAL, "RC override released")
        self.rc = msg

    def _on_state(self, msg: VesselState) -> None:
        self.state = msg

    def _on_gnss(self, fix: GnssFix) -> None:
        self.last_fix = fix
        if fix.usable:
            self.last_usable_fix_s = self.ctx.now()

    def _on_battery(self, msg: BatteryStatus) -> None:
        self.battery = msg

    def _on_rpm(self, msg: RpmSample) -> None:
        """Compare the tachometers with the commanded speeds (a failed ESC, a fouled propeller)."""
        cmd = self._last_command
        if cmd is None:
            return
        fs = self.config.failsafes
        bad = []
        for name, meas, want in (("azimuth 1", msg.n1_rps, cmd.n1_rps), ("azimuth 2", msg.n2_rps, cmd.n2_rps),
                                 ("bow", msg.nt_rps, cmd.nt_rps)):
            if math.isfinite(meas) and abs(meas - want) > max(fs.thruster_mismatch_frac * abs(want),
                                                              fs.thruster_mismatch_min_rps):
                bad.append(f"{name} {meas:.0f} rev/s, commanded {want:.0f}")
        self._rpm_mismatch = "; ".join(bad)

    def _on_mag(self, msg: MagSample) -> None:
        if self.mode == Mode.CALIBRATE:
            self._cal_samples.append((msg.field_uT[0], msg.field_uT[1]))

    def _on_route(self, msg: RouteMessage) -> None:
        from lotsen.planning import plan_route
        from lotsen.planning.io import route_from_dict

        try:
            route = route_from_dict(msg.route)
            path = plan_route(route)
        except LotsenError as exc:
            self.ctx.log("error", f"route refused: {exc}")
            self.counters["refused_requests"] += 1
            return
        if self.mode in (Mode.AUTO, Mode.RETURN):
            self._enter_hold("new route received while moving")
        self.route, self.path = route, path
        self.ctx.log("info", f"route accepted: {len(route.nodes)} nodes, {path.length_m:.1f} m")
        self.ctx.publish(Topic.PATH, _path_message(self.ctx.now(), path, self.config.path_message_points))

    def set_route(self, route: Any, path: Any) -> None:
        """Load a route directly (launch config's `route`), as if the operator had sent it."""
        self.route, self.path = route, path

    # ------------------------------------------------------------------ operator requests
    def _on_operator(self, cmd: OperatorCommand) -> None:
        action = cmd.action
        if action not in OPERATOR_ACTIONS:
            self._refuse(f"unknown action {action!r}")
            return
        if action in ("rtk_start", "rtk_stop", "logging_on", "logging_off"):
            return  # handled by the GNSS driver and the recorder
        if action == "estop":
            self._set_mode(Mode.ESTOP, f"emergency stop by {cmd.source}")
            return
        if self.mode == Mode.RC:
            self._refuse(f"{action}: the RC transmitter has control")
            return
        if self.mode == Mode.ESTOP and action != "reset_estop":
            self._refuse(f"{action}: emergency stop is latched; reset it first")
            return
        if action == "reset_estop":
            if self.mode == Mode.ESTOP:
                self.manual = None
                self._set_mode(Mode.MANUAL, "emergency stop reset")
            return
        if action == "manual":
            self.manual = None
            self._set_mode(Mode.MANUAL, f"requested by {cmd.source}")
            return
        if not self._position_ok():
            self._refuse(f"{action}: no usable position estimate")
            return
        if action == "hold":
            self._enter_hold(f"requested by {cmd.source}")
        elif action == "auto":
            if self.path is None:
                self._refuse("auto: no route loaded")
                return
            self._start_following(self.path, Mode.AUTO, f"requested by {cmd.source}",
                                  resume=self.active_path is self.path and self.mode == Mode.HOLD)
        elif action == "return":
            self._start_return(f"requested by {cmd.source}")
        elif action == "calibrate_mag":
            self._cal_samples = []
            self._cal_heading_travel = 0.0
            self._cal_last_heading = None
            self._cal_start_s = self.ctx.now()
            self._set_mode(Mode.CALIBRATE, f"requested by {cmd.source}")

    def _refuse(self, text: str) -> None:
        self.counters["refused_requests"] += 1
        self.ctx.log("warning", f"request refused: {text}")

    # ------------------------------------------------------------------ mode changes
    def _set_mode(self, mode: Mode, reason: str) -> None:
        if mode != self.mode or reason != self.reason:
            self.ctx.log("info" if mode not in (Mode.ESTOP,) else "warning",
                         f"mode {self.mode.value} -> {mode.value}: {reason}", mode=mode.value)
        if mode != Mode.MANUAL:
            self.stopped = ""
        self.mode = mode
        self.reason = reason
        self._publish_status()

    def _enter_hold(self, reason: str, target: Any = None) -> None:
        from lotsen.control import HoldTarget

        s = self.state
        if target is None:
            if s is None:
                self._stop(f"{reason} (no position to hold)")
                return
            target = HoldTarget(s.north_m, s.east_m, s.heading_rad)
        self.hold_target = target
        self.station_keeper.reset()
        self._set_mode(Mode.HOLD, reason)

    def _stop(self, reason: str) -> None:
        self.stopped = reason
        self.manual = None
        self._set_mode(Mode.MANUAL, f"stopped: {reason}")

    def _start_following(self, path: Any, mode: Mode, reason: str, resume: bool = False) -> None:
        if not resume:
            self.follower.reset(path)
            if self.fallback is not None:
                self.fallback.reset(path)
        self.active_path = path
        self._controller_failures = self._controller_overruns = 0
        self._set_mode(mode, reason)

    def _start_return(self, reason: str) -> None:
        from lotsen.planning import plan_return_route

        s = self.state
        if self.route is None or s is None:
            self._enter_hold(f"{reason}: no route/harbour known, holding instead")
            return
        try:
            path = plan_return_route(self.route, s.north_m, s.east_m, s.heading_rad)
        except LotsenError as exc:
            self.ctx.log("error", f"return to harbour cannot be planned: {exc}")
            self._enter_hold(f"{reason}: return not plannable, holding instead")
            return
        self.ctx.publish(Topic.PATH, _path_message(self.ctx.now(), path, self.config.path_message_points))
        self._start_following(path, Mode.RETURN, reason)

    # ------------------------------------------------------------------ the control tick
    def _tick(self) -> None:
        t = self.ctx.now()
        self._check_failsafes(t)
        cmd, status = self._command(t)
        if not cmd.is_finite():
            self.counters["non_finite_commands"] += 1
            self.ctx.log("error", "non-finite thrust command replaced by neutral", mode=self.mode.value)
            cmd = _neutral(t, "supervisor:non-finite")
        self.ctx.publish(Topic.SHIP_COMMAND, cmd)
        self._last_command = cmd
        if status is not None:
            self.last_status = status
            self.ctx.publish(Topic.CONTROL_STATUS, status)
        self._publish_status()

    def _command(self, t: float) -> tuple[ThrustCommand, ControllerStatus | None]:
        mode = self.mode
        if mode == Mode.ESTOP:
            return _neutral(t, "estop"), None
        if mode == Mode.RC:
            rc = self.rc
            return (rc.command if rc and rc.command else _neutral(t, "rc")), None
        if mode == Mode.MANUAL:
            return self._manual_command(t), None
        if mode == Mode.CALIBRATE:
            return self._calibration_command(t), None
        s = self.state
        if s is None or not _finite_state(s):
            self._stop("no finite state estimate")
            return _neutral(t, "supervisor"), None
        if mode == Mode.HOLD:
            return self.station_keeper.update(t, s, self.hold_target)
        follower = self.fallback or self.follower
        t0 = time.perf_counter()
        cmd, status = follower.update(t, s)
        self._watch_controller(t, status, (time.perf_counter() - t0) * 1000.0)
        if self.mode not in (Mode.AUTO, Mode.RETURN):  # the controller watch switched mode
            return self._command(t)
        if follower.done:
            end = self.active_path.sample(self.active_path.length_m)
            from lotsen.control import HoldTarget

            self._enter_hold(f"{mode.value.lower()} finished: holding at the end",
                             HoldTarget(float(end.north_m), float(end.east_m), float(end.heading_rad)))
        return cmd, status

    def _manual_command(self, t: float) -> ThrustCommand:
        fs = self.config.failsafes
        m = self.manual
        if self.stopped or m is None or t - self.manual_arrival_s > fs.manual_timeout_s:
            return _neutral(t, "manual:idle" if not self.stopped else "manual:stopped")
        if "link_lost" in self.failsafes.active:
            return _neutral(t, "manual:link-lost")
        c = self.config
        tau = (m.surge * c.manual_surge_N, m.sway * c.manual_sway_N, m.yaw * c.manual_yaw_Nm)
        if tau == (0.0, 0.0, 0.0):
            return _neutral(t, "manual")
        res = self.allocator.allocate(tau)
        return ThrustCommand.from_tuple(t, res.command, source="manual")

    def _calibration_command(self, t: float) -> ThrustCommand:
        """One slow turn on the bow thruster (the azimuths idle), then fit the ellipse."""
        c = self.config
        s = self.state
        if s is not None and math.isfinite(s.heading_rad):
            if self._cal_last_heading is not None:
                d = (s.heading_rad - self._cal_last_heading + math.pi) % (2 * math.pi) - math.pi
                self._cal_heading_travel += abs(d)
            self._cal_last_heading = s.heading_rad
        done = math.degrees(self._cal_heading_travel) >= c.calibration_turn_deg
        if done or t - self._cal_start_s > c.calibration_timeout_s:
            self._finish_calibration(t, done)
            return _neutral(t, "calibration:done")
        return ThrustCommand(stamp_s=t, nt_rps=c.calibration_bow_rps, source="calibration")

    def _finish_calibration(self, t: float, turned: bool) -> None:
        result = MagCalibrationResult(stamp_s=t, ok=False, text="calibration manoeuvre timed out")
        if turned and self.mag_calibrator is not None:
            try:
                result = self.mag_calibrator(self._cal_samples)
                result.stamp_s = t
            except LotsenError as exc:
                result = MagCalibrationResult(stamp_s=t, ok=False, text=str(exc))
        elif turned:
            result = MagCalibrationResult(stamp_s=t, ok=False, text="no magnetometer calibrator configured")
        self.ctx.publish(Topic.MAG_CALIBRATION, result)
        self.ctx.log("info" if result.ok else "warning", f"magnetometer calibration: {result.text}")
        if self._position_ok():
            self._enter_hold("calibration finished")
        else:
            self._set_mode(Mode.MANUAL, "calibration finished")

    # ------------------------------------------------------------------ failsafes
    def _flag(self, name: str, on: bool, reason: str = "") -> bool:
        became_on, became_off = self.failsafes.set(name, on, reason)
        if became_on:
            self.ctx.log("warning", f"failsafe {name}: {reason}", failsafe=name)
        elif became_off:
            self.ctx.log("info", f"failsafe {name} cleared", failsafe=name)
        return became_on

    def _position_ok(self) -> bool:
        s = self.state
        if s is None or not _finite_state(s):
            return False
        if len(s.std) >= 2 and max(s.std[0], s.std[1]) > self.config.failsafes.max_position_std_m:
            return False
        return True

    def _check_failsafes(self, t: float) -> None:
        fs = self.config.failsafes
        moving = self.mode in (Mode.AUTO, Mode.RETURN)
        # operator link: only meaningful once a pilot has been seen
        if self.link is not None:
            age = t - self.link_arrival_s
            lost = age > fs.link_timeout_s or not self.link.pilot_connected
            if self._flag("link_lost", lost, f"no pilot heard for {age:.1f} s" if age > fs.link_timeout_s
                          else "pilot disconnected") and moving and fs.link_lost_auto_action == "hold":
                self._enter_hold("failsafe: operator link lost")
        # GNSS lost: hold on dead reckoning, stop after gnss_stop_after_s
        if self.last_usable_fix_s is not None:
            lost = t - self.last_usable_fix_s > fs.gnss_lost_s
            if self._flag("gnss_lost", lost, f"no usable fix for {t - self.last_usable_fix_s:.1f} s"):
                self._gnss_lost_since = t
                if moving or self.mode == Mode.CALIBRATE:
                    if fs.gnss_lost_action == "hold":
                        self._enter_hold("failsafe: GNSS lost (dead reckoning)")
                    else:
                        self._stop("failsafe: GNSS lost")
            if lost and self._gnss_lost_since is not None and t - self._gnss_lost_since > fs.gnss_stop_after_s \
                    and self.mode == Mode.HOLD:
                self._stop(f"failsafe: GNSS lost for more than {fs.gnss_stop_after_s:.0f} s")
            if not lost:
                self._gnss_lost_since = None
        # RTK degraded
        fix = self.last_fix
        degraded = fix is not None and fix.usable and fix.fix_type < fs.min_fix_type
        degraded = self._gnss_degraded.update(degraded, t)
        if self._flag("gnss_degraded", degraded, f"fix {fix.fix_type.name if fix else '-'} below {fs.gnss_min_fix}") \
                and moving and fs.gnss_degraded_action != "continue":
            if fs.gnss_degraded_action == "hold":
                self._enter_hold("failsafe: RTK degraded")
            else:
                self._stop("failsafe: RTK degraded")
        # thruster fault: the tachometers disagree with the commands
        fault = self._thruster_fault.update(bool(self._rpm_mismatch), t)
        if self._flag("thruster", fault, self._rpm_mismatch) and moving:
            if fs.thruster_fault_action == "hold":
                self._enter_hold("failsafe: thruster fault")
            elif fs.thruster_fault_action == "stop":
                self._stop("failsafe: thruster fault")
        # geofence: bring the boat back inside, never freeze it outside (field notes #7)
        self._check_geofence(t)
        # battery
        v = self.battery.voltage_v if self.battery else math.nan
        critical = self._battery_critical.update(math.isfinite(v) and v < fs.battery_critical_v, t)
        low = self._battery_low.update(math.isfinite(v) and v < fs.battery_low_v, t)
        if self._flag("battery_critical", critical, f"{v:.2f} V below {fs.battery_critical_v} V"):
            if self.mode not in (Mode.ESTOP, Mode.RC):
                self._stop("failsafe: battery critical")
        if self._flag("battery_low", low and not critical, f"{v:.2f} V below {fs.battery_low_v} V") \
                and not self._low_battery_handled and self.mode in (Mode.AUTO, Mode.HOLD):
            self._low_battery_handled = True
            self._start_return("failsafe: battery low")

    def _check_geofence(self, t: float) -> None:
        fs = self.config.failsafes
        s = self.state
        if self.route is None or s is None or not _finite_state(s):
            self._flag("geofence", False)
            return
        from shapely.geometry import Point

        free = self.route.free_region()
        p = Point(s.north_m, s.east_m)
        outside = not free.buffer(fs.geofence_margin_m).contains(p)
        breach = self._geofence.update(outside, t)
        self._flag("geofence", breach, f"position ({s.north_m:.1f}, {s.east_m:.1f}) outside the navigable area")
        # act whenever the boat is outside in a fenced mode (also when it was already outside on entering
        # the mode), unless it is already holding at the point inside
        if not breach or self.reason.startswith("failsafe: geofence"):
            return
        if self.mode in (Mode.ESTOP, Mode.RC, Mode.CALIBRATE) or (self.mode == Mode.MANUAL and not fs.geofence_in_manual):
            return
        from shapely.ops import nearest_points

        from lotsen.control import HoldTarget

        inner = free.buffer(-fs.geofence_inset_m)
        if inner.is_empty:
            inner = free
        q = nearest_points(inner, p)[0]
        # bow toward the water the boat was pushed out of: whatever pushed it out (current,
        # wind) is then met by the azimuths' full forward thrust, not by the weak sideways one
        heading = math.atan2(q.y - p.y, q.x - p.x) if p.distance(q) > 0.05 else s.heading_rad
        self._enter_hold("failsafe: geofence, holding inside the area", HoldTarget(q.x, q.y, heading))

    def _watch_controller(self, t: float, status: ControllerStatus, solve_ms: float) -> None:
        fs = self.config.failsafes
        # the controllers report "ok"/"saturated" normally, "fallback_plan (...)" while coasting on
        # the previous solution and "safe_stop (...)" when they gave up
        failed = status.status.startswith(("safe_stop", "fallback_plan", "failed"))
        self._controller_failures = self._controller_failures + 1 if failed else 0
        overrun = solve_ms > fs.controller_overrun_factor * self.period_s * 1000.0
        self._controller_overruns = self._controller_overruns + 1 if overrun else 0
        if self._controller_failures >= fs.controller_failure_count or \
                self._controller_overruns >= fs.controller_overrun_count:
            why = (f"{self._controller_failures} failed updates ({status.status})"
                   if self._controller_failures >= fs.controller_failure_count
                   else f"{self._controller_overruns} overruns ({solve_ms:.1f} ms)")
            self._controller_failures = self._controller_overruns = 0
            if self.fallback is None:
                self.counters["controller_fallbacks"] += 1
                self._flag("controller", True, f"{self.follower.name}: {why}; fallback {fs.fallback_controller}")
                self.fallback = self._make_follower(fs.fallback_controller)
                self.fallback.reset(self.active_path)
            else:
                self._flag("controller", True, f"fallback {self.fallback.name} failed too: {why}")
                self._stop("failsafe: controller and fallback failed")

    # ------------------------------------------------------------------ status
    def _publish_status(self) -> None:
        warnings = tuple(f"{k}: {v}" for k, v in self.failsafes.active.items())
        if self.stopped:
            warnings = (f"stopped: {self.stopped}",) + warnings
        self.ctx.publish(Topic.SUPERVISOR, SupervisorStatus(
            stamp_s=self.ctx.now(), mode=self.mode.value, reason=self.reason,
            armed=self.mode not in (Mode.ESTOP,), warnings=warnings,
            active_failsafes=tuple(self.failsafes.active)))


def _with_controller(config: Any, name: str) -> Any:
    from dataclasses import replace

    return replace(config, controller=name)


def _clip1(v: float) -> float:
    return min(max(float(v), -1.0), 1.0)


def _finite_state(s: VesselState) -> bool:
    return all(math.isfinite(v) for v in s.as_array_tuple())


def _path_message(t: float, path: Any, max_points: int) -> PathMessage:
    n = len(path.s_m)
    step = max(1, n // max_points)
    idx = list(range(0, n, step))
    if idx[-1] != n - 1:
        idx.append(n - 1)
    return PathMessage(stamp_s=t, north_m=tuple(float(path.north_m[i]) for i in idx),
                       east_m=tuple(float(path.east_m[i]) for i in idx),
                       speed_mps=tuple(float(path.speed_mps[i]) for i in idx))
