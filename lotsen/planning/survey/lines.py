"""Survey lines over a polygon: parallel lines at a spacing and angle, clipped to the navigable
water, in the order the boat flies them (entry corner, alternating directions; a racetrack for a
one-sided sensor; a second pass at 90 deg for a crosshatch).

Each line covers a strip (its swath): `spacing_m` wide centred on it for a sensor that sees both
sides, `spacing_m` wide on one side for a one-sided one. The strips tile the polygon: every point
of the polygon lies in a strip (the lines' extent along their direction is that of the polygon
inside their strip, not only under the line), so a convex polygon is covered edge to edge.

Pure geometry (shapely); no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon, box
from shapely.affinity import affine_transform

from lotsen.errors import ConfigError
from lotsen.planning.survey.pattern import MAX_LINES, SurveyPattern

#: a piece of a line shorter than this is not surveyed (a sliver between an obstacle and the edge)
MIN_PIECE_M = 0.3


@dataclass(frozen=True)
class SurveyLine:
    """One line as flown: `pieces` are the surveyed parts in flying order ((start, end) [north,
    east] pairs; more than one where an obstacle splits the line), `heading_rad` the direction.
    `swath_m` = (port, starboard) width the sensor covers either side of the track. `pass_index`
    0 for the main pass, 1 for the crosshatch."""

    index: int
    pieces: tuple[tuple[tuple[float, float], tuple[float, float]], ...]
    heading_rad: float
    swath_m: tuple[float, float]
    pass_index: int = 0

    @property
    def start(self) -> tuple[float, float]:
        return self.pieces[0][0]

    @property
    def end(self) -> tuple[float, float]:
        return self.pieces[-1][1]

    @property
    def length_m(self) -> float:
        return float(sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in self.pieces))


def _frame(angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """u: along the lines (heading angle_deg, clockwise from north), w: u turned 90 deg to starboard."""
    a = math.radians(angle_deg)
    return np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])


def _to_uw(geom, u: np.ndarray, w: np.ndarray):
    # [north, east] -> [u, w]: a rotation (affine matrix a, b, d, e, xoff, yoff)
    return affine_transform(geom, [u[0], u[1], w[0], w[1], 0.0, 0.0])


def _pieces_along(segment: LineString, safe, u: np.ndarray, direction: int, gap_room_m: float = 0.0
                  ) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The parts of `segment` inside `safe`, ordered and oriented along direction * u. Where an
    obstacle cuts the line, the pieces end `gap_room_m` short of it: the boat needs room to turn
    round the obstacle (the planner detours between the pieces)."""
    cut = segment.intersection(safe)
    parts = [g for g in getattr(cut, "geoms", [cut]) if isinstance(g, LineString) and g.length > 0]
    ends = []
    for g in parts:
        a, b = np.asarray(g.coords[0]), np.asarray(g.coords[-1])
        if direction * float(np.dot(b - a, u)) < 0:
            a, b = b, a
        ends.append([a, b])
    ends.sort(key=lambda ab: direction * float(np.dot(ab[0], u)))
    step = direction * u
    for j in range(len(ends)):
        if j > 0:
            ends[j][0] = ends[j][0] + gap_room_m * step
        if j < len(ends) - 1:
            ends[j][1] = ends[j][1] - gap_room_m * step
    out = []
    for a, b in ends:
        if float(np.dot(b - a, step)) >= MIN_PIECE_M:
            out.append(((round(float(a[0]), 4), round(float(a[1]), 4)), (round(float(b[0]), 4), round(float(b[1]), 4))))
    return out


