"""Speed reference along the path: seed eq. (42) plus lateral- and longitudinal-acceleration limits."""

from __future__ import annotations

import numpy as np


def speed_profile(
    s_m: np.ndarray,
    curvature_1pm: np.ndarray,
    node_s_m: np.ndarray,
    node_speed_mps: np.ndarray,
    a_lat_max_mps2: float,
    a_long_max_mps2: float,
    speed_max_mps: float,
) -> np.ndarray:
    """Speed at each path point.

    1. Linear interpolation between node speeds in arc length (seed eq. 42: with evenly spaced
       points, v(n) = (N - n)/N v_k + n/N v_{k+1} is linear in s).
    2. v <= sqrt(a_lat_max / |kappa|) in tight curves, and v <= speed_max.
    3. |dv/dt| <= a_long_max: v^2 may grow or shrink by at most 2 a ds between points; a forward
       pass (acceleration) and a backward pass (braking), both vectorised with a running minimum:
       v_i^2 <= min_{j<=i} (v_j^2 + 2 a (s_i - s_j)) = 2 a s_i + cummin_j (v_j^2 - 2 a s_j).
    """
    v = np.interp(s_m, node_s_m, node_speed_mps)                    # seed eq. (42)
    with np.errstate(divide="ignore"):
        v_lat = np.sqrt(a_lat_max_mps2 / np.abs(curvature_1pm))
    v = np.minimum(np.minimum(v, v_lat), speed_max_mps)
    w = v * v
    two_a = 2.0 * a_long_max_mps2
    w = np.minimum(w, two_a * s_m + np.minimum.accumulate(w - two_a * s_m))          # forward
    w = np.minimum(w, -two_a * s_m + np.minimum.accumulate((w + two_a * s_m)[::-1])[::-1])  # backward
    return np.sqrt(np.maximum(w, 0.0))
