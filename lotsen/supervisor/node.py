"""The supervisor: operator requests, modes, failsafes, and the one ship_command of the stack.

The supervisor owns the controllers and publishes the only ship_command, so exactly one thing
decides what the thrusters do. Every command leaving it is checked for non-finite values
(neutral instead), and the actuator guard downstream checks again.

Each control tick: inputs -> failsafe monitors (lotsen.supervisor.failsafes; the controller
monitor judges each path-follower update) -> the mode's command -> ship_command, supervisor/status (with the actions possible now and why the
others are not), mission/progress. Operator requests are checked against the modes' capability
predicates; a refusal is an `Alert` the operator sees, not only a log line.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np
from shapely import Point, contains_xy

from lotsen.control import ControlConfig, HoldTarget, ThrustAllocator, make_path_follower, make_station_keeper
from lotsen.errors import LotsenError
from lotsen.messages import (
    DepthSample,
    OPERATOR_ACTIONS, ActuatorState, CommandAck, ModeName, Alert, BatteryStatus, ControllerStatus, GnssFix, LinkStatus,
    MagCalibrationResult, MagSample, ManualCommand, MissionProgress, OperatorCommand, PathMessage, PlannedRoute,
    RcOverride, RecorderStatus, RouteMessage, RpmSample, SupervisorStatus, ThrustCommand, Topic, VesselState,
)
from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, VesselModel
from lotsen.planning import PlannerConfig, plan_return_route
from lotsen.planning.exchange import path_from_message
from lotsen.planning.io import route_from_dict, route_to_dict
from lotsen.runtime.executor import Node, NodeContext
from lotsen.supervisor.failsafes import (
    ControllerMonitor, FailsafeAction, FailsafeConfig, FailsafeState, GeofenceMonitor, Monitor, ProgressMonitor,
    ThrusterMonitor, monitor, standard_monitors, storage_problem,
)
from lotsen.supervisor.inputs import SupervisorInputs, finite_state as _finite_state
from lotsen.supervisor.modes import Hold, Mode, all_modes, neutral
from lotsen.supervisor.prearm import FailedCheck, PrearmInputs, blocking, describe, prearm_failures, route_corridor_m

#: failsafes whose action is "hold on dead reckoning, then stop after gnss_stop_after_s"
DEAD_RECKONING = ("gnss_lost", "estimator")
#: the mode each operator request asks for
REQUESTED_MODE = {"auto": ModeName.AUTO, "hold": ModeName.HOLD, "return": ModeName.RETURN,
                  "calibrate_mag": ModeName.CALIBRATE, "experiment": ModeName.EXPERIMENT}
PREARM_ACTIONS = ("arm", "auto", "experiment")  # the requests pre-arm checks guard
GEOFENCE_HOLD_REASON = "failsafe: geofence, holding inside the area"
SEVERITY_ORDER = ("info", "warning", "error", "critical")
#: request ids answered, kept to answer a resent request again without acting twice
ANSWERS_KEPT = 256


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
    progress_rate_hz: float = 2.0
    route_fence_tolerance_m: float = 0.05  # a received path may touch the area's edge by this much
    failsafes: FailsafeConfig = field(default_factory=FailsafeConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)  # the return to the harbour


class SupervisorNode(Node):
    name = "supervisor"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: SupervisorConfig = SupervisorConfig(), control_config: ControlConfig | None = None,
                 mag_calibrator: Callable[[list[tuple[float, float]]], Any] | None = None,
                 follower: Any = None, station_keeper: Any = None, heading_calibration: str = "") -> None:
        self.model = model or VesselModel()
        self.limits = limits
        self.config = config
        self.control_config = control_config or ControlConfig(controller=config.controller)
        self._make_follower = lambda name: make_path_follower(
            _with_controller(self.control_config, name), self.model, limits)
        self.follower = follower or self._make_follower(self.control_config.controller)
        self.fallback: Any = None
        self.station_keeper = station_keeper or make_station_keeper(self.control_config, self.model, limits)
        self.allocator = ThrustAllocator(self.model, limits)
        self.mag_calibrator = mag_calibrator
        self.period_s = 1.0 / config.control_rate_hz
        self.inputs = SupervisorInputs()
        # route (the route itself is an input: the geofence monitor reads it)
        self.path: Any = None
        self.route_id = ""
        self.node_s: tuple[float, ...] = ()
        self.route_checking = ""  # the id of a received route being checked (off the loop), "" = none
        self._route_seq = 0  # received routes, counted: only the last one's check result counts
        self.active_path: Any = None  # the path AUTO/RETURN is following
        self._time_to_end: np.ndarray | None = None  # planned seconds from each path point to the end
        # modes
        self.modes: dict[ModeName, Mode] = all_modes()
        self.mode: Mode = self.modes[ModeName.MANUAL]
        self.reason = "start"
        self.armed = False
        self.stopped = ""  # non-empty: a failsafe stopped the boat (MANUAL, neutral until new keys)
        self.mode_before_rc = ModeName.MANUAL
        # failsafes
        fs = config.failsafes
        self.failsafes = FailsafeState()
        self.monitors: list[Monitor] = standard_monitors(fs, limits)
        self.thruster: ThrusterMonitor = monitor(self.monitors, "thruster")
        self.geofence: GeofenceMonitor = monitor(self.monitors, "geofence")
        self.controller_monitor = ControllerMonitor(fs, self.period_s)
        self.progress_monitor = ProgressMonitor(fs)
        self.failsafe_history: list[str] = []  # "name: reason at t" of every failsafe that triggered
        self.counters = {"non_finite_commands": 0, "refused_requests": 0, "controller_fallbacks": 0,
                         "routes_refused": 0}
        self.last_status: ControllerStatus | None = None
        self._last_progress_s = -math.inf
        # pre-arm: where the magnetometer calibration in use came from ("" = not calibrated), and
        # the route's corridor, computed once per (route, path)
        self.heading_calibration = heading_calibration
        self.mag_review: MagCalibrationResult | None = None  # a fresh fit in use, awaiting accept/reject
        self._heading_calibration_before = heading_calibration
        self._corridor: tuple[Any, Any, float] = (None, None, math.inf)
        self._answered: OrderedDict[str, CommandAck] = OrderedDict()  # request_id -> its answer

    @property
    def route(self) -> Any:
        return self.inputs.route

    @route.setter
    def route(self, route: Any) -> None:
        self.inputs.route = route

    @property
    def fence(self) -> Any:
        """The boat's own navigable area (a Route whose area and obstacles count): the launch
        config's route area; None when the config has none. Set once at start."""
        return self.inputs.fence

    @fence.setter
    def fence(self, route: Any) -> None:
        self.inputs.fence = route

    @property
    def hold_target(self) -> HoldTarget | None:
        return self.modes[ModeName.HOLD].target  # type: ignore[attr-defined]

    # ------------------------------------------------------------------ wiring
    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        ctx.subscribe(Topic.MANUAL, self._on_manual)
        ctx.subscribe(Topic.EXPERIMENT_COMMAND, self._on_experiment)
        ctx.subscribe(Topic.LINK, self._on_link)
        ctx.subscribe(Topic.RC, self._on_rc)
        ctx.subscribe(Topic.STATE, self._on_state)
        ctx.subscribe(Topic.GNSS, self._on_gnss)
        ctx.subscribe(Topic.BATTERY, self._on_battery)
        ctx.subscribe(Topic.DEPTH, self._on_depth)
        ctx.subscribe(Topic.ROUTE, self._on_route)
        ctx.subscribe(Topic.IMU_MAG, self._on_mag)
        ctx.subscribe(Topic.RPM, self._on_rpm)
        ctx.subscribe(Topic.ACTUATORS, self._on_actuators)
        ctx.subscribe(Topic.RECORDER, self._on_recorder)
        health_topic = getattr(Topic, "ESTIMATOR_HEALTH", None)
        if health_topic is not None:
            ctx.subscribe(health_topic, self._on_health)
        ctx.add_timer(self.period_s, self._tick)
        if self.path is not None:  # a route loaded at start (launch config `route`)
            self._publish_route()

    def _on_manual(self, msg: ManualCommand) -> None:
        vals = (msg.surge, msg.sway, msg.yaw)
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            self.counters["refused_requests"] += 1
            return
        self.inputs.manual = ManualCommand(stamp_s=msg.stamp_s, surge=_clip1(msg.surge), sway=_clip1(msg.sway),
                                           yaw=_clip1(msg.yaw))
        self.inputs.manual_arrival_s = self.ctx.now()
        if any(vals) and self.stopped and self.mode.name == ModeName.MANUAL:
            self.stopped = ""  # the operator takes over after a failsafe stop

    def _on_experiment(self, msg: ThrustCommand) -> None:
        if not msg.is_finite():
            self.counters["refused_requests"] += 1
            return
        t = self.ctx.now()
        self.inputs.experiment, self.inputs.experiment_arrival_s = msg, t
        if self.mode.name == ModeName.EXPERIMENT:
            # forwarded as it comes, at the experiment's own rate (its design may be faster than
            # the control loop); the failsafes are judged on the loop's ticks as always
            self.send_command(t, self._command(t)[0])

    def _on_link(self, msg: LinkStatus) -> None:
        self.inputs.link = msg
        self.inputs.link_arrival_s = self.ctx.now()

    def _on_rc(self, msg: RcOverride) -> None:
        """The e-stop switch latches ESTOP; the takeover switch going on enters RC (also from
        ESTOP: the transmitter wins), going off releases it. Without a good link the switches are
        unknown and change nothing (the RC mode then commands neutral)."""
        t = self.ctx.now()
        was_on = self.inputs.rc_takeover
        self.inputs.rc, self.inputs.rc_arrival_s = msg, t
        if msg.link != "ok":
            return
        self.inputs.rc_takeover = msg.active
        if msg.estop:
            if self.mode.name != ModeName.ESTOP:
                self.set_mode(self.modes[ModeName.ESTOP], "emergency stop by the RC transmitter")
                self.alert("critical", "estop", "emergency stop by the RC transmitter")
            return
        if msg.active and not was_on:
            self.mode_before_rc = self.mode.name
            self.set_mode(self.modes[ModeName.RC], "RC transmitter override")
        elif not msg.active and self.mode.name == ModeName.RC:
            if self.position_ok() and self.armed:
                self.enter_hold(t, "RC override released")
            else:
                self.set_mode(self.modes[ModeName.MANUAL], "RC override released")

    def _on_state(self, msg: VesselState) -> None:
        self.inputs.state = msg

    def _on_gnss(self, fix: GnssFix) -> None:
        self.inputs.fix = fix
        if fix.usable:
            self.inputs.last_usable_fix_s = self.ctx.now()

    def _on_battery(self, msg: BatteryStatus) -> None:
        self.inputs.battery = msg

    def _on_depth(self, msg: DepthSample) -> None:
        if math.isfinite(msg.depth_m):  # a ping without a bottom says nothing about the depth
            self.inputs.depth = msg
            self.inputs.depth_arrival_s = self.ctx.now()

    def _on_actuators(self, msg: ActuatorState) -> None:
        self.inputs.actuators = msg

    def _on_recorder(self, msg: RecorderStatus) -> None:
        self.inputs.recorder, self.inputs.recorder_arrival_s = msg, self.ctx.now()

    def _on_health(self, msg: Any) -> None:
        self.inputs.health = msg

    def _on_rpm(self, msg: RpmSample) -> None:
        self.thruster.on_rpm(msg, self.inputs.actuators)

    def _on_mag(self, msg: MagSample) -> None:
        if self.mode.name == ModeName.CALIBRATE:
            self.modes[ModeName.CALIBRATE].samples.append((msg.field_uT[0], msg.field_uT[1]))  # type: ignore[attr-defined]

    # ------------------------------------------------------------------ routes
    def _on_route(self, msg: Any) -> None:
        """A received route is checked away from the control loop (`check_planned_route`: a
        survey's 78 000-point path took 0.2 s, two control periods) and switched to as a whole when
        its check is done: until then the boat keeps the route it held, and flies it in AUTO."""
        if not isinstance(msg, PlannedRoute):
            self._refuse("route", "the boat takes planned routes (PlannedRoute) only; plan it first")
            return
        self._route_seq += 1
        seq, fence, tolerance = self._route_seq, self.fence, self.config.route_fence_tolerance_m
        self.route_checking = msg.route_id or "(no id)"
        self.ctx.run_in_background(lambda: check_planned_route(msg, fence, tolerance),
                                   lambda checked, error: self._route_checked(seq, msg, checked, error))

    def _route_checked(self, seq: int, msg: PlannedRoute, checked: CheckedRoute | None,
                       error: BaseException | None) -> None:
        """On the loop's thread: the route, its path, id and corridor switched together, or refused."""
        if seq != self._route_seq:
            return  # a newer route arrived while this one was checked: the newer one counts
        self.route_checking = ""
        if error is not None or checked is None:
            self.counters["routes_refused"] += 1
            why = str(error) if isinstance(error, LotsenError) else f"route {msg.route_id}: not checkable ({error!r})"
            self._refuse("route", why)
            self._publish_status()
            return
        t = self.ctx.now()
        if self.mode.moving:
            self.enter_hold(t, "new route received while moving")
        self.set_route(checked.route, checked.path, msg.route_id, msg.node_s_m, checked.corridor_m)
        self.ctx.log("info", f"route {msg.route_id} accepted: {len(checked.route.nodes)} nodes, "
                             f"{checked.path.length_m:.1f} m")
        self._publish_route()
        self._publish_status()

    def return_route(self) -> Any:
        """The route the return to the harbour is planned in: the route in use, inside the boat's
        own area when the route brought none."""
        r, f = self.route, self.fence
        if r is None or f is None or r.area is not None:
            return r
        return replace(r, area=f.area, obstacles=tuple(r.obstacles) + tuple(f.obstacles))

    def set_route(self, route: Any, path: Any, route_id: str = "", node_s: tuple[float, ...] = (),
                  corridor_m: float | None = None) -> None:
        """Hold `route` and its planned `path` (the launch config's route, or one received); with
        its corridor when known (else the first pre-arm check computes it, on the loop)."""
        self.route, self.path, self.route_id, self.node_s = route, path, route_id, tuple(node_s)
        if corridor_m is not None:
            self._corridor = (route, path, corridor_m)

    def _publish_route(self) -> None:
        t = self.ctx.now()
        self.ctx.publish(Topic.PATH, path_message(t, self.path, self.config.path_message_points))
        if self.route is not None:
            self.ctx.publish(Topic.ACTIVE_ROUTE, RouteMessage(stamp_s=t, route=route_to_dict(self.route),
                                                              source="boat", route_id=self.route_id))

    # ------------------------------------------------------------------ operator requests
    def why_not(self, action: str) -> str:
        """'' when `action` would be accepted now, else the reason (for refusals and the page)."""
        if action not in OPERATOR_ACTIONS:
            return f"unknown action {action!r}"
        if action in ("estop", "rtk_start", "rtk_stop", "logging_on", "logging_off"):
            return ""
        if action in ("mag_accept", "mag_reject"):  # moves nothing: possible in any mode
            return "" if self.mag_review is not None else "no magnetometer fit waiting for review"
        if self.mode.human_in_control:
            latched_estop = self.mode.name == ModeName.ESTOP and action == "reset_estop"
            return "" if latched_estop else self.mode.human_in_control
        if action == "reset_estop":
            return "no emergency stop to reset"
        if action == "disarm":
            return "" if self.armed else "already disarmed"
        if action == "arm":
            if self.armed:
                return "already armed"
            if not self.inputs.escs_armed:
                return "the ESCs are not armed yet (they need neutral for a few seconds)"
            return describe(blocking(self.prearm_failures(action), self.config.failsafes))
        if action == "manual":
            return ""
        mode = self.modes[REQUESTED_MODE[action]]
        if mode.requires_armed and not self.armed:
            return "arm first"
        if action == "auto" and self.route_checking:  # the operator means the route just sent
            return f"route {self.route_checking} is still being checked"
        if action in PREARM_ACTIONS:  # every failing pre-arm check, listed
            why = describe(blocking(self.prearm_failures(action), self.config.failsafes))
            if why or action != "experiment":
                return why
            stale = self.ctx.now() - self.inputs.experiment_arrival_s > self.config.failsafes.manual_timeout_s
            return "no experiment is sending commands (lotsen experiment run)" if stale else ""
        if mode.requires_armed and not self.inputs.escs_armed:
            return "the ESCs are not armed"
        if mode.requires_heading and not self._heading_ok():
            return "no trustworthy heading estimate"
        if mode.requires_position and not self.position_ok():
            return "no usable position estimate"
        if action == "auto" and self.path is None:
            return "no route loaded"
        return ""

    def _on_operator(self, cmd: OperatorCommand) -> None:
        """One operator request: refused with the reason, or done; with a request_id it is answered
        by a CommandAck (operator/ack), and a resent id is answered again without acting twice."""
        rid = cmd.request_id
        if rid and rid in self._answered:
            self.ctx.publish(Topic.OPERATOR_ACK, replace(self._answered[rid], stamp_s=self.ctx.now()))
            return
        why = self._operator(cmd)
        if rid:
            ack = CommandAck(stamp_s=self.ctx.now(), request_id=rid, action=cmd.action, accepted=not why,
                             reason=why, mode=str(self.mode.name), armed=self.armed)
            self._answered[rid] = ack
            while len(self._answered) > ANSWERS_KEPT:
                self._answered.popitem(last=False)
            self.ctx.publish(Topic.OPERATOR_ACK, ack)

    def _operator(self, cmd: OperatorCommand) -> str:
        """Carry out one request; the reason when it is refused, "" when done."""
        action = cmd.action
        if action in ("rtk_start", "rtk_stop", "logging_on", "logging_off") and action in OPERATOR_ACTIONS:
            return ""  # handled by the GNSS driver / simulated receiver and the recorder
        why = self.why_not(action)
        prearm = self.prearm_failures(action) if action in PREARM_ACTIONS and not self.mode.human_in_control \
            else []
        if why:
            self._refuse(action, why, **({"prearm_failed": [f.id for f in prearm]} if prearm else {}))
            return why
        t = self.ctx.now()
        by = f"requested by {cmd.source}"
        if prearm:  # accepted with failing checks: only the expert override does that
            self._log_override(action, by, prearm)
        if action == "estop":
            self.set_mode(self.modes[ModeName.ESTOP], f"emergency stop by {cmd.source}")
            self.alert("critical", "estop", f"emergency stop by {cmd.source}")
        elif action == "reset_estop":
            self.set_mode(self.modes[ModeName.MANUAL], "emergency stop reset (disarmed)")
            self.alert("info", "estop", "emergency stop reset", active=False)
        elif action == "arm":
            self.armed = True
            self.ctx.log("info", f"armed ({by})")
        elif action == "disarm":
            self.armed = False
            if self.mode.name != ModeName.MANUAL:
                self.set_mode(self.modes[ModeName.MANUAL], f"disarmed ({by})")
            self.ctx.log("info", f"disarmed ({by})")
        elif action == "manual":
            self.set_mode(self.modes[ModeName.MANUAL], by)
        elif action == "hold":
            self.enter_hold(t, by)
        elif action == "auto":
            self.start_following(self.path, ModeName.AUTO, by,
                                 resume=self.active_path is self.path and self.mode.name == ModeName.HOLD)
        elif action == "return":
            self.start_return(t, by)
        elif action in ("calibrate_mag", "experiment"):
            self.set_mode(self.modes[REQUESTED_MODE[action]], by)
        elif action in ("mag_accept", "mag_reject") and self.mag_review is not None:
            decision = "accepted" if action == "mag_accept" else "rejected"
            if decision == "rejected":
                self.heading_calibration = self._heading_calibration_before
            self.ctx.log("info", f"magnetometer calibration {decision} ({by})")
            self.ctx.publish(Topic.MAG_CALIBRATION, replace(self.mag_review, stamp_s=t, decision=decision))
            self.mag_review = None
        self._publish_status()
        return ""

    def _refuse(self, action: str, why: str, **data: Any) -> None:
        self.counters["refused_requests"] += 1
        self.ctx.log("warning", f"request refused: {action}: {why}", refused=action, **data)
        self.alert("warning", f"refused:{action}", f"{action} refused: {why}")

    # ------------------------------------------------------------------ pre-arm checks
    def prearm_inputs(self) -> PrearmInputs:
        i, t = self.inputs, self.ctx.now()
        route, path, corridor = self._corridor
        if route is not self.route or path is not self.path:
            corridor = route_corridor_m(self.route, self.path)
            self._corridor = (self.route, self.path, corridor)
        return PrearmInputs(now_s=t, escs_armed=i.escs_armed, state=i.state, position_usable=self.position_ok(),
                            heading_usable=self._heading_ok(), health=i.health, fix=i.fix,
                            heading_calibration=self.heading_calibration, battery=i.battery, route=self.route,
                            path=self.path, corridor_m=corridor, link=i.link, link_age_s=t - i.link_arrival_s,
                            rc=i.rc, storage=storage_problem(i, t, self.config.failsafes))

    def prearm_failures(self, action: str) -> list[FailedCheck]:
        """The failed pre-arm checks of `action` (arm, auto); prearm_skip as in prearm.prearm_failures."""
        return prearm_failures(action, self.prearm_inputs(), self.config.failsafes)

    def _log_override(self, action: str, by: str, failed: list[FailedCheck]) -> None:
        text = f"pre-arm checks overridden for {action} (prearm_override, {by}): {describe(failed)}"
        self.ctx.log("warning", text, prearm_overridden=[f.id for f in failed], action=action)
        self.alert("warning", f"prearm_override:{action}", text)

    def alert(self, severity: str, code: str, text: str, active: bool = True) -> None:
        self.ctx.publish(Topic.ALERT, Alert(stamp_s=self.ctx.now(), severity=severity, code=code, text=text,
                                            active=active))

    # ------------------------------------------------------------------ mode changes
    def set_mode(self, mode: Mode, reason: str) -> None:
        t = self.ctx.now()
        if mode is not self.mode or reason != self.reason:
            self.ctx.log("warning" if mode.name == ModeName.ESTOP else "info",
                         f"mode {self.mode.name} -> {mode.name}: {reason}", mode=mode.name)
        if mode is not self.mode:
            self.mode.exit(self, t)
            self.mode = mode
            mode.enter(self, t)
        if mode.name != ModeName.MANUAL:
            self.stopped = ""
        self.reason = reason
        self._publish_status()

    def enter_hold(self, t: float, reason: str, target: HoldTarget | None = None) -> None:
        s = self.inputs.state
        if target is None:
            if s is None or not _finite_state(s):
                self.stop(f"{reason} (no position to hold)")
                return
            target = HoldTarget(s.north_m, s.east_m, s.heading_rad)
        hold: Hold = self.modes[ModeName.HOLD]  # type: ignore[assignment]
        hold.target = target
        if self.mode is hold:
            self.station_keeper.reset()
        self.set_mode(hold, reason)

    def stop(self, reason: str) -> None:
        self.stopped = reason
        self.set_mode(self.modes[ModeName.MANUAL], f"stopped: {reason}")

    def start_following(self, path: Any, mode_name: ModeName, reason: str, resume: bool = False) -> None:
        if not resume:
            self.follower.reset(path)
            # a new path gives the configured controller a new chance: its failsafe (and the
            # fallback) end here, the history stays in the log
            self.fallback = None
            self._flag("controller", False, "", "info")
        self.active_path = path
        self._time_to_end = _time_to_end(path)
        self.controller_monitor.reset()
        self.set_mode(self.modes[mode_name], reason)

    def start_return(self, t: float, reason: str) -> None:
        s = self.inputs.state
        if self.route is None or s is None:
            self.enter_hold(t, f"{reason}: no route/harbour known, holding instead")
            return
        try:
            path = plan_return_route(self.return_route(), s.north_m, s.east_m, s.heading_rad, self.config.planner)
        except LotsenError as exc:
            self.ctx.log("error", f"return to harbour cannot be planned: {exc}")
            self.alert("error", "return", f"return to harbour cannot be planned: {exc}")
            self.enter_hold(t, f"{reason}: return not plannable, holding instead")
            return
        self.ctx.publish(Topic.PATH, path_message(t, path, self.config.path_message_points))
        self.start_following(path, ModeName.RETURN, reason)

    def publish_calibration(self, result: MagCalibrationResult) -> None:
        """A fresh fit is used at once (the estimator applies it) and waits for the operator's
        mag_accept / mag_reject; a rejection brings back the calibration in use before it."""
        self.ctx.publish(Topic.MAG_CALIBRATION, result)
        if result.ok:
            if self.mag_review is None:
                self._heading_calibration_before = self.heading_calibration
            self.mag_review = result
            self.heading_calibration = f"the turn manoeuvre at {self.ctx.now():.0f} s"
        self.ctx.log("info" if result.ok else "warning", f"magnetometer calibration: {result.text}")
        if not result.ok:
            self.alert("warning", "calibration", f"magnetometer calibration failed: {result.text}")
        else:
            self.alert("info", "calibration", "magnetometer calibrated", active=False)

    # ------------------------------------------------------------------ the control tick
    def _tick(self) -> None:
        t = self.ctx.now()
        self._check_failsafes(t)
        cmd, status = self._command(t)
        self.send_command(t, cmd)
        if status is not None:
            self.last_status = status
            self.ctx.publish(Topic.CONTROL_STATUS, status)
        self._publish_status()
        if self.mode.moving and t - self._last_progress_s >= 1.0 / self.config.progress_rate_hz:
            self._publish_progress(t, status)

    def send_command(self, t: float, cmd: ThrustCommand) -> None:
        """The one place a ship_command leaves the supervisor."""
        if not cmd.is_finite():
            self.counters["non_finite_commands"] += 1
            self.ctx.log("error", "non-finite thrust command replaced by neutral", mode=self.mode.name)
            cmd = neutral(t, "supervisor:non-finite")
        self.ctx.publish(Topic.SHIP_COMMAND, cmd)
        self.thruster.on_command(cmd, t, self.inputs.escs_armed)

    def _command(self, t: float) -> tuple[ThrustCommand, ControllerStatus | None]:
        mode = self.mode
        if mode.requires_armed and not self.armed:  # cannot happen by a request; a safety net
            return neutral(t, "disarmed"), None
        if mode.requires_position or mode.requires_heading:
            s = self.inputs.state
            if s is None or not _finite_state(s):
                self.stop("no finite state estimate")
                return neutral(t, "supervisor"), None
        return mode.update(self, t)

    # ------------------------------------------------------------------ failsafes
    def _flag(self, mon_name: str, on: bool, reason: str, severity: str, realert: bool = False) -> bool:
        before = self.failsafes.active.get(mon_name)
        became_on, became_off = self.failsafes.set(mon_name, on, reason)
        # what is wrong changed in kind (its first words; not a figure that counts down)
        if realert and on and not became_on and before is not None and before[:16] != reason[:16]:
            self.ctx.log("warning", f"failsafe {mon_name}: {reason}", failsafe=mon_name)
            self.alert(severity, f"failsafe:{mon_name}", f"{mon_name}: {reason}")
        if became_on:
            self.failsafe_history.append(f"{mon_name}: {reason} at {self.ctx.now():.2f} s")
            self.ctx.log("warning", f"failsafe {mon_name}: {reason}", failsafe=mon_name)
            self.alert(severity, f"failsafe:{mon_name}", f"{mon_name}: {reason}")
        elif became_off:
            self.ctx.log("info", f"failsafe {mon_name} cleared", failsafe=mon_name)
            self.alert("info", f"failsafe:{mon_name}", f"{mon_name} cleared", active=False)
        return became_on

    def position_ok(self) -> bool:
        return self.inputs.position_trusted(self.config.failsafes.max_position_std_m)

    def _heading_ok(self) -> bool:
        s = self.inputs.state
        if s is None or not math.isfinite(s.heading_rad):
            return False
        h = self.inputs.health
        return h is None or bool(h.heading_ok)

    def _check_failsafes(self, t: float) -> None:
        if self.progress_monitor.idle(t):  # not following a route: no progress to miss
            self._flag(ProgressMonitor.name, False, "", ProgressMonitor.severity)
        for mon in self.monitors:
            active = mon.update(self.inputs, t)
            if self._flag(mon.name, active, mon.reason, mon.severity, mon.realert_on_change) or \
                    (active and mon.acts_while_active):
                self._act(t, mon, mon.action_for(self.mode))

    def _act(self, t: float, mon: Monitor, action: FailsafeAction) -> None:
        why = f"failsafe {mon.name}: {mon.reason}"
        if action is FailsafeAction.CONTINUE or self.mode.human_in_control:
            return
        if action is FailsafeAction.HOLD:
            if self.mode.name != ModeName.HOLD:
                self.enter_hold(t, f"{why} (holding{' on dead reckoning' if mon.name in DEAD_RECKONING else ''})")
        elif action is FailsafeAction.HOLD_INSIDE:
            # once: then the boat holds at the point inside until the operator decides
            if self.armed and self.reason != GEOFENCE_HOLD_REASON:
                self.enter_hold(t, GEOFENCE_HOLD_REASON, HoldTarget(*self.geofence.hold_target(self.inputs)))
        elif action is FailsafeAction.STOP:
            self.stop(why)
        elif action is FailsafeAction.RETURN:
            self.start_return(t, why)
        elif action is FailsafeAction.FALLBACK:
            fallback = self.config.failsafes.fallback_controller
            if self.fallback is None:
                self.counters["controller_fallbacks"] += 1
                self._flag(mon.name, True, f"{self.follower.name}: {mon.reason}; fallback {fallback}", mon.severity)
                self.fallback = self._make_follower(fallback)
                # take over where the boat is: from 0 the fallback would re-localise from the start
                # of the path (metres of false cross-track error, a wrong branch of a figure eight)
                self.fallback.reset(self.active_path, progress_m=self.follower.progress_m)
            else:
                self._flag(mon.name, True, f"fallback {self.fallback.name} failed too: {mon.reason}", mon.severity)
                self.stop("failsafe: controller and fallback failed")

    def watch_controller(self, t: float, status: ControllerStatus, solve_ms: float) -> None:
        """After each path-follower update: the progress monitor (a warning) and the controller monitor
        (which may act) judge it."""
        stalled, stall_why = self.progress_monitor.observe(t, status.progress_m, status.speed_ref_mps)
        self._flag(ProgressMonitor.name, stalled, stall_why, ProgressMonitor.severity)
        mon = self.controller_monitor
        why = mon.observe(status.status, solve_ms)
        if why:
            mon.reason = why
            self._act(t, mon, mon.action_for(self.mode))

    # ------------------------------------------------------------------ status
    def _publish_status(self) -> None:
        warnings = tuple(f"{k}: {v}" for k, v in self.failsafes.active.items())
        if self.stopped:
            warnings = (f"stopped: {self.stopped}",) + warnings
        available, blocked = [], []
        for action in OPERATOR_ACTIONS:
            why = self.why_not(action)
            if why:
                blocked.append(f"{action}: {why}")
            else:
                available.append(action)
        self.ctx.publish(Topic.SUPERVISOR, SupervisorStatus(
            stamp_s=self.ctx.now(), mode=str(self.mode.name), reason=self.reason, armed=self.armed, warnings=warnings,
            active_failsafes=tuple(self.failsafes.active), escs_armed=self.inputs.escs_armed,
            available_actions=tuple(available), blocked_actions=tuple(blocked), route_id=self.route_id))

    def _publish_progress(self, t: float, status: ControllerStatus | None) -> None:
        path = self.active_path
        if path is None or status is None or not math.isfinite(status.progress_m):
            return
        self._last_progress_s = t
        s = min(max(status.progress_m, 0.0), path.length_m)
        eta = float(np.interp(s, path.s_m, self._time_to_end)) if self._time_to_end is not None else math.nan
        next_node, dist = -1, math.nan
        if self.mode.name == ModeName.AUTO and path is self.path:
            for k, sk in enumerate(self.node_s):
                if sk > s + 0.05:
                    next_node, dist = k - 1, sk - s  # planner node k is route node k - 1 (harbour first)
                    break
        self.ctx.publish(Topic.PROGRESS, MissionProgress(
            stamp_s=t, mode=str(self.mode.name), path_length_m=round(path.length_m, 3), progress_m=round(s, 3),
            remaining_m=round(path.length_m - s, 3), eta_s=round(eta, 1), next_node=next_node,
            distance_to_next_node_m=round(dist, 3) if math.isfinite(dist) else math.nan,
            route_id=self.route_id if path is self.path else ""))


