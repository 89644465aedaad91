"""Checks the control tests share (the closed loop itself is lotsen.harness.controller_loop)."""

from __future__ import annotations

import math

import numpy as np

from lotsen.model import DEFAULT_LIMITS


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


#: the MPC weights before the 2026-11-27 retunings (cross-track 60 everywhere, azimuth crossing 0.01 N^-1,
#: 2-s dwell, yaw-rate weight 1): what the QP recording and the second-QP measurement were made with
WEIGHTS_BEFORE_RETUNING = dict(q_cross_track=60.0, reversal_cost_azimuth_per_N=0.01, reversal_dwell_s=2.0,
                               q_yaw_rate=1.0)


def one_metre_off_at_rest(path) -> list[float]:
    """Initial state at rest, 1 m to port of the path's first point, on its heading."""
    h0 = float(path.heading_rad[0])
    return [float(path.north_m[0]) - math.sin(h0), float(path.east_m[0]) + math.cos(h0), h0, 0.0, 0.0, 0.0]