def interleaved_order(n: int, spacing_m: float, turn_radius_m: float) -> list[int]:
    """The order of n neighbouring lines flown back and forth. Lines closer than a turn's diameter
    would need a bulb turn (out, round and back in: about twice a U-turn's length); then the lines
    are flown in blocks of 2k, k the smallest step with k and k - 1 lines both a diameter apart:
    0, k, 1, k + 1, ..., k - 1, 2k - 1, so every turn in a block is a plain U-turn of k or k - 1
    spacings (one short turn between blocks)."""
    if spacing_m >= 2.0 * turn_radius_m - 1e-9 or n < 4:
        return list(range(n))
    k = math.ceil(2.0 * turn_radius_m / spacing_m - 1e-9) + 1
    order: list[int] = []
    start = 0
    while start < n:
        size = min(2 * k, n - start)
        half = math.ceil(size / 2)
        for j in range(half):
            order.append(start + j)
            if j + half < size:
                order.append(start + half + j)
        start += size
    return order


@dataclass(frozen=True)
class _Strip:
    offset_m: float      # the track's cross position (w)
    low_m: float         # the strip it covers [low, high] in w
    high_m: float
    direction: int       # +1: flown along u, -1: against


def _strips(pattern: SurveyPattern, w_lo: float, w_hi: float, left_first: bool, down_first: bool) -> list[_Strip]:
    """The strips across [w_lo, w_hi] and the order and direction they are flown in."""
    s = pattern.spacing_m
    n = max(1, math.ceil((w_hi - w_lo) / s - 1e-6))
    if n > MAX_LINES:
        raise ConfigError(f"survey: {n} lines at spacing {s:g} m across {w_hi - w_lo:.0f} m, more than a survey may "
                          f"have ({MAX_LINES}); widen the spacing or survey a smaller polygon")
    mid = 0.5 * (w_lo + w_hi)
    lows = [mid + (k - n / 2) * s for k in range(n)]         # the strips, centred on the polygon
    if not left_first:
        lows = lows[::-1]
    first_dir = -1 if down_first else 1
    if pattern.side == "both":
        lows = [lows[k] for k in interleaved_order(n, s, pattern.turn_radius())]
        return [_Strip(lo + s / 2, lo, lo + s, first_dir * (1 if k % 2 == 0 else -1)) for k, lo in enumerate(lows)]
    # one-sided: a track covers the strip on its sensor's side; flying back and forth over
    # neighbouring strips would put the sensor on the wrong side every other line, so the strips
    # are flown as a racetrack: strip k out, strip k + half back (turns half the area wide)
    sigma = 1 if pattern.side == "starboard" else -1          # covered side of a track along +u, in w
    half = math.ceil(n / 2)
    order = []
    for k in range(half):
        order.append((k, first_dir))
        if k + half < n:
            order.append((k + half, -first_dir))
    out = []
    for k, d in order:
        lo = lows[k]
        covers_up = sigma * d > 0                             # the sensor looks towards +w
        out.append(_Strip(lo if covers_up else lo + s, lo, lo + s, d))
    return out


