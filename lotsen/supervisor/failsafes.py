"""Failsafes as monitor objects (docs/failsafes.md has the table).

Each monitor watches one condition of the supervisor's inputs and says, every control tick,
whether it holds and why. A `PersistentCondition` turns that into a failsafe: the condition must
hold for `persist_s` before the failsafe triggers and be clear for `clear_s` before it releases
(hysteresis), so one bad sample neither triggers nor releases one. When a failsafe triggers, the
supervisor logs it, raises an `Alert` for the operator and runs its action for the current mode
(`action_for(mode)`, a `FailsafeAction`: continue, hold, hold inside the area, stop, return,
fallback controller). The monitors ask the mode object what it is (fenced, needs a heading, a
human in control), never compare its name.

Monitors are pure: they get the inputs and the time, never read a clock.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Any, Literal

from shapely.geometry import Point
from shapely.ops import nearest_points

from lotsen.messages import ActuatorState, GnssFixType, ModeName, RpmSample, ThrustCommand
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.model.actuators import advance_motors
from lotsen.settings import value_range as _r

if TYPE_CHECKING:  # monitors only read the inputs and ask the mode what it is; the web server and
    # the launcher import this module for FailsafeConfig without the controllers the modes run
    from lotsen.supervisor.inputs import SupervisorInputs
    from lotsen.supervisor.modes import Mode


class FailsafeAction(StrEnum):
    """What a triggered failsafe does in the current mode (docs/failsafes.md)."""

    CONTINUE = "continue"  # reported only
    HOLD = "hold"  # station keeping where the boat is (on dead reckoning when the position is lost)
    HOLD_INSIDE = "hold_inside"  # station keeping at the nearest point inside the navigable area
    STOP = "stop"  # MANUAL, thrusters neutral, the reason shown
    RETURN = "return"  # plan to the harbour and follow it
    FALLBACK = "fallback"  # the fallback path follower; stop when that fails too


FOLLOWING = (ModeName.AUTO, ModeName.RETURN)  # the modes that follow a path
UNDER_WAY = FOLLOWING + (ModeName.EXPERIMENT,)  # the modes in which the boat moves by itself
#: pre-arm checks an expert may skip (lotsen.supervisor.prearm; the ESCs are always checked)
SkippablePrearmCheck = Literal["battery", "position", "gnss", "heading", "route", "pilot_link", "storage"]


@dataclass(frozen=True)
class FailsafeConfig:
    """Thresholds and actions of every failsafe (all times in seconds)."""

    # operator link (the web pilot): MANUAL always stops; AUTO/RETURN continue or hold
    link_timeout_s: float = field(default=1.5, metadata=_r(0.2, 60.0))
    link_lost_auto_action: Literal["continue", "hold"] = "continue"
    # manual driving: a ManualCommand older than this is treated as zero
    manual_timeout_s: float = field(default=0.5, metadata=_r(0.1, 5.0))
    # GNSS: no usable fix for gnss_lost_s -> hold on dead reckoning, then stop after gnss_stop_after_s
    gnss_lost_s: float = field(default=1.5, metadata=_r(0.2, 60.0))
    gnss_lost_action: Literal["hold", "stop"] = "hold"
    gnss_stop_after_s: float = field(default=20.0, metadata=_r(1.0, 600.0))
    # RTK degraded: fix type below gnss_min_fix for gnss_degraded_s
    gnss_min_fix: Literal["RTK_FIXED", "RTK_FLOAT", "FIX_3D"] = "RTK_FLOAT"
    gnss_degraded_s: float = field(default=2.0, metadata=_r(0.2, 60.0))
    gnss_degraded_action: Literal["hold", "stop", "continue"] = "hold"
    # state estimator integrity (lotsen.fusion health): position not trustworthy -> hold on dead
    # reckoning (as GNSS lost), then stop after gnss_stop_after_s; heading not trustworthy -> stop
    estimator_persist_s: float = field(default=0.3, metadata=_r(0.0, 10.0))
    estimator_position_action: Literal["hold", "stop"] = "hold"
    # geofence: estimated position outside the navigable area by more than geofence_margin_m
    geofence_margin_m: float = field(default=0.0, metadata=_r(0.0, 20.0))
    geofence_persist_s: float = field(default=0.3, metadata=_r(0.0, 10.0))
    geofence_inset_m: float = field(default=1.5, metadata=_r(0.1, 20.0))  # hold this far inside
    geofence_in_manual: bool = False
    # battery (3S LiPo): low -> return to harbour, critical -> stop
    battery_low_v: float = field(default=10.8, metadata=_r(0.0, 60.0))
    battery_critical_v: float = field(default=10.2, metadata=_r(0.0, 60.0))
    battery_persist_s: float = field(default=5.0, metadata=_r(0.0, 120.0))
    # controller: failure or overrun -> fallback controller, then stop
    controller_overrun_factor: float = field(default=0.8, metadata=_r(0.1, 10.0))  # x control period
    controller_overrun_count: int = field(default=5, metadata=_r(1, 1000))
    controller_failure_count: int = field(default=3, metadata=_r(1, 1000))
    fallback_controller: Literal["los", "pursuit", "lq"] = "los"
    # no progress: while following a route, less than no_progress_fraction of the distance along it
    # that the reference speed asked for over the last no_progress_window_s -> a warning, no action
    # (a boat held by a strong current, a stalled start, a fouled propeller: the operator decides)
    no_progress_window_s: float = field(default=30.0, metadata=_r(5.0, 600.0))
    no_progress_fraction: float = field(default=0.25, metadata=_r(0.0, 1.0))
    # thruster: the tachometer disagrees with the modelled response to the commands (ESC lag, ramp
    # and arming included) by more than this fraction of the modelled speed and more than
    # thruster_mismatch_min_rps (tachometer quantisation, the speed loop's own error)
    thruster_mismatch_frac: float = field(default=0.5, metadata=_r(0.05, 1.0))
    thruster_mismatch_min_rps: float = field(default=8.0, metadata=_r(0.0, 100.0))
    thruster_persist_s: float = field(default=0.5, metadata=_r(0.1, 30.0))
    # a command reaches the ESCs up to this late (bus, driver, PWM period): the tachometer may show
    # the modelled response of any moment in the last thruster_latency_s
    thruster_latency_s: float = field(default=0.15, metadata=_r(0.0, 2.0))
    thruster_fault_action: Literal["hold", "stop", "continue"] = "hold"
    # state estimate: uncertainty above this (position std, m) counts as no position
    max_position_std_m: float = field(default=2.0, metadata=_r(0.01, 100.0))
    # pre-arm checks before arm and AUTO (lotsen.supervisor.prearm, docs/failsafes.md): the
    # position accuracy needed is the smaller of prearm_max_position_accuracy_m and
    # prearm_corridor_fraction x the path's clearance to non-navigable water
    prearm_corridor_fraction: float = field(default=0.25, metadata=_r(0.05, 1.0))
    prearm_max_position_accuracy_m: float = field(default=1.0, metadata=_r(0.01, 10.0))
    prearm_max_heading_std_deg: float = field(default=5.0, metadata=_r(0.1, 90.0))
    prearm_battery_reserve_frac: float = field(default=0.25, metadata=_r(0.0, 1.0))  # the return reserve
    # checks not run at all (e.g. pilot_link in a headless simulation nobody watches)
    prearm_skip: tuple[SkippablePrearmCheck, ...] = ()
    # expert override: failed checks that can be overridden are logged and alerted, not refused
    prearm_override: bool = False
    # storage: the recorder's disk (its RecorderStatus) with less free space than this, a write
    # failure, or a recorder silent for storage_silent_s: an alert, and a failed pre-arm check
    storage_min_free_mb: float = field(default=50.0, metadata=_r(0.0, 1e6))
    storage_silent_s: float = field(default=5.0, metadata=_r(1.0, 600.0))
    # RC receiver: no rc/override for this long counts as a lost RC link (the driver itself
    # reports a lost link after its lost_after_s); while the RC has control: neutral
    rc_timeout_s: float = field(default=0.3, metadata=_r(0.1, 0.4))
    # minimum depth (the echosounder's depth under its transducer): shallower for min_depth_persist_s
    # -> hold where the boat is; 0 = off. Pings older than min_depth_max_age_s do not count
    min_depth_m: float = field(default=0.0, metadata=_r(0.0, 100.0))
    min_depth_persist_s: float = field(default=0.5, metadata=_r(0.0, 30.0))
    min_depth_max_age_s: float = field(default=2.0, metadata=_r(0.2, 60.0))
    min_depth_action: Literal["hold", "stop", "continue"] = "hold"

    @property
    def min_fix_type(self) -> GnssFixType:
        return GnssFixType[self.gnss_min_fix]


class PersistentCondition:
    """True once `condition` has held for persist_s; false again after it is clear for clear_s."""

    def __init__(self, persist_s: float, clear_s: float | None = None) -> None:
        self.persist_s = persist_s
        self.clear_s = persist_s if clear_s is None else clear_s
        self.active = False
        self._since: float | None = None  # when the raw condition last changed towards the other state
        self.activations = 0

    def update(self, condition: bool, t: float) -> bool:
        if condition != self.active:
            if self._since is None:
                self._since = t
            if t - self._since >= (self.persist_s if condition else self.clear_s):
                self.active = condition
                self._since = None
                if condition:
                    self.activations += 1
        else:
            self._since = None
        return self.active


@dataclass
class FailsafeState:
    """The currently active failsafes with their reasons, for the status message and the log."""

    active: dict[str, str] = field(default_factory=dict)

    def set(self, name: str, on: bool, reason: str = "") -> tuple[bool, bool]:
        """Returns (became_active, became_inactive)."""
        was = name in self.active
        if on:
            self.active[name] = reason
        else:
            self.active.pop(name, None)
        return (on and not was, was and not on)


# ------------------------------------------------------------------------------------------------
# monitors
# ------------------------------------------------------------------------------------------------
class Monitor:
    """One failsafe: `check(inputs, t) -> (condition, reason)`, persistence, severity, actions.

    `actions` maps a mode to the action taken when the failsafe triggers in that mode; modes not
    listed: the failsafe is reported and nothing else happens. `acts_while_active`: the action is
    taken on every tick the failsafe is active (the mode may change under it), not only when it
    triggers."""

    name = "monitor"
    severity = "warning"
    acts_while_active = False
    # the alert is raised again when the reason changes while the failsafe is active: the storage
    # check's "low on space" that becomes "the write failed" (not for reasons that count seconds)
    realert_on_change = False

    def __init__(self, persist_s: float, clear_s: float, actions: dict[ModeName, FailsafeAction]) -> None:
        self.condition = PersistentCondition(persist_s, clear_s)
        self.actions = actions
        self.reason = ""

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        raise NotImplementedError

    def update(self, inputs: "SupervisorInputs", t: float) -> bool:
        raw, reason = self.check(inputs, t)
        if raw and reason:
            self.reason = reason  # the reason of the condition as it began, kept while it lasts
        return self.condition.update(raw, t)

    @property
    def active(self) -> bool:
        return self.condition.active

    def action_for(self, mode: "Mode") -> FailsafeAction:
        return self.actions.get(mode.name, FailsafeAction.CONTINUE)


def _in(modes: tuple[ModeName, ...], action: str | FailsafeAction) -> dict[ModeName, FailsafeAction]:
    """`action` (a config value such as "hold") in each of `modes`; "continue": no action at all."""
    act = FailsafeAction(action)
    return {} if act is FailsafeAction.CONTINUE else {m: act for m in modes}


class LinkMonitor(Monitor):
    """The operator's link, once a pilot has been seen: silent for link_timeout_s, or gone."""

    name = "link_lost"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(0.0, 0.0, _in(UNDER_WAY, cfg.link_lost_auto_action))
        self.timeout_s = cfg.link_timeout_s

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        if inputs.link is None:
            return False, ""
        age = t - inputs.link_arrival_s
        if age > self.timeout_s:
            return True, f"no word from the operator's page for {age:.1f} s"
        if not inputs.link.pilot_connected:
            return True, "the pilot left (page closed or silent)"
        return False, ""