@dataclass(frozen=True)
class CheckedRoute:
    """A received route made ready to fly: parsed, its path built and inside the navigable water."""

    route: Any  # lotsen.planning.Route
    path: Any  # lotsen.planning.Path
    corridor_m: float  # prearm.route_corridor_m: the smallest distance from the path to the shore


def check_planned_route(msg: PlannedRoute, fence: Any, tolerance_m: float) -> CheckedRoute:
    """The supervisor's check of a received route (pure; LotsenError says why it is refused): it
    parses, its arrays are a path, and the path lies in the route's navigable water (the planner's
    promise, checked) and in the boat's own (`fence`), whatever area the route itself declares: a
    page that cleared or widened the area cannot send the boat beyond the configured one."""
    route = route_from_dict(msg.route)
    path = path_from_message(msg)
    check_path_inside(route, path, tolerance_m)
    check_path_inside(fence, path, tolerance_m, "of the boat (its launch config)")
    return CheckedRoute(route, path, route_corridor_m(route, path))


def check_path_inside(route: Any, path: Any, tolerance_m: float, whose: str = "of the route") -> None:
    """LotsenError when `path` leaves `route`'s navigable water by more than `tolerance_m`."""
    if route is None or (route.area is None and not route.obstacles):
        return
    free = route.free_region().buffer(tolerance_m)
    step = max(1, len(path) // 2000)
    inside = contains_xy(free, path.north_m[::step], path.east_m[::step])
    if not np.all(inside):
        i = int(np.argmin(inside)) * step
        d = free.distance(Point(path.north_m[i], path.east_m[i]))
        raise LotsenError(f"route: the path leaves the navigable area {whose} at ({path.north_m[i]:.1f}, "
                          f"{path.east_m[i]:.1f}) m ({d:.1f} m outside); the boat keeps the route it held")


def _with_controller(config: Any, name: str) -> Any:
    from dataclasses import replace

    return replace(config, controller=name)


def _clip1(v: float) -> float:
    return min(max(float(v), -1.0), 1.0)


def _time_to_end(path: Any, min_speed_mps: float = 0.05) -> np.ndarray:
    """Planned seconds from each path point to the end (at the planned speeds)."""
    v = np.maximum(np.asarray(path.speed_mps, dtype=float), min_speed_mps)
    dt = np.diff(np.asarray(path.s_m, dtype=float)) / (0.5 * (v[1:] + v[:-1]))
    return np.concatenate([np.cumsum(dt[::-1])[::-1], [0.0]])


def path_message(t: float, path: Any, max_points: int) -> PathMessage:
    n = len(path.s_m)
    step = max(1, math.ceil(n / max_points))
    idx = list(range(0, n, step))
    if idx[-1] != n - 1:
        idx.append(n - 1)
    return PathMessage(stamp_s=t, north_m=tuple(float(path.north_m[i]) for i in idx),
                       east_m=tuple(float(path.east_m[i]) for i in idx),
                       speed_mps=tuple(float(path.speed_mps[i]) for i in idx))

