"""Modes as classes (ArduPilot's `Mode` pattern): each says what it needs (capability
predicates), what happens when it is entered and left, and what the thrusters do every tick.

| mode      | what the thrusters do                                  | needs                       |
|-----------|--------------------------------------------------------|-----------------------------|
| MANUAL    | keyboard ManualCommand -> thrust allocation            | armed for thrust            |
| AUTO      | follow the planned route; HOLD at its end              | armed, route, position      |
| HOLD      | station keeping at a target pose                       | armed, position             |
| RETURN    | plan to the harbour inside the area and follow it      | armed, route, position      |
| CALIBRATE | spin on the bow thruster one turn, fit the magnetometer | armed, heading              |
| ESTOP     | neutral, latched until 'reset_estop'; disarms          | -                           |
| RC        | the RC transmitter's command (neutral without a link)  | RcOverride.active           |
| EXPERIMENT| the identification experiment's commands (neutral when | armed, position, heading,   |
|           | they stop coming)                                      | an experiment sending       |

"Stop" in the failsafe table means MANUAL with neutral thrusters and the reason shown: the
operator can still drive by keyboard, the boat does not move by itself.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

from lotsen.control import HoldTarget
from lotsen.errors import LotsenError
from lotsen.messages import ControllerStatus, MagCalibrationResult, ModeName, ThrustCommand
from lotsen.model import wrap_angle
from lotsen.supervisor.inputs import SupervisorInputs

Output = tuple[ThrustCommand, "ControllerStatus | None"]


class Helm(Protocol):
    """What a mode may use of the supervisor that runs it (`node.SupervisorNode` is one): the
    modes are below the node, so they name what they need instead of importing it."""

    config: Any  # node.SupervisorConfig
    inputs: SupervisorInputs
    armed: bool
    stopped: str
    mode: "Mode"
    modes: dict[ModeName, "Mode"]
    failsafes: Any  # failsafes.FailsafeState
    allocator: Any
    station_keeper: Any
    follower: Any
    fallback: Any
    active_path: Any
    mag_calibrator: Any
    ctx: Any

    def set_mode(self, mode: "Mode", reason: str) -> None: ...
    def enter_hold(self, t: float, reason: str, target: HoldTarget | None = None) -> None: ...
    def send_command(self, t: float, cmd: ThrustCommand) -> None: ...
    def watch_controller(self, t: float, status: ControllerStatus, solve_ms: float) -> None: ...
    def position_ok(self) -> bool: ...
    def publish_calibration(self, result: MagCalibrationResult) -> None: ...


def neutral(t: float, source: str) -> ThrustCommand:
    return ThrustCommand.neutral(t, source=source)


class Mode:
    """Base class. Capability predicates are class attributes; `update` returns the command."""

    name: ModeName
    requires_armed = True  # thrust in this mode needs the operator's arm
    requires_position = False  # a trustworthy position estimate
    requires_heading = False
    requires_route = False
    moving = False  # follows a path (failsafes that 'hold' act in it)
    fenced = False  # the geofence acts in it
    # a human has the boat (the latched e-stop, the RC transmitter): failsafe actions leave it
    # alone and operator requests other than the e-stop are refused with this reason
    human_in_control = ""

    def enter(self, sup: "Helm", t: float) -> None:
        pass

    def exit(self, sup: "Helm", t: float) -> None:
        pass

    def update(self, sup: "Helm", t: float) -> Output:
        return neutral(t, self.name.lower()), None


class Manual(Mode):
    name = ModeName.MANUAL
    requires_armed = False  # selectable disarmed; keys give thrust only when armed

    def enter(self, sup: "Helm", t: float) -> None:
        sup.inputs.manual = None  # keys held before the switch do not count

    def update(self, sup: "Helm", t: float) -> Output:
        fs = sup.config.failsafes
        m = sup.inputs.manual
        if not sup.armed:
            return neutral(t, "manual:disarmed"), None
        if sup.stopped or m is None or t - sup.inputs.manual_arrival_s > fs.manual_timeout_s:
            return neutral(t, "manual:idle" if not sup.stopped else "manual:stopped"), None
        if "link_lost" in sup.failsafes.active:
            return neutral(t, "manual:link-lost"), None
        c = sup.config
        tau = (m.surge * c.manual_surge_N, m.sway * c.manual_sway_N, m.yaw * c.manual_yaw_Nm)
        if tau == (0.0, 0.0, 0.0):
            return neutral(t, "manual"), None
        res = sup.allocator.allocate(tau)
        return ThrustCommand.from_tuple(t, res.command, source="manual"), None


class Hold(Mode):
    """Station keeping at `target` (set before entering)."""

    name = ModeName.HOLD
    requires_position = True
    requires_heading = True
    fenced = True

    def __init__(self) -> None:
        self.target: HoldTarget | None = None

    def enter(self, sup: "Helm", t: float) -> None:
        sup.station_keeper.reset()

    def update(self, sup: "Helm", t: float) -> Output:
        return sup.station_keeper.update(t, sup.inputs.state, self.target)


class FollowPath(Mode):
    """Follow `sup.active_path` with the path follower (or its fallback); HOLD at the end."""

    requires_position = True
    requires_heading = True
    requires_route = True
    moving = True
    fenced = True

    def update(self, sup: "Helm", t: float) -> Output:
        follower = sup.fallback or sup.follower
        w0 = sup.ctx.work()
        cmd, status = follower.update(t, sup.inputs.state)
        sup.watch_controller(t, status, (sup.ctx.work() - w0) * 1000.0)
        if sup.mode is not self:  # the controller watch switched mode
            return sup.mode.update(sup, t)
        if follower.done:
            end = sup.active_path.sample(sup.active_path.length_m)
            sup.enter_hold(t, f"{self.name.lower()} finished: holding at the end",
                           HoldTarget(float(end.north_m), float(end.east_m), float(end.heading_rad)))
        return cmd, status


class Auto(FollowPath):
    name = ModeName.AUTO


class Return(FollowPath):
    name = ModeName.RETURN


class Calibrate(Mode):
    """One slow turn on the bow thruster (the azimuths idle), then fit the magnetometer ellipse."""

    name = ModeName.CALIBRATE
    requires_heading = True

    def __init__(self) -> None:
        self.samples: list[tuple[float, float]] = []
        self.travel_rad = 0.0
        self.last_heading: float | None = None
        self.start_s = 0.0

    def enter(self, sup: "Helm", t: float) -> None:
        self.samples, self.travel_rad, self.last_heading, self.start_s = [], 0.0, None, t

    def update(self, sup: "Helm", t: float) -> Output:
        c = sup.config
        s = sup.inputs.state
        if s is not None and math.isfinite(s.heading_rad):
            if self.last_heading is not None:
                self.travel_rad += abs(wrap_angle(s.heading_rad - self.last_heading))
            self.last_heading = s.heading_rad
        done = math.degrees(self.travel_rad) >= c.calibration_turn_deg
        if done or t - self.start_s > c.calibration_timeout_s:
            self.finish(sup, t, done)
            return neutral(t, "calibration:done"), None
        return ThrustCommand(stamp_s=t, nt_rps=c.calibration_bow_rps, source="calibration"), None

    def finish(self, sup: "Helm", t: float, turned: bool) -> None:
        result = MagCalibrationResult(stamp_s=t, ok=False, text="calibration manoeuvre timed out")
        if turned and sup.mag_calibrator is not None:
            try:
                result = sup.mag_calibrator(self.samples)
                result.stamp_s = t
            except LotsenError as exc:
                result = MagCalibrationResult(stamp_s=t, ok=False, text=str(exc))
        elif turned:
            result = MagCalibrationResult(stamp_s=t, ok=False, text="no magnetometer calibrator configured")
        sup.publish_calibration(result)
        if sup.position_ok():
            sup.enter_hold(t, "calibration finished")
        else:
            sup.set_mode(sup.modes[ModeName.MANUAL], "calibration finished")


class Estop(Mode):
    name = ModeName.ESTOP
    requires_armed = False
    human_in_control = "emergency stop is latched; reset it first"

    def enter(self, sup: "Helm", t: float) -> None:
        sup.armed = False
        sup.send_command(t, neutral(t, "estop"))  # now, not on the next tick

    def update(self, sup: "Helm", t: float) -> Output:
        return neutral(t, "estop"), None


class Rc(Mode):
    """The RC transmitter has control (the seed: a human can always take over). Neutral when it
    sends no command, and when its link is lost, in failsafe or silent for rc_timeout_s."""

    name = ModeName.RC
    requires_armed = False
    human_in_control = "the RC transmitter has control"

    def update(self, sup: "Helm", t: float) -> Output:
        rc = sup.inputs.rc
        if rc is None or rc.link != "ok" or t - sup.inputs.rc_arrival_s > sup.config.failsafes.rc_timeout_s:
            return neutral(t, "rc:link-lost"), None
        return (rc.command if rc.command is not None else neutral(t, "rc")), None


class Experiment(Mode):
    """An identification experiment (lotsen experiment run) drives: its commands on
    experiment/command are forwarded like the keys in MANUAL, under every failsafe of a boat
    under way; neutral once they are older than the manual timeout."""

    name = ModeName.EXPERIMENT
    requires_position = True
    requires_heading = True  # the experiment's zigzag triggers and its record need the heading
    fenced = True

    def update(self, sup: "Helm", t: float) -> Output:
        cmd = sup.inputs.experiment
        if cmd is None or t - sup.inputs.experiment_arrival_s > sup.config.failsafes.manual_timeout_s:
            return neutral(t, "experiment:stale"), None
        return ThrustCommand.from_tuple(t, cmd.as_tuple(), source="experiment"), None


def all_modes() -> dict[ModeName, Mode]:
    return {m.name: m for m in (Manual(), Auto(), Hold(), Return(), Calibrate(), Estop(), Rc(), Experiment())}