class RcLinkMonitor(Monitor):
    """The RC receiver, once heard: its link lost or in failsafe, or the driver silent for
    rc_timeout_s. No action of its own: the RC mode commands neutral without a good link, and
    in the other modes the boat goes on (the RC is the pilot's backup)."""

    name = "rc_lost"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(0.0, 0.5, {})
        self.timeout_s = cfg.rc_timeout_s

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        rc = inputs.rc
        if rc is None:
            return False, ""
        age = t - inputs.rc_arrival_s
        if age > self.timeout_s:
            return True, f"no word from the RC receiver for {age:.1f} s"
        if rc.link == "failsafe":
            return True, "RC receiver in failsafe (transmitter off or out of range)"
        if rc.link != "ok":
            return True, "RC link lost: no good frames (transmitter off or out of range, or the receiver unplugged)"
        return False, ""


class GnssLostMonitor(Monitor):
    """No usable fix for gnss_lost_s (once one was seen): hold on dead reckoning, stop later."""

    name = "gnss_lost"
    severity = "error"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(0.0, 1.0, _in(UNDER_WAY + (ModeName.CALIBRATE,), cfg.gnss_lost_action))
        self.lost_s = cfg.gnss_lost_s

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        if inputs.last_usable_fix_s is None:
            return False, ""
        age = t - inputs.last_usable_fix_s
        return age > self.lost_s, f"no usable GNSS fix for {age:.1f} s"


