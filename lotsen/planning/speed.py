"""Speed reference along the path: seed eq. (42) plus lateral- and longitudinal-acceleration limits.

Start from rest (the harbour, speed 0) and stops (a node with speed 0): seed eq. (42) interpolates
linearly in arc length between node speeds, so the first leg after the harbour (speed 0) would
ramp from 0 to the node speed over its *whole length* -- a 100 m leg at 0.5 m/s planned at about
660 s, the boat leaving the harbour at 0.15 m/s after 30 m. A speed of 0 at a node
means "at rest here", not "slow along the leg": the leg next to a zero-speed node runs at the
speed of its other node, and the longitudinal-acceleration limit `a_long_max_mps2` (the
planner's default 0.2 m/s^2) shapes the ramp from and to rest: v = sqrt(2 a s), so 0 -> 0.5 m/s
in 0.63 m and 2.5 s. Between two moving nodes eq. (42) is unchanged.
"""

from __future__ import annotations

import numpy as np


def leg_speeds(node_speed_mps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Speed at the start and at the end of each leg for the linear interpolation (eq. 42).

    A zero-speed node (rest) takes the speed of the leg's other node; the rest itself is imposed
    afterwards at the node's point, where the acceleration limit builds the ramp."""
    v = np.asarray(node_speed_mps, dtype=float)
    start, end = v[:-1].copy(), v[1:].copy()
    at_rest = v <= 0.0
    start[at_rest[:-1]] = v[1:][at_rest[:-1]]
    end[at_rest[1:]] = v[:-1][at_rest[1:]]
    return start, end


def speed_profile(
    s_m: np.ndarray,
    curvature_1pm: np.ndarray,
    node_s_m: np.ndarray,
    node_speed_mps: np.ndarray,
    a_lat_max_mps2: float,
    a_long_max_mps2: float,
    speed_max_mps: float,
    rest_at_end: bool = False,
) -> np.ndarray:
    """Speed at each path point.

    1. Linear interpolation between node speeds in arc length, leg by leg (seed eq. 42: with
       evenly spaced points, v(n) = (N - n)/N v_k + n/N v_{k+1} is linear in s); a leg that
       starts or ends at a zero-speed node runs at its other node's speed (see `leg_speeds`).
    2. v = 0 at the zero-speed nodes (start from rest, stops), and at the last point with
       `rest_at_end` (the boat holds there after the route; the last leg keeps its node speeds).
    3. v <= sqrt(a_lat_max / |kappa|) in tight curves, and v <= speed_max.
    4. |dv/dt| <= a_long_max: v^2 may grow or shrink by at most 2 a ds between points; a forward
       pass (acceleration) and a backward pass (braking), both vectorised with a running minimum:
       v_i^2 <= min_{j<=i} (v_j^2 + 2 a (s_i - s_j)) = 2 a s_i + cummin_j (v_j^2 - 2 a s_j).
    """
    s_m = np.asarray(s_m, dtype=float)
    node_s = np.asarray(node_s_m, dtype=float)
    node_v = np.asarray(node_speed_mps, dtype=float)
    if len(node_s) < 2:
        v = np.full_like(s_m, float(node_v[0]) if len(node_v) else 0.0)
    else:
        v_start, v_end = leg_speeds(node_v)
        k = np.clip(np.searchsorted(node_s, s_m, side="right") - 1, 0, len(node_s) - 2)
        leg = np.maximum(node_s[k + 1] - node_s[k], 1e-12)
        frac = np.clip((s_m - node_s[k]) / leg, 0.0, 1.0)
        v = v_start[k] + frac * (v_end[k] - v_start[k])                 # seed eq. (42), per leg
        for s_rest in node_s[node_v <= 0.0]:                            # at rest at these nodes
            v[int(np.argmin(np.abs(s_m - s_rest)))] = 0.0
    if rest_at_end and len(v):
        v[-1] = 0.0
    with np.errstate(divide="ignore"):
        v_lat = np.sqrt(a_lat_max_mps2 / np.abs(curvature_1pm))
    v = np.minimum(np.minimum(v, v_lat), speed_max_mps)
    w = v * v
    two_a = 2.0 * a_long_max_mps2
    w = np.minimum(w, two_a * s_m + np.minimum.accumulate(w - two_a * s_m))          # forward
    w = np.minimum(w, -two_a * s_m + np.minimum.accumulate((w + two_a * s_m)[::-1])[::-1])  # backward
    return np.sqrt(np.maximum(w, 0.0))
