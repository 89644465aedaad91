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
