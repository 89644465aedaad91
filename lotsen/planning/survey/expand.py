"""A survey as route nodes: each line with its lead-in and lead-out (the turnaround distance), and
the turns between lines as Dubins paths at the pattern's turn radius, cut into nodes every quarter
turn; the cubic planner then plans them like any route (seed section 3.4), so turns are part of
the spline plan and the lines are straight legs at the line speed.

Everything that can be checked before planning is checked here and named in survey terms: a lead-in
or a turn that leaves the navigable water says which line and what to change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString, Point, Polygon

from lotsen.errors import ConfigError
from lotsen.planning.dubins import dubins_waypoints, dubins_words
from lotsen.planning.route import HarbourNode, RouteNode
from lotsen.planning.survey.lines import SurveyLine, survey_lines
from lotsen.planning.survey.pattern import SurveyPattern

#: turn nodes every quarter turn: the cubic between two of them is within 11 % of the arc's length
#: (the planner's length bound is 15 %)
TURN_NODE_RAD = math.pi / 2
#: nodes closer than this are one node (lotsen.planning.route.DUPLICATE_TOL_M is 5 cm)
NODE_GAP_M = 0.3


@dataclass(frozen=True)
class SurveyPlan:
    """The lines in flying order, the route nodes that fly them, and for each line the indices in
    `nodes` of its first and last node (its lead-in and lead-out where it has them)."""

    pattern: SurveyPattern
    polygon: tuple[tuple[float, float], ...] | None
    lines: tuple[SurveyLine, ...]
    nodes: tuple[RouteNode, ...]
    line_nodes: tuple[tuple[int, int], ...]

    @property
    def line_length_m(self) -> float:
        return float(sum(ln.length_m for ln in self.lines))


def survey_polygon(pattern: SurveyPattern, free) -> Polygon:
    """The polygon the lines cover: the pattern's, else the navigable water shrunk so that the lead-ins,
    lead-outs and turns fit inside it (its largest part)."""
    if pattern.polygon is not None:
        return Polygon(pattern.polygon)
    r = pattern.turn_radius()
    room = pattern.margin_m + pattern.turnaround_m + (2.0 if pattern.spacing_m < 2.0 * r else 1.0) * r
    inner = free.buffer(-room, join_style="mitre")
    parts = [g for g in getattr(inner, "geoms", [inner]) if isinstance(g, Polygon) and not g.is_empty]
    if not parts:
        raise ConfigError(f"survey: the navigable area leaves no room for lines: the boat needs {room:.1f} m from "
                          "its edge to run in and turn (margin, turnaround and turn radius); draw a survey polygon "
                          "or use a shorter turnaround")
    return max(parts, key=lambda g: g.area)


def _dubins_nodes(start: tuple[float, float, float], goal: tuple[float, float, float], radius_m: float,
                  safe, what: str) -> list[tuple[float, float, float]]:
    """Poses between start and goal (goal included) along the shortest Dubins path that stays in
    `safe`; ConfigError naming `what` when none does."""
    words = dubins_words(start, goal, radius_m)
    first_miss = None
    for _, word, params in words:
        fine = dubins_waypoints(start, word, params, radius_m, max_turn_rad=math.radians(5.0), min_gap_m=0.0)
        track = LineString([(start[0], start[1])] + [(p[0], p[1]) for p in fine])
        if safe.covers(track):
            return dubins_waypoints(start, word, params, radius_m, max_turn_rad=TURN_NODE_RAD, min_gap_m=NODE_GAP_M)
        if first_miss is None:
            outside = track.difference(safe)
            p = outside.representative_point() if not outside.is_empty else Point(start[0], start[1])
            first_miss = (p.x, p.y)
    n, e = first_miss if first_miss else (start[0], start[1])
    raise ConfigError(f"survey: {what} leaves the navigable water (near north {n:.1f}, east {e:.1f}): a turn of radius "
                      f"{radius_m:.2f} m does not fit there; use a shorter turnaround, draw the survey polygon further "
                      "inside the area, or widen the area")


def expand_survey(pattern: SurveyPattern, harbour: HarbourNode, free, area: Polygon | None = None) -> SurveyPlan:
    """The route nodes of `pattern` from `harbour`, inside the navigable water `free` (shapely); the
    survey polygon must lie inside `area` (the navigable area; obstacles inside it cut the lines).
    ConfigError naming the polygon, line, lead-in or turn that does not fit."""
    if pattern.polygon is not None and area is not None:
        poly = Polygon(pattern.polygon)
        outside = poly.difference(area)
        if outside.area > 1e-3 * max(poly.area, 1.0):
            p = outside.representative_point()
            raise ConfigError(f"survey.polygon: {outside.area:.1f} m^2 of it lies outside the navigable water (e.g. at "
                              f"north {p.x:.1f}, east {p.y:.1f}); draw the survey polygon inside the area")
    safe = free.buffer(-(pattern.margin_m + 1e-3), quad_segs=16)
    polygon = survey_polygon(pattern, free) if pattern.lines is None else None
    lines = survey_lines(pattern, polygon, safe, (harbour.north_m, harbour.east_m))
    v = pattern.speed_mps
    radius = pattern.turn_radius()
    T = pattern.turnaround_m
    nodes: list[RouteNode] = []
    line_nodes: list[tuple[int, int]] = []
    pose = (harbour.north_m, harbour.east_m, harbour.heading_rad)

    def add(n: float, e: float, psi: float) -> None:
        if nodes and math.hypot(n - nodes[-1].north_m, e - nodes[-1].east_m) < NODE_GAP_M:
            nodes[-1] = RouteNode(round(n, 4), round(e, 4), psi, v)   # the later pose wins
            return
        nodes.append(RouteNode(round(n, 4), round(e, 4), psi, v))

    for k, line in enumerate(lines):
        h = line.heading_rad
        u = np.array([math.cos(h), math.sin(h)])
        start, end = np.asarray(line.start, float), np.asarray(line.end, float)
        lead_in = start - T * u
        lead_out = end + T * u
        name = f"line {k + 1}"
        for what, p in (("lead-in", lead_in), ("lead-out", lead_out)):
            if not safe.covers(Point(*p)):
                raise ConfigError(f"survey: {name}'s {what} at north {p[0]:.1f}, east {p[1]:.1f} is outside the navigable "
                                  f"water with the margin {pattern.margin_m:g} m; use a shorter turnaround "
                                  f"(now {T:g} m) or draw the survey polygon further inside the area")
        goal = (float(lead_in[0]), float(lead_in[1]), h)
        if math.hypot(goal[0] - pose[0], goal[1] - pose[1]) >= NODE_GAP_M:
            what = f"the way from the harbour to {name}" if k == 0 else f"the turn from line {k} to {name}"
            for n, e, psi in _dubins_nodes(pose, goal, radius, safe, what)[:-1]:
                add(n, e, psi)
        first = len(nodes)
        add(goal[0], goal[1], h)
        first = min(first, len(nodes) - 1)
        # the line's own ends lie on the straight lead-in -> lead-out leg; where an obstacle splits the
        # line, the ends of the pieces are nodes and the planner detours between them
        for j, (a, b) in enumerate(line.pieces):
            if j > 0:
                add(a[0], a[1], h)
            if j < len(line.pieces) - 1:
                add(b[0], b[1], h)
        add(float(lead_out[0]), float(lead_out[1]), h)
        line_nodes.append((first, len(nodes) - 1))
        pose = (float(lead_out[0]), float(lead_out[1]), h)
    return SurveyPlan(pattern, tuple(map(tuple, polygon.exterior.coords[:-1])) if polygon is not None else None,
                      tuple(lines), tuple(nodes), tuple(line_nodes))