class GnssDegradedMonitor(Monitor):
    """The fix type below the configured minimum (RTK float or fixed) for gnss_degraded_s."""

    name = "gnss_degraded"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(cfg.gnss_degraded_s, 2.0, _in(UNDER_WAY, cfg.gnss_degraded_action))
        self.min_fix = cfg.min_fix_type

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        fix = inputs.fix
        if fix is None or not fix.usable or fix.fix_type >= self.min_fix:
            return False, ""
        return True, f"GNSS fix {GnssFixType(fix.fix_type).name}, needs {self.min_fix.name} or better"


class EstimatorMonitor(Monitor):
    """The state estimator declared its position (or heading) untrustworthy (lotsen.fusion's
    integrity monitors: GNSS inconsistent, sensors stuck, estimate frozen, inputs starved)."""

    name = "estimator"
    severity = "error"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(cfg.estimator_persist_s, 2.0,
                         {**_in(UNDER_WAY, cfg.estimator_position_action), ModeName.CALIBRATE: FailsafeAction.STOP})
        self.heading_bad = False

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        h = inputs.health
        if h is None:
            return False, ""
        self.heading_bad = not h.heading_ok
        bad = not (h.position_ok and h.heading_ok)
        what = ", ".join(x for x, ok in (("position", h.position_ok), ("heading", h.heading_ok)) if not ok)
        return bad, f"estimate not trustworthy ({what}): " + "; ".join(h.faults[:3])

    def action_for(self, mode: "Mode") -> FailsafeAction:
        if self.heading_bad and mode.requires_heading:
            return FailsafeAction.STOP  # without a heading neither following nor holding works
        return super().action_for(mode)


