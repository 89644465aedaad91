"""The planned path the controller follows: evenly spaced points with heading, curvature and speed.

Headings are radians NED (0 = north, positive clockwise towards east). The cross-track error of
``Path.project`` is positive when the vessel is to starboard (right) of the path.

Where a position lies on a path is computed in one place, `lotsen.model.polyline`:
`Path.project` and the controllers' `lotsen.control.PathReference.project` both call it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from lotsen.errors import ConfigError
from lotsen.model.angles import wrap_angle
from lotsen.model.polyline import project_window, search_window

_FIELDS = ("north_m", "east_m", "heading_rad", "curvature_1pm", "speed_mps", "s_m")


@dataclass(frozen=True, slots=True)
class SegmentMetrics:
    """How one planned segment meets the constraints (seed eqs. 40g-h, obstacles) and what it cost."""

    label: str                  # "segment 2 (nodes[1] -> nodes[2])", detour parts add "part j"
    length_m: float
    straight_m: float
    length_ratio: float         # length / straight, bounded by PlannerConfig.length_ratio_max (40g)
    max_curvature_1pm: float    # bounded by 1 / min_turn_radius_m (40h)
    min_clearance_m: float      # distance to the nearest non-navigable water (inf if none near)
    candidates_tried: int
    cost: float                 # V of seed eq. (41) (+ optional bending-energy term)
    s_start_m: float
    s_end_m: float
    detour: bool = False        # True for parts of a detour the planner inserted around obstacles


@dataclass(frozen=True, slots=True)
class PathPoint:
    """The path at arc length s_m (floats, or arrays when sampled at an array of s)."""

    north_m: Any
    east_m: Any
    heading_rad: Any
    curvature_1pm: Any
    speed_mps: Any
    s_m: Any


@dataclass(frozen=True, slots=True)
class Projection:
    """Closest point of the path to a position.

    cross_track_error_m > 0: the position is to starboard (right) of the path direction.
    index: the path segment [index, index + 1] containing the foot point.
    """

    s_m: float
    cross_track_error_m: float
    index: int
    heading_rad: float


@dataclass(frozen=True, eq=False)
class Path:
    """Per-point arrays (same length n >= 2), arc length ``s_m`` strictly increasing from 0."""

    north_m: np.ndarray
    east_m: np.ndarray
    heading_rad: np.ndarray
    curvature_1pm: np.ndarray
    speed_mps: np.ndarray
    s_m: np.ndarray
    segments: tuple[SegmentMetrics, ...] = ()
    _heading_unwrapped: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        arrays = {}
        for name in _FIELDS:
            arr = np.ascontiguousarray(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            arrays[name] = arr
            object.__setattr__(self, name, arr)
        n = arrays["s_m"].shape
        if len(n) != 1 or n[0] < 2 or any(a.shape != n for a in arrays.values()):
            raise ConfigError(f"path: all point arrays must be 1-D of equal length >= 2, got "
                              + ", ".join(f"{k} {v.shape}" for k, v in arrays.items()))
        if not all(np.isfinite(a).all() for a in arrays.values()):
            raise ConfigError("path: arrays contain NaN or infinite values")
        if np.any(np.diff(arrays["s_m"]) <= 0):
            raise ConfigError("path: s_m must be strictly increasing")
        object.__setattr__(self, "_heading_unwrapped", np.unwrap(arrays["heading_rad"]))

    # -- queries used by the controller ------------------------------------------------------
    @property
    def length_m(self) -> float:
        return float(self.s_m[-1] - self.s_m[0])

    def duration_s(self, min_speed_mps: float = 0.05) -> float:
        """Time to follow the path at its speed reference (each step at the mean of its ends' speeds,
        at least `min_speed_mps`: the start from rest and the stop at the end take finite time)."""
        ds = np.diff(self.s_m)
        v_mid = np.maximum(0.5 * (self.speed_mps[1:] + self.speed_mps[:-1]), min_speed_mps)
        return float(np.sum(ds / v_mid))

    def __len__(self) -> int:
        return int(self.s_m.shape[0])

    def sample(self, s_m: float | np.ndarray) -> PathPoint:
        """Linear interpolation at arc length s (clipped to [0, length]); scalar or array s."""
        s = np.clip(np.asarray(s_m, dtype=float), self.s_m[0], self.s_m[-1])
        out = [np.interp(s, self.s_m, arr) for arr in
               (self.north_m, self.east_m, self._heading_unwrapped, self.curvature_1pm, self.speed_mps)]
        out[2] = wrap_angle(out[2])  # interpolate unwrapped, so +179 deg -> -179 deg passes through 180
        if s.ndim == 0:
            return PathPoint(*(float(v) for v in out), s_m=float(s))
        return PathPoint(*out, s_m=s)

    def project(self, north_m: float, east_m: float, s_hint_m: float | None = None,
                window_m: float | None = None) -> Projection:
        """Closest point of the path polyline to (north, east).

        Without ``s_hint_m`` the whole path is searched. With it, only s in
        [s_hint - window, s_hint + window] (window default 10 m), which keeps the projection on the
        right branch where the path crosses or passes close to itself (figure eight).
        """
        lo, hi = 0, len(self) - 1
        if s_hint_m is not None:
            lo, hi = search_window(self.s_m, float(s_hint_m), 10.0 if window_m is None else float(window_m))
        s, cte, hdg, i = project_window(float(north_m), float(east_m), self.north_m, self.east_m, self.s_m,
                                        self._heading_unwrapped, lo, hi)
        hdg = float(wrap_angle(hdg))
        return Projection(s_m=float(s), cross_track_error_m=float(cte), index=int(i), heading_rad=hdg)

    # -- serialisation -----------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict (lists of floats, segment metrics as dicts)."""
        out: dict[str, Any] = {"format": "lotsen.path", "version": 1}
        for name in _FIELDS:
            out[name] = getattr(self, name).tolist()
        out["segments"] = [
            {k: (None if isinstance(v, float) and not np.isfinite(v) else v)
             for k, v in asdict(m).items()} for m in self.segments]
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "Path":
        if not isinstance(data, dict) or data.get("format") != "lotsen.path":
            raise ConfigError("path: not a lotsen path (expected 'format': 'lotsen.path')")
        try:
            arrays = {name: np.asarray(data[name], dtype=float) for name in _FIELDS}
        except KeyError as exc:
            raise ConfigError(f"path: missing key {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"path: arrays must be lists of numbers ({exc})") from None
        segs = []
        for i, m in enumerate(data.get("segments", [])):
            try:
                m = {k: (float("inf") if v is None else v) for k, v in m.items()}
                segs.append(SegmentMetrics(**m))
            except TypeError as exc:
                raise ConfigError(f"path.segments[{i}]: {exc}") from None
        return cls(**arrays, segments=tuple(segs))

