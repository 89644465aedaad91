"""The one path projection of the project: where a position lies on a polyline path.

`project_window` is the foot point on the segments between two indices (compiled: every controller
step calls it); `search_window` gives the indices within +-window of the last known progress.
`lotsen.planning.Path.project` and the controllers' `lotsen.control.PathReference.project` both
call them. A moving vessel is localised near its last progress, never over the whole path: where a
path crosses or passes close to itself (figure eight), a global search jumps to the other branch.
"""

from __future__ import annotations

import math

import numpy as np

from lotsen.model._jit import njit


def search_window(s_m: np.ndarray, s_hint_m: float, window_m: float) -> tuple[int, int]:
    """Segment indices (lo, hi) for `project_window`: the segments within +-window_m of s_hint_m
    (a hint beyond the end searches the last window_m of the path)."""
    n = len(s_m)
    lo = max(0, int(np.searchsorted(s_m, min(s_hint_m, s_m[-1]) - window_m, side="right")) - 1)
    hi = min(n - 1, int(np.searchsorted(s_m, s_hint_m + window_m, side="left")) + 1)
    return lo, max(hi, lo + 1)


def _project_window_py(north, east, pn, pe, ps, heading, lo, hi):  # type: ignore[no-untyped-def]
    """Foot point of (north, east) on the polyline segments lo .. hi-1 (points pn, pe at arc lengths
    ps, unwrapped headings): (s, signed distance (+ = starboard), heading (not wrapped), segment
    index). Numba-compiled: every controller step calls it."""
    best, j_best, t_best, q_nb, q_eb = math.inf, lo, 0.0, 0.0, 0.0
    for i in range(lo, hi):
        d_n = pn[i + 1] - pn[i]
        d_e = pe[i + 1] - pe[i]
        q_n = north - pn[i]
        q_e = east - pe[i]
        t = (q_n * d_n + q_e * d_e) / max(d_n * d_n + d_e * d_e, 1e-18)
        t = min(max(t, 0.0), 1.0)
        r_n = q_n - t * d_n
        r_e = q_e - t * d_e
        d2 = r_n * r_n + r_e * r_e
        if d2 < best:
            best, j_best, t_best, q_nb, q_eb = d2, i, t, q_n, q_e
    dist = math.sqrt(best)
    # sign: cross(direction, vessel - point) in the (north, east) plane; > 0 = starboard
    cross = (pn[j_best + 1] - pn[j_best]) * q_eb - (pe[j_best + 1] - pe[j_best]) * q_nb
    cte = dist if cross >= 0 else -dist
    s = ps[j_best] + t_best * (ps[j_best + 1] - ps[j_best])
    hdg = heading[j_best] + t_best * (heading[j_best + 1] - heading[j_best])
    return s, cte, hdg, j_best


project_window = njit(_project_window_py)
