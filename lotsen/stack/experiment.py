"""Identification experiments on a running stack: the real boat (drivers), or its emulated twin.

The same `lotsen.sysid.experiment.InputGenerator` that drives the simulator in
`lotsen experiment run --sim` is a command source here, like the operator's keys: it publishes
experiment/command, and the supervisor forwards it in EXPERIMENT mode under every failsafe (the
pre-arm checks, GNSS and estimator loss, the thruster monitor, the geofence of a loaded route,
the RC takeover and e-stop). The node asks for the mode as an operator would (`arm`, then
`experiment`, once the ESCs are armed and the estimate has settled), starts the experiment's clock
when the supervisor is in EXPERIMENT, and ends it with `disarm`. It records the identification
record as it goes:
  - inputs: the commanded azimuth angles (the servos report no angle) and the propeller speeds
    measured by the tachometers (rpm_chatter; the command where none has arrived yet);
  - outputs: north, east, psi, r, u, v of state/estimate at each command tick.
When the boat is about to leave the experiment's area (relative to where the experiment started;
a hull that turns wider than the model the design predicted with) the signal pauses and the node
steers the boat back to the area's centre, then resumes the signal where it paused
(`lotsen.sysid.experiment.AreaKeeper`; the return's rows stay in the record). It aborts (and
disarms) when the estimate is not finite, when the boat leaves the area all the same or a return
takes too long, when the supervisor refuses the mode or leaves it (a failsafe, the RC pilot, an
e-stop). It knows the sea the boat's IMU measures (fusion/sea_state): when
the experiment starts in waves it warns that the sea is too high for a trustworthy record and what to
do (lotsen.sysid.waves.experiment_sea_warning); `sea` is the last estimate.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from lotsen.messages import (
    Alert, ModeName, OperatorCommand, RpmSample, SeaState, SupervisorStatus, ThrustCommand, Topic, VesselState,
)
from lotsen.runtime.config import LaunchConfig
from lotsen.runtime.executor import Node, NodeContext
from lotsen.stack.launch import build_stack

if TYPE_CHECKING:
    from lotsen.sysid.experiment import ReturnConfig


class ExperimentNode(Node):
    name = "experiment"

    def __init__(self, experiment: Any, preroll_s: float = 2.0, margin_m: float = 0.0,
                 request_timeout_s: float = 3.0, keep_inside: bool = True,
                 returns: ReturnConfig | None = None) -> None:
        from lotsen.sysid.experiment import AreaKeeper, InputGenerator, ReturnConfig

        self.experiment = experiment
        self.generator = InputGenerator(experiment)
        # keep_inside False: no return, the area's edge aborts the run
        self.keeper = AreaKeeper(experiment.area, returns or ReturnConfig()) if keep_inside else None
        self.preroll_s = preroll_s
        self.margin_m = margin_m
        self.request_timeout_s = request_timeout_s
        self.state: VesselState | None = None
        self.rpm: RpmSample | None = None
        self.status: SupervisorStatus | None = None
        self.refusal = ""
        self.requested_s: float | None = None
        self.t0: float | None = None
        self.origin = (0.0, 0.0)
        self.rows: list[tuple[float, ...]] = []
        self.done = False
        self.aborted = ""
        self.plant: Any = None  # set by run_on_stack in simulation
        self.sea: SeaState | None = None  # the boat's last valid sea-state estimate

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self.t_start = ctx.now()
        ctx.subscribe(Topic.STATE, self._on_state)
        ctx.subscribe(Topic.RPM, self._on_rpm)
        ctx.subscribe(Topic.SUPERVISOR, self._on_status)
        ctx.subscribe(Topic.ALERT, self._on_alert)
        ctx.subscribe(Topic.SEA_STATE, self._on_sea)
        ctx.add_timer(1.0 / self.experiment.command_rate_hz, self._tick)

    def _on_state(self, msg: VesselState) -> None:
        self.state = msg

    def _on_sea(self, msg: SeaState) -> None:
        if msg.valid:
            self.sea = msg

    def _on_rpm(self, msg: RpmSample) -> None:
        self.rpm = msg

    def _on_status(self, msg: SupervisorStatus) -> None:
        self.status = msg

    def _on_alert(self, msg: Alert) -> None:
        if msg.active and msg.code in ("refused:arm", "refused:experiment"):
            self.refusal = msg.text

    def _request(self, action: str, t: float) -> None:
        self.ctx.publish(Topic.OPERATOR, OperatorCommand(stamp_s=t, action=action, source="experiment"))

    def _neutral(self, t: float) -> None:
        # keeps the command stream alive (the supervisor takes EXPERIMENT only from a live source)
        self.ctx.publish(Topic.EXPERIMENT_COMMAND, ThrustCommand.neutral(t, source="experiment"))

    def _end(self, t: float, why: str) -> None:
        self.done = True
        self.aborted = why
        self.ctx.log("error" if why else "info", f"experiment '{self.experiment.name}' "
                     + (f"aborted: {why}" if why else "finished"))
        self._neutral(t)
        self._request("disarm", t)

    def _tick(self) -> None:
        t = self.ctx.now()
        s = self.state
        if self.done:
            self._neutral(t)
            return
        finite = s is not None and all(math.isfinite(v) for v in s.as_array_tuple())
        mode = self.status.mode if self.status is not None else ""
        if self.t0 is None:  # the estimate settles and the ESCs arm at neutral; then ask for the mode
            if (self.requested_s is None and finite and t - self.t_start >= self.preroll_s
                    and self.status is not None and self.status.escs_armed):
                self.requested_s = t
                if not self.status.armed:
                    self._request("arm", t)
                self._request("experiment", t)
                mode = self.status.mode  # a supervisor in this process has answered already
            if self.refusal:
                self._end(t, f"the supervisor refused: {self.refusal}")
            elif mode == ModeName.EXPERIMENT and finite:
                self.t0, self.origin = t, (s.north_m, s.east_m)
                self.ctx.log("info", f"experiment '{self.experiment.name}' started "
                                     f"({self.experiment.duration_s:.0f} s)")
                self._check_sea()
            elif self.requested_s is not None and t - self.requested_s > self.request_timeout_s:
                self._end(t, f"the supervisor did not enter EXPERIMENT within {self.request_timeout_s:g} s "
                             f"(mode {mode or 'unknown'})")
            self._neutral(t)  # the experiment's first command goes out on the next tick
            return
        tau = t - self.t0
        why = "" if finite else "the state estimate is not finite"
        back = self._keep_inside(tau, s) if finite else None
        if finite and not self.experiment.area.contains(*self._relative(s), -self.margin_m):
            # the area was checked on the model's prediction: a boat that turns wider than its model
            # (a hull not built like it, the defaults before any identification) leaves it
            why = (f"left the experiment area at ({s.north_m:.1f}, {s.east_m:.1f}) m: the boat went wider than "
                   f"the model predicted" + (" and did not turn back in time" if self.keeper else "")
                   + "; design again with a larger --margin (the predicted track kept that far inside the area), "
                   "or with --params from a first record's identification")
        elif self.keeper is not None:
            why = self.keeper.failure(tau, self.experiment.duration_s)
        if mode != ModeName.EXPERIMENT:
            why = f"the supervisor left EXPERIMENT: {mode} ({self.status.reason if self.status else ''})"
        signal_s = tau - (self.keeper.paused_s if self.keeper is not None else 0.0)
        if why or signal_s >= self.experiment.duration_s:
            self._end(t, why)
            return
        u = back if back is not None else self.generator.command(signal_s, s)
        self.ctx.publish(Topic.EXPERIMENT_COMMAND, ThrustCommand.from_tuple(t, u, source="experiment"))
        n = (self.rpm.n1_rps, self.rpm.n2_rps, self.rpm.nt_rps) if self.rpm is not None else u[2:]
        self.rows.append((tau, u[0], u[1], *n, s.north_m, s.east_m, s.heading_rad, s.r_radps, s.u_mps, s.v_mps))

    def _keep_inside(self, tau: float, s: VesselState) -> tuple[float, ...] | None:
        """The return's set-points while the boat is brought back into the area, else None (and
        the operator told when a return starts and ends)."""
        k = self.keeper
        if k is None:
            return None
        was, returns = k.returning, k.returns
        back = k.update(tau, *self._relative(s), s.heading_rad, s.u_mps, s.v_mps)
        if k.returns > returns:
            self.ctx.log("warning", f"experiment '{self.experiment.name}': the boat is about to leave the area at "
                                    f"({s.north_m:.1f}, {s.east_m:.1f}) m: the signal pauses at "
                                    f"{tau - k.paused_s:.1f} s and the boat turns back to the area's centre "
                                    f"(return {k.returns})")
        elif was and not k.returning:
            self.ctx.log("info", f"experiment '{self.experiment.name}': back in the area; the signal resumes at "
                                 f"{tau - k.paused_s:.1f} s ({k.paused_s:.0f} s of returns so far)")
        return back

    def _check_sea(self) -> None:
        """The experiment's check of the sea (the boat's IMU estimate at the start): a warning in waves."""
        from lotsen.sysid.waves import experiment_sea_warning

        sea = self.sea
        msg = experiment_sea_warning(sea.hs_m, sea.tp_s, sea.from_deg) if sea is not None else None
        if msg:
            self.ctx.log("warning", f"experiment '{self.experiment.name}': {msg}")

    def _relative(self, s: VesselState) -> tuple[float, float]:
        """North and east from where the experiment started: the frame of its area."""
        return s.north_m - self.origin[0], s.east_m - self.origin[1]

    def run_limit_s(self) -> float:
        """The longest the signal may take from its start: its duration, or with returns the keeper's limit."""
        d = self.experiment.duration_s
        return self.keeper.config.run_limit_s(d) if self.keeper is not None else d

    def record(self) -> Any:
        """The identification record of what ran so far (lotsen.sysid.data.IdRecord, with u and v)."""
        from lotsen.sysid.data import IdRecord

        data = np.array(self.rows, dtype=float).reshape(-1, 12)
        return IdRecord(data[:, 0], data[:, 1:6], data[:, 6:12],
                        output_names=("north", "east", "psi", "r", "u", "v"),
                        source=f"runtime:{self.experiment.name}")


