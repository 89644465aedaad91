"""How a flown track kept a survey's lines: where each line lies on the planned path, and per line
the cross-track error on it, the distance after the turn until the boat is within a tolerance of
the line, and the share of the mission's time spent on lines (issue 48 item 2).

A line's span is its surveyed pieces' arc lengths on the path (the projection of their ends, searched
forwards, so a crosshatch that crosses the first pass keeps its order); the turn ends where the line's
lead-in starts (the turnaround before the line). Pure: arrays in, numbers out; the harnesses and the
live run's log analysis call it on the true track.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lotsen.model.polyline import project_window, search_window

#: the tolerance the report's settle distance is measured to (issue 48: within 5 cm after the turn)
SETTLE_TOLERANCE_M = 0.05


@dataclass(frozen=True)
class LineSpan:
    """Where survey line `index` (1-based, flying order) lies on the path: `pieces_s_m` the arc-length
    intervals of its surveyed pieces, `turn_end_s_m` where the turn before it ends (its lead-in starts)."""

    index: int
    pass_index: int
    pieces_s_m: tuple[tuple[float, float], ...]
    turn_end_s_m: float

    @property
    def start_s_m(self) -> float:
        return self.pieces_s_m[0][0]

    @property
    def end_s_m(self) -> float:
        return self.pieces_s_m[-1][1]

    @property
    def length_m(self) -> float:
        return float(sum(b - a for a, b in self.pieces_s_m))


def line_spans(route: Any, path: Any) -> tuple[LineSpan, ...]:
    """The spans of `route.survey_lines` on `path` (the path planned from the route); () for a route
    without survey lines."""
    lines = getattr(route, "survey_lines", ()) or ()
    if not lines:
        return ()
    turnaround = float(route.survey.turnaround_m) if route.survey is not None else 0.0
    heading = np.unwrap(np.asarray(path.heading_rad, dtype=float))
    s_path = np.asarray(path.s_m, dtype=float)
    pn, pe = np.asarray(path.north_m, dtype=float), np.asarray(path.east_m, dtype=float)
    s = 0.0
    out = []
    for k, line in enumerate(lines):
        pieces = []
        for a, b in line.pieces:
            ends = []
            for n, e in (a, b):
                # forwards from the last end only: the window [s, s + the rest of the path]
                half = 0.5 * (s_path[-1] - s) + 1.0
                lo, hi = search_window(s_path, s + half, half)
                s_end, _, _, _ = project_window(float(n), float(e), pn, pe, s_path, heading, lo, hi)
                s = max(s, float(s_end))
                ends.append(s)
            pieces.append((ends[0], ends[1]))
        previous_end = out[-1].end_s_m if out else 0.0
        out.append(LineSpan(index=k + 1, pass_index=int(getattr(line, "pass_index", 0)), pieces_s_m=tuple(pieces),
                            turn_end_s_m=max(previous_end, pieces[0][0] - turnaround)))
    return tuple(out)


@dataclass(frozen=True)
class LineKeeping:
    """One line as flown: cross-track RMS and max on its pieces (m), the distance (m, along the path)
    from the end of the turn before it until the boat stayed within `SETTLE_TOLERANCE_M` for the rest
    of the line (0: never outside; NaN: never within), the time on it (s)."""

    index: int
    cross_track_rms_m: float
    cross_track_max_m: float
    settle_distance_m: float
    time_on_line_s: float

    def as_dict(self) -> dict[str, float]:
        return {"line": self.index, "cross_track_rms_m": round(self.cross_track_rms_m, 4),
                "cross_track_max_m": round(self.cross_track_max_m, 4),
                "settle_distance_m": round(self.settle_distance_m, 3) if math.isfinite(self.settle_distance_m) else None,
                "time_on_line_s": round(self.time_on_line_s, 2)}


@dataclass(frozen=True)
class SurveyKeeping:
    """The lines of one survey as flown, and the figures over all of them."""

    lines: tuple[LineKeeping, ...]
    mission_time_s: float
    tolerance_m: float = SETTLE_TOLERANCE_M

    @property
    def time_on_lines_s(self) -> float:
        return float(sum(ln.time_on_line_s for ln in self.lines))

    @property
    def share_on_lines(self) -> float:
        return self.time_on_lines_s / self.mission_time_s if self.mission_time_s > 0 else math.nan

    def summary(self) -> dict[str, Any]:
        """The report's `survey` section: the figures over all lines, then each line's."""
        flown = [ln for ln in self.lines if ln.time_on_line_s > 0]
        if not flown:
            return {"lines": len(self.lines), "lines_flown": 0}
        settle = [ln.settle_distance_m for ln in flown]
        return {"lines": len(self.lines), "lines_flown": len(flown),
                "cross_track_rms_m": round(max(ln.cross_track_rms_m for ln in flown), 4),
                "cross_track_rms_all_lines_m": round(_pooled_rms(flown), 4),
                "cross_track_max_m": round(max(ln.cross_track_max_m for ln in flown), 4),
                "settle_tolerance_m": self.tolerance_m,
                "settle_distance_max_m": round(max(settle), 3) if all(map(math.isfinite, settle)) else None,
                "time_on_lines_s": round(self.time_on_lines_s, 1), "mission_time_s": round(self.mission_time_s, 1),
                "share_on_lines": round(self.share_on_lines, 4),
                "per_line": [ln.as_dict() for ln in self.lines]}


def _pooled_rms(lines: list[LineKeeping]) -> float:
    w = np.array([ln.time_on_line_s for ln in lines])
    r = np.array([ln.cross_track_rms_m for ln in lines])
    return float(np.sqrt(np.sum(w * r**2) / np.sum(w)))


def track_on_path(path: Any, north_m: np.ndarray, east_m: np.ndarray, window_m: float = 3.0
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Arc length and signed cross-track error (+ starboard) of each track sample on `path`, each one
    searched near the previous sample's (the one path projection, `lotsen.model.polyline`)."""
    s_path = np.asarray(path.s_m, dtype=float)
    pn, pe = np.asarray(path.north_m, dtype=float), np.asarray(path.east_m, dtype=float)
    heading = np.unwrap(np.asarray(path.heading_rad, dtype=float))
    s_out = np.empty(len(north_m))
    cte = np.empty(len(north_m))
    hint = 0.0
    for i, (n, e) in enumerate(zip(np.asarray(north_m, float), np.asarray(east_m, float))):
        lo, hi = search_window(s_path, hint, window_m)
        s, d, _, _ = project_window(float(n), float(e), pn, pe, s_path, heading, lo, hi)
        hint = max(hint, float(s))  # progress only forwards: the window never slides back onto a crossed line
        s_out[i], cte[i] = s, d
    return s_out, cte