class ThrusterMonitor(Monitor):
    """Tachometers against the modelled response of the ESCs to what was commanded.

    The model is the simulator's actuator model (first-order motor with its time constant and
    ramp limit; zero while the ESCs are not armed), driven by the commands as they were sent and
    stepped to each tachometer sample. A failed ESC, a fouled or lost propeller or a broken
    tachometer shows as a persistent disagreement; a propeller that is still spinning up after a
    commanded reversal does not. Two conditions, either declares the fault:

    * sample by sample: every tachometer sample for thruster_persist_s off the band of modelled
      speeds (over the latency window) by more than the tolerance;
    * on average: over the last 2 x thruster_persist_s the propeller turned at less than a quarter
      of the modelled mean speed while that mean is above thruster_mismatch_min_rps (a stopped
      motor). In a turn the MPC drives a propeller in short pulses around zero: between the
      pulses a stopped motor and a running one read alike, so the sample-by-sample persistence
      restarts at every pulse and declares a dead motor late or never; the mean does not.
    """

    name = "thruster"
    severity = "error"
    _NAMES = ("azimuth 1", "azimuth 2", "bow")
    _STOPPED_FRACTION = 0.25

    def __init__(self, cfg: FailsafeConfig, limits: ActuatorLimits = DEFAULT_LIMITS) -> None:
        # the persistence is in the two conditions (per sample, over the mean window), not the timer's
        super().__init__(0.0, 2.0, _in(UNDER_WAY, cfg.thruster_fault_action))
        self.limits = limits
        self.frac = cfg.thruster_mismatch_frac
        self.min_rps = cfg.thruster_mismatch_min_rps
        self.window_s = 2.0 * cfg.thruster_persist_s
        self.model_n = [0.0, 0.0, 0.0]
        self.latency_s = cfg.thruster_latency_s
        self._history: deque[tuple[float, list[float]]] = deque()  # (t, model_n) over the latency window
        self._t: float | None = None
        self._cmd = (0.0, 0.0, 0.0)
        self._off = PersistentCondition(cfg.thruster_persist_s, 0.0)  # on the latest sample, at the control ticks
        self._speeds: list[deque[tuple[float, float, float]]] = [deque() for _ in range(3)]  # (t, |meas|, |model|)
        self.mismatch = ""  # the latest sample off the band (propellers and speeds)
        self.stopped = ""  # a propeller stopped on average over the window

    def on_command(self, cmd: ThrustCommand, t: float, escs_armed: bool) -> None:
        """A command leaving the supervisor at t: advance the model to t with the previous one."""
        self._advance(t)
        self._cmd = (cmd.n1_rps, cmd.n2_rps, cmd.nt_rps) if escs_armed else (0.0, 0.0, 0.0)
        self._cmd = tuple(self.limits.clip(0.0, 0.0, *self._cmd)[2:])

    def _advance(self, t: float) -> None:
        if self._t is None:
            self._t = t
            return
        dt = t - self._t
        if dt <= 0.0:
            return
        self.model_n = list(advance_motors(self.model_n, self._cmd, dt, self.limits))
        self._t = t
        self._history.append((t, self.model_n))
        while len(self._history) > 1 and self._history[1][0] <= t - self.latency_s:
            self._history.popleft()

    def expected_band(self, j: int) -> tuple[float, float]:
        """The range of modelled speeds of propeller j over the latency window."""
        values = [n[j] for _, n in self._history] or [self.model_n[j]]
        return min(values), max(values)

    def on_rpm(self, msg: RpmSample, actuators: ActuatorState | None) -> None:
        t = msg.stamp_s
        self._advance(t)
        bad, stopped = [], []
        for j, meas in enumerate((msg.n1_rps, msg.n2_rps, msg.nt_rps)):
            if not math.isfinite(meas):
                continue
            lo, hi = self.expected_band(j)
            want = self.model_n[j]
            off = lo - meas if meas < lo else meas - hi if meas > hi else 0.0
            if off > max(self.frac * abs(want), self.min_rps):
                bad.append(f"{self._NAMES[j]} {meas:.0f} rev/s, expected {want:.0f}")
            speeds = self._speeds[j]
            speeds.append((t, abs(meas), abs(want)))
            while speeds[0][0] < t - self.window_s:
                speeds.popleft()
            if t - speeds[0][0] >= self.window_s - 0.06:  # a full window (tachometers at 20 Hz or faster)
                mean_meas = sum(s[1] for s in speeds) / len(speeds)
                mean_model = sum(s[2] for s in speeds) / len(speeds)
                if mean_model > self.min_rps and mean_meas < self._STOPPED_FRACTION * mean_model:
                    stopped.append(f"{self._NAMES[j]} {mean_meas:.0f} rev/s on average over {self.window_s:g} s, "
                                   f"expected {mean_model:.0f}")
        self.mismatch = "; ".join(bad)
        self.stopped = "; ".join(stopped)

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        if self._off.update(bool(self.mismatch), t):
            return True, self.mismatch or self.stopped
        return bool(self.stopped), self.stopped


