"""Identification experiments on a running stack: the real boat (drivers), or its emulated twin.

The same `lotsen.sysid.experiment.InputGenerator` that drives the simulator in
`lotsen experiment run --sim` publishes ship_command here, with the state estimate as its heading
feedback (zigzag triggers). The node records the identification record as it goes:
  - inputs: the commanded azimuth angles (the servos report no angle) and the propeller speeds
    measured by the tachometers (rpm_chatter; the command where none has arrived yet);
  - outputs: north, east, psi, r, u, v of state/estimate at each command tick.
It aborts to neutral when the estimate is not finite or leaves the experiment's area (relative
to where the experiment started): no supervisor runs during an experiment, so this node is the
geofence, and the actuator guard downstream still applies neutral on a stale command.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from lotsen.messages import RpmSample, ThrustCommand, Topic, VesselState
from lotsen.runtime.executor import Node, NodeContext


class ExperimentNode(Node):
    name = "experiment"

    def __init__(self, experiment: Any, preroll_s: float = 2.0, margin_m: float = 0.0) -> None:
        from lotsen.sysid.experiment import InputGenerator

        self.experiment = experiment
        self.generator = InputGenerator(experiment)
        self.preroll_s = preroll_s
        self.margin_m = margin_m
        self.state: VesselState | None = None
        self.rpm: RpmSample | None = None
        self.t0: float | None = None
        self.origin = (0.0, 0.0)
        self.rows: list[tuple[float, ...]] = []
        self.done = False
        self.aborted = ""

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self.t_start = ctx.now()
        ctx.subscribe(Topic.STATE, self._on_state)
        ctx.subscribe(Topic.RPM, self._on_rpm)
        ctx.add_timer(1.0 / self.experiment.command_rate_hz, self._tick)

    def _on_state(self, msg: VesselState) -> None:
        self.state = msg

    def _on_rpm(self, msg: RpmSample) -> None:
        self.rpm = msg

    def _neutral(self, t: float) -> None:
        self.ctx.publish(Topic.SHIP_COMMAND, ThrustCommand.neutral(t, source="experiment"))

    def _tick(self) -> None:
        t = self.ctx.now()
        s = self.state
        if self.done:
            self._neutral(t)
            return
        finite = s is not None and all(math.isfinite(v) for v in s.as_array_tuple())
        if self.t0 is None:  # wait for the estimate to settle, thrusters neutral
            if finite and t - self.t_start >= self.preroll_s:
                self.t0, self.origin = t, (s.north_m, s.east_m)
                self.ctx.log("info", f"experiment '{self.experiment.name}' started "
                                     f"({self.experiment.duration_s:.0f} s)")
            self._neutral(t)
            return
        tau = t - self.t0
        why = "" if finite else "the state estimate is not finite"
        if finite and not self._inside(s):
            why = f"left the experiment area at ({s.north_m:.1f}, {s.east_m:.1f}) m"
        if why or tau >= self.experiment.duration_s:
            self.done = True
            self.aborted = why
            self.ctx.log("error" if why else "info", f"experiment '{self.experiment.name}' "
                         + (f"aborted: {why}" if why else "finished"))
            self._neutral(t)
            return
        u = self.generator.command(tau, s)
        cmd = ThrustCommand.from_tuple(t, u, source="experiment")
        self.ctx.publish(Topic.SHIP_COMMAND, cmd)
        n = (self.rpm.n1_rps, self.rpm.n2_rps, self.rpm.nt_rps) if self.rpm is not None else u[2:]
        self.rows.append((tau, u[0], u[1], *n, s.north_m, s.east_m, s.heading_rad, s.r_radps, s.u_mps, s.v_mps))

    def _inside(self, s: VesselState) -> bool:
        a, m = self.experiment.area, self.margin_m
        dn, de = s.north_m - self.origin[0], s.east_m - self.origin[1]
        return a.north_m[0] - m <= dn <= a.north_m[1] + m and a.east_m[0] - m <= de <= a.east_m[1] + m

    def record(self) -> Any:
        """The identification record of what ran so far (lotsen.sysid.data.IdRecord, with u and v)."""
        from lotsen.sysid.data import IdRecord

        data = np.array(self.rows, dtype=float).reshape(-1, 12)
        return IdRecord(data[:, 0], data[:, 1:6], data[:, 6:12],
                        output_names=("north", "east", "psi", "r", "u", "v"),
                        source=f"runtime:{self.experiment.name}")