def line_keeping(spans: tuple[LineSpan, ...], t_s: np.ndarray, s_m: np.ndarray, cross_track_m: np.ndarray,
                 mission_time_s: float, tolerance_m: float = SETTLE_TOLERANCE_M) -> SurveyKeeping:
    """Per line, from a track given as time, arc length on the path and cross-track error (true, in
    time order; `track_on_path`): the figures of `LineKeeping` and the time on lines over
    `mission_time_s` (AUTO until the route's end)."""
    t = np.asarray(t_s, dtype=float)
    s = np.asarray(s_m, dtype=float)
    e = np.abs(np.asarray(cross_track_m, dtype=float))
    out = []
    for span in spans:
        on = np.zeros(len(t), dtype=bool)
        time_on = 0.0
        for a, b in span.pieces_s_m:
            inside = (s >= a) & (s <= b)
            on |= inside
            if np.any(inside):
                idx = np.flatnonzero(inside)
                time_on += float(t[idx[-1]] - t[idx[0]])
        if not np.any(on):
            out.append(LineKeeping(span.index, math.nan, math.nan, math.nan, 0.0))
            continue
        # from the turn's end to the line's end: the last sample outside the tolerance sets the settle distance
        run = (s >= span.turn_end_s_m) & (s <= span.end_s_m)
        outside = np.flatnonzero(run & (e > tolerance_m))
        if not outside.size:
            settle = 0.0
        elif outside[-1] >= np.flatnonzero(run)[-1]:
            settle = math.nan
        else:
            settle = float(s[outside[-1] + 1] - span.turn_end_s_m)
        out.append(LineKeeping(span.index, float(np.sqrt(np.mean(e[on] ** 2))), float(np.max(e[on])), max(settle, 0.0)
                               if math.isfinite(settle) else settle, time_on))
    return SurveyKeeping(tuple(out), float(mission_time_s), tolerance_m)