class BatteryMonitor(Monitor):
    """Pack voltage below a threshold for battery_persist_s."""

    def __init__(self, name: str, threshold_v: float, persist_s: float,
                 actions: dict[ModeName, FailsafeAction], severity: str) -> None:
        super().__init__(persist_s, 10.0, actions)
        self.name = name
        self.severity = severity
        self.threshold_v = threshold_v

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        v = inputs.battery.voltage_v if inputs.battery is not None else math.nan
        return (math.isfinite(v) and v < self.threshold_v), f"battery {v:.2f} V below {self.threshold_v} V"


class DeadReckoningMonitor(Monitor):
    """Dead reckoning (GNSS lost, or the estimate's position not trusted) for longer than
    gnss_stop_after_s while the boat holds or follows a path: stop. Reads the monitors it follows
    up on (updated before it in the same tick)."""

    name = "dead_reckoning"
    severity = "error"
    acts_while_active = True  # also when HOLD is entered after the time is up

    def __init__(self, cfg: FailsafeConfig, sources: list[Monitor]) -> None:
        super().__init__(cfg.gnss_stop_after_s, 0.0, _in(UNDER_WAY + (ModeName.HOLD,), FailsafeAction.STOP))
        self.sources = sources
        self.stop_after_s = cfg.gnss_stop_after_s

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        return (any(m.active for m in self.sources),
                f"no trustworthy position for more than {self.stop_after_s:.0f} s")


