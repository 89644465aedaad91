"""One controller on the bare simulator: the true state in, the command out, the boat advanced.

The loop a controller's own checks need (its prediction against the motion, its fallbacks, its
hold in a current), without the sensors, the estimator, the supervisor or the actuator guard; the
product's loop with all of them is `lotsen.harness.mission.run_mission`.

    sim = Simulator(config=SimConfig(sensors=False), x0=[0, 0, 0, 0, 0, 0])
    for tick in control_ticks(sim, lambda t, s: keeper.update(t, s, target), until_s=60.0):
        errors.append(math.hypot(sim.x[0], sim.x[1]))

The loop itself (`control_ticks`) is `lotsen.sim.loop`'s: a mission's prediction
(lotsen.stack.prediction) runs the same one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from lotsen.model import Environment
from lotsen.sim import SimConfig, SimulatedBoat, Simulator
from lotsen.sim.loop import ControllerStep, Tick, control_ticks  # noqa: F401 - the loop, in lotsen.sim since the prediction uses it


@dataclass
class PathRun:
    cross_track_m: np.ndarray  # per tick, as the follower reported it
    commands: np.ndarray  # K x 5
    statuses: list[Any]
    sim: Simulator


def follow_path(follower: Any, path: Any, duration_s: float, x0: Sequence[float] | None = None,
                environment: Environment = Environment(), period_s: float = 0.1,
                boat: SimulatedBoat | None = None) -> PathRun:
    """`follower` (reset on `path`) on the simulated boat (default: the simulator's default boat),
    truth as its state, no sensors, from `x0` (default: the path's start, at rest) until
    `duration_s` or the end of the path."""
    follower.reset(path)
    h0 = float(path.heading_rad[0])
    x0 = x0 if x0 is not None else [float(path.north_m[0]), float(path.east_m[0]), h0, 0.0, 0.0, 0.0]
    sim = Simulator(boat, config=SimConfig(sensors=False, environment=environment), x0=x0)
    n_sub = int(round(period_s / sim.config.dt_s))
    cte, cmds, statuses = [], [], []
    if not follower.done:
        for tick in control_ticks(sim, follower.update, n_sub * sim.config.dt_s, duration_s - 1e-9):
            cte.append(tick.status.cross_track_error_m)
            cmds.append(tick.command.as_tuple())
            statuses.append(tick.status)
            if follower.done:
                break
    return PathRun(np.array(cte), np.array(cmds), statuses, sim)
