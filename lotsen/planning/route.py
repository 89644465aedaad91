"""The route an operator draws: harbour, nodes N_k (seed eqs. 36-37), navigable area, obstacles.

All positions are local NED metres [north, east]; headings are radians (0 = north, clockwise).
Pure data plus geometric validation (shapely); loading and saving live in ``lotsen.planning.io``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import shapely
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

from lotsen.errors import ConfigError

if TYPE_CHECKING:
    from lotsen.planning.survey.pattern import SurveyPattern  # the module, not the package: no circle

Forbidden = Literal["inside", "outside"]

#: Two consecutive nodes closer than this are "the same node" (an input error, not a segment).
DUPLICATE_TOL_M = 0.05

# Physical limits of a route for a 1 m model ship, the one place for them: the route files of
# the CLI (`lotsen plan`, `lotsen run`'s config route), the page's drawn and imported routes and
# the supervisor's routes all pass `validate_route`. Beyond them a number is a typo or hostile.
#: every node and polygon vertex within this distance (north and east) of the local origin;
#: the area's extent follows (at most twice this)
MAX_COORDINATE_M = 2000.0
#: node to node (a leg longer than this on a basin is a misplaced node)
MAX_LEG_M = 2000.0
#: |heading| in a route (degrees in the files): one turn either way
MAX_HEADING_RAD = 2.0 * math.pi
#: a node's speed set-point (the boat makes ~2 m/s at most)
MAX_SPEED_MPS = 5.0
#: a moving node's smallest speed set-point: 0 means "at rest here"; below 5 cm/s a leg takes
#: hours (1e-9 m/s planned a 26-million-year route) and no controller holds such a speed
MIN_SPEED_MPS = 0.05


@dataclass(frozen=True, slots=True)
class HarbourNode:
    """Where the route starts (and return-to-harbour ends); its speed is always 0 (seed §3.6)."""

    north_m: float
    east_m: float
    heading_rad: float

    @property
    def speed_mps(self) -> float:
        return 0.0


@dataclass(frozen=True, slots=True)
class RouteNode:
    """A route node N_k = [P_x, P_y, rho, v_abs] (seed eq. 36): position, heading, speed through it."""

    north_m: float
    east_m: float
    heading_rad: float
    speed_mps: float


@dataclass(frozen=True, slots=True)
class Region:
    """A polygon the operator drew; ``forbidden`` says whether its inside or outside is not navigable."""

    polygon: tuple[tuple[float, float], ...]  # [north, east] vertices, ring not closed
    forbidden: Forbidden = "inside"


@dataclass(frozen=True, slots=True)
class GeoOrigin:
    """Geodetic origin of the local NED frame (for GeoJSON import/export)."""

    lat_deg: float
    lon_deg: float
    height_m: float = 0.0


@dataclass(frozen=True)
class Route:
    """Harbour, then nodes in order; ``area`` is the navigable polygon (outside forbidden) or None.

    A survey route carries its pattern (`survey`) and lines (`survey_lines`, in flying order) beside
    the nodes made from them (`lotsen.planning.survey.expand_survey`); its files give the pattern,
    not the nodes."""

    harbour: HarbourNode
    nodes: tuple[RouteNode, ...]
    area: tuple[tuple[float, float], ...] | None = None
    obstacles: tuple[Region, ...] = ()
    origin: GeoOrigin | None = None
    survey: "SurveyPattern | None" = None
    survey_lines: tuple[Any, ...] = ()
    _free: object = field(default=None, init=False, repr=False, compare=False)

    def all_nodes(self) -> list[RouteNode]:
        """Harbour (as a node with speed 0) followed by the route nodes: the planner's node list."""
        h = self.harbour
        return [RouteNode(h.north_m, h.east_m, h.heading_rad, 0.0), *self.nodes]

    @staticmethod
    def node_label(k: int) -> str:
        """Name of planner node k as the operator sees it in the YAML: 'harbour' or 'nodes[i]'."""
        return "harbour" if k == 0 else f"nodes[{k - 1}]"

    def free_region(self):
        """Navigable water as a shapely geometry: area ∩ outside-forbidden regions − inside-forbidden ones.

        Without an area, a large box around everything stands in for open water.
        """
        if self._free is None:
            object.__setattr__(self, "_free", _free_region(self))
        return self._free


def _free_region(route: Route):
    if route.area is not None:
        free = Polygon(route.area)
    else:
        pts = [(n.north_m, n.east_m) for n in route.all_nodes()]
        if route.survey is not None:
            pts.extend(route.survey.polygon or [p for line in route.survey.lines or () for p in line])
        for r in route.obstacles:
            pts.extend(r.polygon)
        # a box 1 km beyond every point (buffering the envelope broke for collinear points: the
        # envelope of a straight route is a degenerate polygon whose mitred buffer was a triangle)
        n0, e0, n1, e1 = shapely.MultiPoint(pts).bounds
        free = box(n0 - 1000.0, e0 - 1000.0, n1 + 1000.0, e1 + 1000.0)
    blocked = []
    for r in route.obstacles:
        poly = Polygon(r.polygon)
        if r.forbidden == "outside":
            free = free.intersection(poly)
        else:
            blocked.append(poly)
    if blocked:
        free = free.difference(unary_union(blocked))
    return free


def check_polygon(label: str, ring: tuple[tuple[float, float], ...]) -> Polygon:
    if len(ring) < 3:
        raise ConfigError(f"{label}: a polygon needs at least 3 vertices, got {len(ring)}")
    for j, p in enumerate(ring):
        if len(p) != 2 or not all(math.isfinite(c) for c in p):
            raise ConfigError(f"{label}[{j}]: vertex must be two finite numbers [north, east], got {list(p)}")
    poly = Polygon(ring)
    if not poly.is_valid:
        reason = shapely.is_valid_reason(poly)
        kind = "self-intersecting" if "Self-intersection" in reason or "Ring" in reason else "invalid"
        raise ConfigError(f"{label}: polygon is {kind} ({reason})")
    if poly.area <= 1e-9:
        raise ConfigError(f"{label}: polygon has zero area")
    return poly


