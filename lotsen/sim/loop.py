"""One controller on the bare simulator: the true state in, the command out, the boat advanced.

The loop a controller's own checks and a mission's prediction need (lotsen.harness.controller_loop,
lotsen.stack.prediction): no sensors, estimator, supervisor or actuator guard. Every `period_s` of
simulated time the controller gets (t, the true state) and returns (command, status); the simulator
takes the command and advances by `period_s` with it held.

    sim = Simulator(config=SimConfig(sensors=False), x0=[0, 0, 0, 0, 0, 0])
    for tick in control_ticks(sim, lambda t, s: keeper.update(t, s, target), until_s=60.0):
        errors.append(math.hypot(sim.x[0], sim.x[1]))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Iterator

from lotsen.messages import ThrustCommand, VesselState
from lotsen.sim.simulator import Simulator

#: the controller's step: (time in s, state) -> (command, status)
ControllerStep = Callable[[float, VesselState], tuple[ThrustCommand, Any]]


@dataclass(frozen=True)
class Tick:
    t_s: float  # when the controller ran
    x: tuple[float, ...]  # the true state it saw (north, east, psi, u, v, r)
    command: ThrustCommand
    status: Any  # what the controller returned with the command


def control_ticks(sim: Simulator, step: ControllerStep, period_s: float = 0.1,
                  until_s: float | None = None) -> Iterator[Tick]:
    """Run `step` on `sim` every `period_s` until the simulator's time reaches `until_s` (or for
    as long as the caller iterates); yields each tick after the simulator advanced."""
    while until_s is None or sim.t < until_s:
        t, x = sim.t, sim.x
        command, status = step(t, sim.truth())
        sim.command(command)
        sim.advance(period_s)
        yield Tick(t, tuple(x), command, status)
