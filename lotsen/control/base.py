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
from lotsen.model.angles import all_finite, wrap_angle
from lotsen.model.polyline import project_window, search_window


@runtime_checkable
class PathFollower(Protocol):
    """Follows a planned `lotsen.planning.Path` (cross-track, heading and speed; seed section 3.5)."""

    name: str

    def reset(self, path: Any, progress_m: float = 0.0) -> None:
        """Follow `path` from arc length `progress_m` on: 0 for a new path; where the vessel is
        (the failed controller's `progress_m`) when a fallback takes over mid-path."""
        ...

    def update(self, t: float, state: VesselState) -> tuple[ThrustCommand, ControllerStatus]: ...

    @property
    def progress_m(self) -> float:
        """Arc length of the vessel's last localisation on the path (`PathReference.project`)."""
        ...

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

    def project(self, north: float, east: float, s_hint: float) -> tuple[float, float, float]:
        """(s, cross_track_error (+ = starboard, as Path.project), path heading) of the closest point
        within +-window_m of `s_hint`, the last known progress (a global search would jump to the
        other branch where a figure eight crosses itself); a vessel ahead of the window is caught up
        window_m per call. The one path projection of `lotsen.planning.path` (`project_window`)."""
        lo, hi = search_window(self.s, float(s_hint), self.window_m)
        # canonical argument types: one compiled signature, warmed at start (a new one compiles in the loop)
        s, cte, hdg, _i = project_window(float(north), float(east), self.north, self.east, self.s, self.heading,
                                         int(lo), int(hi))
        hdg = wrap_angle(hdg)
        if s >= self.length - 1e-9:  # past the end: along-track beyond the last point
            c, sn = self._cos_end, self._sin_end
            dn, de = north - self.north[-1], east - self.east[-1]
            along = c * dn + sn * de
            if along > 0:
                s = self.length + along
                cte = -sn * dn + c * de
        return s, cte, hdg


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


@dataclass(frozen=True)
class SeaLevelConfig:
    """How a controller tells a sea from flat water (issue 46; docs/control.md "Waves"): from the
    wave motion the estimator separated out (`VesselState.wave_motion`), its RMS over
    `time_constant_s`. The displacement beyond `deadband_m` by `ref_m`, or the heading's beyond
    `heading_deadband_rad` by `heading_ref_rad`, whichever is larger, is the sea level 0..1. The
    heading tells the two apart 20-30 x (Hs 3 cm 0.25-0.33 deg, flat water <= 0.013 deg with the
    estimator's start), the displacement not in Hs 3 cm (0.6-0.8 mm; the estimator's start in flat
    water 0.6 mm)."""

    deadband_m: float = 0.001
    ref_m: float = 0.005
    heading_deadband_rad: float = math.radians(0.05)
    heading_ref_rad: float = math.radians(0.2)
    time_constant_s: float = 5.0


class SeaLevel:
    """The sea level (0 flat water .. 1) of `SeaLevelConfig`, updated once per control step."""

    def __init__(self, config: SeaLevelConfig, dt_s: float) -> None:
        self.config = config
        self._a = min(1.0, dt_s / config.time_constant_s)
        self.reset()

    def reset(self) -> None:
        self._ms = 0.0  # mean square of the displacement (north, east)
        self._heading_ms = 0.0
        self.level = 0.0

    def update(self, wave_motion: tuple[float, float, float]) -> float:
        """The sea level after one more step's wave motion (north m, east m, heading rad); a
        non-finite sample leaves it as it was."""
        if not all(math.isfinite(w) for w in wave_motion):
            return self.level
        c, a = self.config, self._a
        n, e, h = wave_motion
        self._ms += a * (n * n + e * e - self._ms)
        self._heading_ms += a * (h * h - self._heading_ms)
        f = max((math.sqrt(0.5 * self._ms) - c.deadband_m) / c.ref_m,
                (math.sqrt(self._heading_ms) - c.heading_deadband_rad) / c.heading_ref_rad)
        self.level = min(1.0, max(0.0, f))
        return self.level