def _first_point(strips: list[_Strip], polygon: Polygon, u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Roughly where the first line starts (for choosing the entry corner nearest a point)."""
    st = strips[0]
    pu = _to_uw(polygon, u, w)
    u0, _, u1, _ = pu.bounds
    along = u0 if st.direction > 0 else u1
    return along * u + st.offset_m * w


def _lines_of_pass(pattern: SurveyPattern, polygon: Polygon, safe, angle_deg: float, pass_index: int,
                   first_index: int, near: np.ndarray | None, entry: int | None) -> list[SurveyLine]:
    u, w = _frame(angle_deg)
    pu = _to_uw(polygon, u, w)
    u_lo, w_lo, u_hi, w_hi = pu.bounds
    corners = [entry] if entry is not None else [0, 1, 2, 3]
    best = None
    for c in corners:   # 0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right (QGroundControl's order)
        strips = _strips(pattern, w_lo, w_hi, left_first=c in (0, 2), down_first=c in (0, 1))
        d = 0.0 if near is None else float(np.hypot(*(_first_point(strips, polygon, u, w) - near)))
        if best is None or d < best[0]:
            best = (d, strips)
    assert best is not None
    s = pattern.spacing_m
    lines: list[SurveyLine] = []
    heading = math.radians(angle_deg)
    for st in best[1]:
        band = box(u_lo - 1.0, st.low_m, u_hi + 1.0, st.high_m)
        inside = pu.intersection(band)
        if inside.is_empty or inside.area < 1e-6:
            continue
        a0, _, a1, _ = inside.bounds
        if a1 - a0 < MIN_PIECE_M:   # the strip holds a sliver of the polygon (a sharp corner): a short line over it
            a0, a1 = 0.5 * (a0 + a1) - MIN_PIECE_M, 0.5 * (a0 + a1) + MIN_PIECE_M
        seg = LineString([tuple(a0 * u + st.offset_m * w), tuple(a1 * u + st.offset_m * w)])
        pieces = _pieces_along(seg, safe, u, st.direction, pattern.turn_radius())
        if not pieces:
            continue
        h = heading if st.direction > 0 else heading + math.pi
        if pattern.side == "both":
            swath = (s / 2, s / 2)
        else:
            swath = (0.0, s) if pattern.side == "starboard" else (s, 0.0)
        lines.append(SurveyLine(first_index + len(lines), tuple(pieces), math.atan2(math.sin(h), math.cos(h)),
                                swath, pass_index))
    return lines


def survey_lines(pattern: SurveyPattern, polygon: Polygon, safe, start_near: tuple[float, float] | None = None
                 ) -> list[SurveyLine]:
    """The lines of `pattern` over `polygon` inside `safe` (the navigable water shrunk by the
    margin), in flying order; the entry corner nearest `start_near` when the pattern gives none.
    ConfigError when not one line fits."""
    if pattern.lines is not None:
        out = []
        for i, (a, b) in enumerate(pattern.lines):
            a_, b_ = np.asarray(a, float), np.asarray(b, float)
            u = (b_ - a_) / float(np.hypot(*(b_ - a_)))
            pieces = _pieces_along(LineString([a, b]), safe, u, 1, pattern.turn_radius())
            if not pieces:
                raise ConfigError(f"survey.lines[{i}]: the line lies outside the navigable water (with the margin "
                                  f"{pattern.margin_m:g} m); move it into open water")
            out.append(SurveyLine(len(out), tuple(pieces), math.atan2(u[1], u[0]),
                                  (pattern.spacing_m / 2, pattern.spacing_m / 2)))
        return out
    near = None if start_near is None else np.asarray(start_near, float)
    lines = _lines_of_pass(pattern, polygon, safe, pattern.angle_deg, 0, 0, near, pattern.entry)
    if pattern.crosshatch and lines:
        lines += _lines_of_pass(pattern, polygon, safe, pattern.angle_deg + 90.0, 1, len(lines),
                                np.asarray(lines[-1].end), None)
    if not lines:
        raise ConfigError(f"survey: not one line fits: the polygon ({polygon.area:.1f} m^2) has no water at least "
                          f"{MIN_PIECE_M:g} m long inside the navigable area and clear of obstacles by the margin "
                          f"{pattern.margin_m:g} m")
    if len(lines) > MAX_LINES:
        raise ConfigError(f"survey: {len(lines)} lines, more than a survey may have ({MAX_LINES})")
    return lines


def strip_of(line: SurveyLine, piece: tuple[tuple[float, float], tuple[float, float]]) -> Polygon:
    """The water one piece of a line covers (its swath either side), as a polygon [north, east]."""
    a, b = np.asarray(piece[0], float), np.asarray(piece[1], float)
    u = (b - a) / max(float(np.hypot(*(b - a))), 1e-9)
    w = np.array([-u[1], u[0]])                # starboard of the direction flown
    port, stbd = line.swath_m
    ring = [a - port * w, b - port * w, b + stbd * w, a + stbd * w]
    return Polygon([tuple(p) for p in ring])


def coverage_polygon(lines: list[SurveyLine]):
    """The water all lines cover together (their strips' union)."""
    return shapely.union_all([strip_of(ln, p) for ln in lines for p in ln.pieces])