def check_route_limits(route: Route) -> None:
    """The physical limits above (finite numbers assumed): ConfigError naming the node or vertex,
    the value and the limit. Cheap: runs before any geometry."""
    def coordinate(where: str, north: float, east: float) -> None:
        for name, v in (("north", north), ("east", east)):
            if not abs(v) <= MAX_COORDINATE_M:
                raise ConfigError(f"{where}.{name}: {v:g} m is outside [-{MAX_COORDINATE_M:g}, {MAX_COORDINATE_M:g}] m "
                                  "(a route stays within 2 km of its origin)")

    nodes = route.all_nodes()
    for k, n in enumerate(nodes):
        where = "harbour" if k == 0 else f"nodes[{k - 1}]"
        coordinate(where, n.north_m, n.east_m)
        if not abs(n.heading_rad) <= MAX_HEADING_RAD + 1e-9:
            raise ConfigError(f"{where}.heading_deg: {math.degrees(n.heading_rad):g} deg is outside "
                              f"[-{math.degrees(MAX_HEADING_RAD):g}, {math.degrees(MAX_HEADING_RAD):g}] deg")
        if k > 0:
            speed = getattr(n, "speed_mps", 0.0)
            if not speed <= MAX_SPEED_MPS:
                raise ConfigError(f"{where}.speed_mps: {speed:g} m/s is more than {MAX_SPEED_MPS:g} m/s")
            if 0.0 < speed < MIN_SPEED_MPS:
                raise ConfigError(f"{where}.speed_mps: {speed:g} m/s is below the smallest speed set-point "
                                  f"{MIN_SPEED_MPS:g} m/s (allowed: 0, at rest, or {MIN_SPEED_MPS:g} to "
                                  f"{MAX_SPEED_MPS:g} m/s)")
            leg = math.hypot(n.north_m - nodes[k - 1].north_m, n.east_m - nodes[k - 1].east_m)
            if leg > MAX_LEG_M:
                raise ConfigError(f"{Route.node_label(k)}: {leg:.0f} m from {Route.node_label(k - 1)}, more than "
                                  f"{MAX_LEG_M:g} m (a misplaced node?)")
    polygons = ([("area", route.area)] if route.area is not None else []) + \
        [(f"obstacles[{i}]", r.polygon) for i, r in enumerate(route.obstacles)]
    for name, poly in polygons:
        for j, (north, east) in enumerate(poly):
            if not (math.isfinite(north) and math.isfinite(east)):
                raise ConfigError(f"{name}[{j}]: [{north}, {east}] is not a finite point")
            coordinate(f"{name}[{j}]", north, east)


def validate_route(route: Route) -> None:
    """Check everything about a route that does not depend on the planner's settings.

    Raises ConfigError naming the node or polygon: finite numbers, non-negative speeds, at least
    two nodes (harbour + one), no duplicate consecutive nodes, valid (non self-intersecting)
    polygons, every node inside the navigable water.
    """
    if len(route.nodes) < 1:
        raise ConfigError("nodes: a route needs at least two nodes (the harbour and one route node)")
    h = route.harbour
    for name, v in (("north", h.north_m), ("east", h.east_m), ("heading", h.heading_rad)):
        if not math.isfinite(v):
            raise ConfigError(f"harbour.{name}: {v} is not a finite number")
    for i, n in enumerate(route.nodes):
        for name, v in (("north", n.north_m), ("east", n.east_m), ("heading", n.heading_rad),
                        ("speed_mps", n.speed_mps)):
            if not math.isfinite(v):
                raise ConfigError(f"nodes[{i}].{name}: {v} is not a finite number")
        if n.speed_mps < 0:
            raise ConfigError(f"nodes[{i}].speed_mps: {n.speed_mps:g} is negative")
    check_route_limits(route)
    nodes = route.all_nodes()
    for k in range(1, len(nodes)):
        d = math.hypot(nodes[k].north_m - nodes[k - 1].north_m, nodes[k].east_m - nodes[k - 1].east_m)
        if d < DUPLICATE_TOL_M:
            raise ConfigError(
                f"{Route.node_label(k)}: duplicates {Route.node_label(k - 1)} "
                f"(only {d:.3f} m apart at north {nodes[k].north_m:g}, east {nodes[k].east_m:g})")
    area = check_polygon("area", route.area) if route.area is not None else None
    regions = []
    for i, r in enumerate(route.obstacles):
        if r.forbidden not in ("inside", "outside"):
            raise ConfigError(f"obstacles[{i}].forbidden: must be 'inside' or 'outside', got {r.forbidden!r}")
        regions.append((i, r, check_polygon(f"obstacles[{i}]", r.polygon)))
    for k, n in enumerate(nodes):
        p = Point(n.north_m, n.east_m)
        where = f"{Route.node_label(k)} (north {n.north_m:g}, east {n.east_m:g})"
        if area is not None and not area.covers(p):
            raise ConfigError(f"{where} is outside the navigable area")
        for i, r, poly in regions:
            if r.forbidden == "inside" and poly.intersects(p):
                raise ConfigError(f"{where} is inside obstacles[{i}]")
            if r.forbidden == "outside" and not poly.covers(p):
                raise ConfigError(f"{where} is outside obstacles[{i}], whose outside is forbidden")
    free = route.free_region()
    if free.is_empty:
        raise ConfigError("area: no navigable water is left after removing the obstacles")
