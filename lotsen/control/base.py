"""What every controller shares: the `PathFollower` / `StationKeeper` protocols and path geometry.

A path follower is pure: `reset(path)` once per path, then `update(t, state)` at a fixed rate
returns the actuator command and a `ControllerStatus`. Time comes in as an argument; nothing
reads a clock (the MPC measures its own solve time with `time.perf_counter` for reporting only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

from lotsen.messages import ControllerStatus, ThrustCommand, VesselState
from lotsen.model._jit import njit
from lotsen.model.angles import all_finite, wrap_angle


@runtime_checkable
class PathFollower(Protocol):
    """Follows a planned `lotsen.planning.Path` (cross-track, heading and speed; seed section 3.5)."""

    name: str

    def reset(self, path: Any) -> None: ...

    def update(self, t: float, state: VesselState) -> tuple[ThrustCommand, ControllerStatus]: ...

    @property
    def done(self) -> bool:
        """True once the progress has reached the end of the path."""
        ...


@dataclass(frozen=True)
class HoldTarget:
    """Position and heading to hold (station keeping, 'hold' mode)."""

    north_m: float
    east_m: float
    heading_rad: float


@runtime_checkable
class StationKeeper(Protocol):
    name: str

    def reset(self) -> None: ...

    def update(self, t: float, state: VesselState, target: HoldTarget) -> tuple[ThrustCommand, ControllerStatus]: ...


class PathReference:
    """Fast vectorised access to a Path, extended straight beyond its end (for a horizon that
    looks past the last point) and with a minimum speed reference so the vessel leaves a
    harbour node whose planned speed is 0."""

    def __init__(self, path: Any, min_speed_mps: float = 0.15, window_m: float = 1.5) -> None:
        self.path = path
        # own writable copies: a Path's arrays are read-only, which numba compiles as another signature
        # (the one warmed at start must be the one the control loop calls)
        self.s = np.array(path.s_m, dtype=float)
        self.north = np.array(path.north_m, dtype=float)
        self.east = np.array(path.east_m, dtype=float)
        self.heading = np.unwrap(np.asarray(path.heading_rad, dtype=float))
        self.kappa = np.asarray(path.curvature_1pm, dtype=float)
        self.speed = np.maximum(np.asarray(path.speed_mps, dtype=float), min_speed_mps)
        self.length = float(self.s[-1])
        self.window_m = window_m
        # one table, one search per query: (north, east, heading, curvature, speed)
        self._table = np.stack([self.north, self.east, self.heading, self.kappa, self.speed], axis=1)
        self._dtable = np.diff(self._table, axis=0)
        self._ds = np.diff(self.s)
        self._end = (self.north[-1], self.east[-1], self.heading[-1])
        self._cos_end, self._sin_end = math.cos(self._end[2]), math.sin(self._end[2])

    def sample(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(north, east, heading (unwrapped along the path), curvature, speed) at arc lengths s.

        Beyond the end the path continues straight along the final heading at the final speed.
        """
        s = np.asarray(s, dtype=float)
        sc = np.clip(s, self.s[0], self.length)
        i = np.clip(np.searchsorted(self.s, sc, side="right") - 1, 0, len(self.s) - 2)
        f = (sc - self.s[i]) / self._ds[i]
        v = self._table[i] + f[..., None] * self._dtable[i]
        n, e, h, k, sp = v[..., 0], v[..., 1], v[..., 2], v[..., 3], v[..., 4]
        beyond = s - sc
        if np.any(beyond > 0):
            n = n + beyond * self._cos_end
            e = e + beyond * self._sin_end
            k = np.where(beyond > 0, 0.0, k)
        return n, e, h, k, sp

    def project(self, north: float, east: float, s_hint: float | None) -> tuple[float, float, float]:
        """(s, cross_track_error (+ = starboard, as Path.project), path heading) of the closest
        point; with `s_hint` only within +-window_m of it (keeps the right branch of a figure eight)."""
        if s_hint is None:
            p = self.path.project(north, east)
            s, cte, hdg = p.s_m, p.cross_track_error_m, p.heading_rad
        else:
            lo = max(0, int(np.searchsorted(self.s, min(s_hint, self.length) - self.window_m)) - 1)
            hi = min(len(self.s) - 1, int(np.searchsorted(self.s, s_hint + self.window_m)) + 1)
            hi = max(hi, lo + 1)
            # canonical argument types: one compiled signature, warmed at start (a new one compiles in the loop)
            s, cte, hdg = _project_window(float(north), float(east), self.north, self.east, self.s, self._ds,
                                          self.heading, self._dtable, int(lo), int(hi))
            hdg = wrap_angle(hdg)
        if s >= self.length - 1e-9:  # past the end: along-track beyond the last point
            c, sn = self._cos_end, self._sin_end
            dn, de = north - self.north[-1], east - self.east[-1]
            along = c * dn + sn * de
            if along > 0:
                s = self.length + along
                cte = -sn * dn + c * de
        return s, cte, hdg


def _project_window_py(north, east, pn, pe, ps, ds, heading, dtable, lo, hi):  # type: ignore[no-untyped-def]
    """Closest point to (north, east) on the polyline segments lo .. hi-1: (s, signed distance
    (+ = starboard), heading, not wrapped). Numba-compiled: every controller step calls it."""
    best, j_best, t_best, q_nb, q_eb = math.inf, lo, 0.0, 0.0, 0.0
    for i in range(lo, hi):
        d_n = dtable[i, 0]
        d_e = dtable[i, 1]
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
    cross = dtable[j_best, 0] * q_eb - dtable[j_best, 1] * q_nb
    cte = dist if cross >= 0 else -dist
    return ps[j_best] + t_best * ds[j_best], cte, heading[j_best] + t_best * dtable[j_best, 2]


_project_window = njit(_project_window_py)


def make_status(t: float, controller: str, cte: float, heading_error: float, state: VesselState,
                speed_ref: float, progress: float, solve_time_ms: float = float("nan"),
                status: str = "ok", failures: int = 0,
                predicted: tuple[np.ndarray, np.ndarray] | None = None) -> ControllerStatus:
    pn: tuple[float, ...] = ()
    pe: tuple[float, ...] = ()
    if predicted is not None:
        pn = tuple(float(v) for v in predicted[0])
        pe = tuple(float(v) for v in predicted[1])
    return ControllerStatus(stamp_s=t, controller=controller, cross_track_error_m=float(cte),
                            heading_error_rad=float(heading_error), speed_mps=state.speed_mps,
                            speed_ref_mps=float(speed_ref), progress_m=float(progress),
                            solve_time_ms=float(solve_time_ms), status=status, failures=failures,
                            predicted_north_m=pn, predicted_east_m=pe)


def state_is_finite(state: VesselState) -> bool:
    return all_finite(*state.as_array_tuple())