def run_on_stack(experiment: Any, config: LaunchConfig, realtime: bool, keep_inside: bool = True) -> ExperimentNode:
    """Run `experiment` through the runtime on the boat the config names (hardware, its emulated
    twin, or the simulated boat): drivers, the state estimate, the supervisor and the recorder
    run; the experiment node is the supervisor's command source in EXPERIMENT mode. Returns the
    ExperimentNode (its `record()`, `aborted`, and `plant`: the simulated boat's plant, whose
    `status()` says whether an external physics answered throughout). `keep_inside` False: the
    area's edge ends the run instead of a return."""
    stack = build_stack(config, realtime=realtime, parts=("state", "supervisor", "logs"))
    node = stack.add(ExperimentNode(experiment, keep_inside=keep_inside))
    deadline = node.run_limit_s() + node.preroll_s + 10.0  # the node ends the run itself before it
    try:
        if realtime:
            stack.executor.add_timer(0.2, lambda: stack.executor.stop() if node.done else None, "experiment-end")
            stack.executor.run(deadline)
        else:
            stack.executor.run_until(deadline, stop=lambda: node.done)
            stack.executor.shutdown()
    finally:
        if stack.simulator is not None:  # an external physics: whether it answered throughout
            node.plant = stack.simulator.plant
        for close in stack.services.get("on_shutdown", []):
            close()
    return node