class GeofenceMonitor(Monitor):
    """The estimated position outside the navigable water (by more than geofence_margin_m) for
    geofence_persist_s, in a fenced mode (or MANUAL with geofence_in_manual): hold at the nearest
    point geofence_inset_m inside. Judged on a trustworthy estimate only: a position the integrity
    monitor declared bad is the estimator failsafe's to act on."""

    name = "geofence"
    severity = "error"
    acts_while_active = True  # also when the boat was already outside on entering the mode

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(cfg.geofence_persist_s, 2.0, {})
        self.margin_m = cfg.geofence_margin_m
        self.inset_m = cfg.geofence_inset_m
        self.in_manual = cfg.geofence_in_manual
        self.max_position_std_m = cfg.max_position_std_m
        self._regions: tuple[Any, Any, Any] = ((), None, None)  # (routes, fence, inset), once per route

    def _fence(self, routes: tuple[Any, ...]) -> tuple[Any, Any]:
        """The region outside which the fence trips, and the one the boat holds in after a breach:
        the free water of the route in use and of the boat's configured area together."""
        known = self._regions[0]
        if len(known) != len(routes) or any(a is not b for a, b in zip(known, routes)):  # by identity: cheap
            free = routes[0].free_region()
            for r in routes[1:]:
                free = free.intersection(r.free_region())
            inner = free.buffer(-self.inset_m)
            self._regions = (routes, free.buffer(self.margin_m), free if inner.is_empty else inner)
        return self._regions[1], self._regions[2]

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        s = inputs.state
        routes = inputs.fence_regions()
        if not routes or s is None or not inputs.position_trusted(self.max_position_std_m):
            return False, ""
        outside = not self._fence(routes)[0].contains(Point(s.north_m, s.east_m))
        return outside, f"position ({s.north_m:.1f}, {s.east_m:.1f}) outside the navigable area"

    def action_for(self, mode: "Mode") -> FailsafeAction:
        fenced = mode.fenced or (mode.name == ModeName.MANUAL and self.in_manual)
        return FailsafeAction.HOLD_INSIDE if fenced else FailsafeAction.CONTINUE

    def hold_target(self, inputs: "SupervisorInputs") -> tuple[float, float, float]:
        """(north, east, heading) of the nearest point geofence_inset_m inside the area, bow toward
        it: whatever pushed the boat out (current, wind) is then met by the azimuths' full forward
        thrust, not by the weak sideways one."""
        s = inputs.state
        p = Point(s.north_m, s.east_m)
        q = nearest_points(self._fence(inputs.fence_regions())[1], p)[0]
        heading = math.atan2(q.y - p.y, q.x - p.x) if p.distance(q) > 0.05 else s.heading_rad
        return (q.x, q.y, heading)


