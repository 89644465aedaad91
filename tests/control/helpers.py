"""Closed-loop runner for the tests: a follower on the simulator (truth, no sensors)."""

from __future__ import annotations

import math

import numpy as np

from lotsen.model import DEFAULT_LIMITS, Environment
from lotsen.sim import SimConfig, Simulator


def closed_loop(follower, path, duration_s: float, x0=None, env: Environment = Environment(), dt_s: float = 0.1):
    follower.reset(path)
    h0 = float(path.heading_rad[0])
    x0 = x0 if x0 is not None else [float(path.north_m[0]), float(path.east_m[0]), h0, 0.0, 0.0, 0.0]
    sim = Simulator(config=SimConfig(sensors=False, environment=env), x0=x0)
    cte, cmds, statuses = [], [], []
    n_sub = int(round(dt_s / sim.config.dt_s))
    while sim.t < duration_s - 1e-9 and not follower.done:
        cmd, st = follower.update(sim.t, sim.truth())
        sim.command(cmd)
        sim.advance(n_sub * sim.config.dt_s)
        cte.append(st.cross_track_error_m)
        cmds.append(cmd.as_tuple())
        statuses.append(st)
    return np.array(cte), np.array(cmds), statuses, sim


def assert_commands_within_limits(cmds: np.ndarray, dt_s: float = 0.1, limits=DEFAULT_LIMITS) -> None:
    assert np.all(np.isfinite(cmds))
    assert np.all(np.abs(cmds[:, :2]) <= limits.alpha_max_rad + 1e-9)
    assert np.all(np.abs(cmds[:, 2:4]) <= limits.n_az_max_rps + 1e-9)
    assert np.all(np.abs(cmds[:, 4]) <= limits.n_bow_max_rps + 1e-9)
    d = np.abs(np.diff(cmds, axis=0))
    assert np.all(d[:, :2] <= limits.alpha_rate_max_radps * dt_s + 1e-9)
    assert np.all(d[:, 2:] <= limits.n_rate_max_rps2 * dt_s + 1e-9)


def rms(a) -> float:
    return float(math.sqrt(np.mean(np.square(a))))