class ControllerMonitor(Monitor):
    """The path follower's health, seen after each of its updates (not on the tick: it judges the
    update itself): controller_failure_count failed updates in a row (solver failure, coasting on
    the previous plan, safe stop) or controller_overrun_count updates longer than
    controller_overrun_factor x the control period. Action: the fallback path follower; when the
    fallback fails too, stop (the supervisor knows which one ran)."""

    name = "controller"
    severity = "error"

    def __init__(self, cfg: FailsafeConfig, period_s: float) -> None:
        super().__init__(0.0, math.inf, _in(FOLLOWING, FailsafeAction.FALLBACK))
        self.failure_count, self.overrun_count = cfg.controller_failure_count, cfg.controller_overrun_count
        self.overrun_ms = cfg.controller_overrun_factor * period_s * 1000.0
        self.failures = self.overruns = 0

    def reset(self) -> None:
        self.failures = self.overruns = 0

    def observe(self, status: str, solve_ms: float) -> str:
        """One update's status text and duration; returns why it trips now ('' when it does not)."""
        # the followers report "ok"/"saturated" normally, "fallback_plan (...)" while coasting on
        # the previous solution and "safe_stop (...)" when they gave up
        failed = status.startswith(("safe_stop", "fallback_plan", "failed"))
        self.failures = self.failures + 1 if failed else 0
        self.overruns = self.overruns + 1 if solve_ms > self.overrun_ms else 0
        if self.failures >= self.failure_count:
            why = f"{self.failures} failed updates ({status})"
        elif self.overruns >= self.overrun_count:
            why = f"{self.overruns} overruns ({solve_ms:.1f} ms)"
        else:
            return ""
        self.reset()
        return why

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        return False, ""  # event-driven: `observe`


def storage_problem(inputs: "SupervisorInputs", t: float, cfg: FailsafeConfig) -> str:
    """What is wrong with the recorder's disk, in the operator's words ("" = nothing, or no
    recorder in this run): a write failure and what was kept, too little free space, silence."""
    r = inputs.recorder
    if r is None:
        return ""
    if r.error:
        return f"{r.error}; recording stopped, kept {r.kept}"
    age = t - inputs.recorder_arrival_s
    if age > cfg.storage_silent_s:
        return f"no word from the recorder for {age:.0f} s (logs in {r.directory})"
    if 0 <= r.free_bytes < cfg.storage_min_free_mb * 1e6:
        return (f"the log disk ({r.directory}) has {r.free_bytes / 1e6:.1f} MB free, below the "
                f"{cfg.storage_min_free_mb:g} MB a run needs (storage_min_free_mb)")
    return ""


class StorageMonitor(Monitor):
    """The log disk full, failing or silent (`storage_problem`): reported only (an alert on every
    page and in the log); the boat goes on as it was, and the pre-arm check refuses the next arm."""

    name = "storage"
    severity = "error"
    realert_on_change = True

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(0.0, 3.0, {})
        self.cfg = cfg

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        why = storage_problem(inputs, t, self.cfg)
        return bool(why), why


class MinDepthMonitor(Monitor):
    """The minimum-depth fence: the echosounder's depth under the transducer below min_depth_m for
    min_depth_persist_s while the boat moves by itself: hold where it is (docs/failsafes.md), the
    reason with the depth and the limit. Pings without a bottom are not evidence either way; a
    sounder silent for min_depth_max_age_s neither trips nor holds the fence."""

    name = "min_depth"
    severity = "error"

    def __init__(self, cfg: FailsafeConfig) -> None:
        super().__init__(cfg.min_depth_persist_s, 3.0, _in(UNDER_WAY, cfg.min_depth_action))
        self.min_depth_m = cfg.min_depth_m
        self.max_age_s = cfg.min_depth_max_age_s

    def check(self, inputs: "SupervisorInputs", t: float) -> tuple[bool, str]:
        d = inputs.depth
        if self.min_depth_m <= 0 or d is None or t - inputs.depth_arrival_s > self.max_age_s:
            return False, ""
        return d.depth_m < self.min_depth_m, (f"depth {d.depth_m:.2f} m under the transducer, shallower than the "
                                              f"minimum {self.min_depth_m:g} m")


class ProgressMonitor:
    """The route's progress, seen after each path-follower update (`observe`, as the controller
    monitor): over the last `no_progress_window_s` the boat got less than `no_progress_fraction` of
    the way along the path that the follower's reference speed asked for. A warning and nothing else:
    the boat is where its controller keeps it (in a strong current, a start that stalls; docs/control.md
    "Limits"), and whether to wait, take over or send another route is the operator's call. Samples
    more than `gap_s` apart (a HOLD in between) or a progress that went back (a new route or lap) begin a
    new window; once raised, the warning clears when the window holds twice the fraction."""

    name = "no_progress"
    severity = "warning"
    gap_s = 1.0

    def __init__(self, cfg: FailsafeConfig) -> None:
        self.window_s, self.fraction = cfg.no_progress_window_s, cfg.no_progress_fraction
        self._samples: deque[tuple[float, float, float]] = deque()  # (t, progress m, reference speed m/s)
        self._asked_m = 0.0  # the reference speed's distance over the samples (trapezoids), kept as they come and go
        self.active = False

    def idle(self, t: float) -> bool:
        """No follower update for longer than `gap_s`: the boat is not following a route."""
        return not self._samples or t - self._samples[-1][0] > self.gap_s

    def observe(self, t: float, progress_m: float, speed_ref_mps: float) -> tuple[bool, str]:
        """One update's progress along the path and reference speed; (no progress now, why)."""
        if not (math.isfinite(progress_m) and math.isfinite(speed_ref_mps)):
            return False, ""
        if self.idle(t) or progress_m < self._samples[-1][1] - 0.5:  # a new route, lap or start
            self._samples.clear()
            self._asked_m = 0.0
            self.active = False
        v = max(speed_ref_mps, 0.0)
        if self._samples:
            t1, _, v1 = self._samples[-1]
            self._asked_m += 0.5 * (v1 + v) * (t - t1)
        self._samples.append((t, progress_m, v))
        while len(self._samples) > 1 and t - self._samples[1][0] >= self.window_s:
            (ta, _, va), (tb, _, vb) = self._samples.popleft(), self._samples[0]
            self._asked_m -= 0.5 * (va + vb) * (tb - ta)
        t0, s0, _ = self._samples[0]
        if self.fraction <= 0.0 or t - t0 < self.window_s - self.gap_s:
            return False, ""
        asked, made = self._asked_m, progress_m - s0
        # cleared at twice the fraction, so a boat near the threshold does not raise it again and again
        self.active = made < self.fraction * asked * (2.0 if self.active else 1.0)
        if not self.active:
            return False, ""
        span = t - t0
        made = made if made <= -0.05 else max(made, 0.0)  # no "-0.0 m" for a boat pushed back a centimetre
        return True, (f"{made:.1f} m along the route in {span:.0f} s where the plan asks {asked:.1f} m "
                      f"({made / span:.2f} m/s made good, {asked / span:.2f} m/s planned)")


def standard_monitors(cfg: FailsafeConfig, limits: ActuatorLimits = DEFAULT_LIMITS) -> list[Monitor]:
    """The failsafe table of docs/failsafes.md that is checked every tick, in order (dead
    reckoning after the monitors it follows up on). The controller monitor is separate: it
    judges each path-follower update (`ControllerMonitor.observe`)."""
    thrusting = _in(UNDER_WAY + (ModeName.HOLD, ModeName.MANUAL, ModeName.CALIBRATE), FailsafeAction.STOP)
    gnss_lost, estimator = GnssLostMonitor(cfg), EstimatorMonitor(cfg)
    return [
        LinkMonitor(cfg),
        RcLinkMonitor(cfg),
        gnss_lost,
        GnssDegradedMonitor(cfg),
        estimator,
        DeadReckoningMonitor(cfg, [gnss_lost, estimator]),
        ThrusterMonitor(cfg, limits),
        BatteryMonitor("battery_critical", cfg.battery_critical_v, cfg.battery_persist_s, thrusting, "critical"),
        BatteryMonitor("battery_low", cfg.battery_low_v, cfg.battery_persist_s,
                       _in((ModeName.AUTO, ModeName.HOLD, ModeName.EXPERIMENT), FailsafeAction.RETURN), "warning"),
        GeofenceMonitor(cfg),
        MinDepthMonitor(cfg),
        StorageMonitor(cfg),
    ]


def monitor(monitors: list[Monitor], name: str) -> Any:
    return next(m for m in monitors if m.name == name)
