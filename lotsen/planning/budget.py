"""Bounds on what one planning request may ask for, checked before any planning work.

A route is small to write and can be expensive to plan: two nodes 100 km apart ask for ten
million 1 cm points. The budget bounds the route's size (nodes, extent, obstacle vertices) so a
request over it is refused at once with a message naming the bound; the planner worker's time
and memory limits catch what these bounds cannot foresee.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from lotsen.errors import PlanningError
from lotsen.planning.route import Route
from lotsen.settings import value_range as _r


@dataclass(frozen=True)
class PlanningBudget:
    max_nodes: int = field(default=200, metadata=_r(2, 10_000))
    max_extent_m: float = field(default=1000.0, metadata=_r(1.0, 100_000.0))  # bounding box side of everything
    max_route_length_m: float = field(default=5000.0, metadata=_r(1.0, 1_000_000.0))  # sum of node-to-node distances
    max_polygon_vertices: int = field(default=2000, metadata=_r(3, 100_000))  # area + obstacles, all vertices
    max_obstacles: int = field(default=50, metadata=_r(0, 10_000))
    # CPU time of one request in the worker (5 x that in wall time stops it too: stuck, or starved)
    time_s: float = field(default=10.0, metadata=_r(0.1, 600.0))
    # CPU time of one prediction of time and energy (the page's Predict: the mission flown on the model
    # in use on simulated time, ~7 ms of CPU per simulated second here, 3-4x that on a Pi 4)
    predict_time_s: float = field(default=120.0, metadata=_r(1.0, 1800.0))
    memory_mb: float = field(default=1024.0, metadata=_r(64.0, 65536.0))  # address space of the worker


def check_budget(route: Route, budget: PlanningBudget) -> None:
    """PlanningError naming the first bound the route exceeds."""
    nodes = route.all_nodes()
    if len(nodes) - 1 > budget.max_nodes:
        raise PlanningError(f"route: {len(nodes) - 1} nodes, more than the planning budget's {budget.max_nodes} "
                            "(extra.planning.max_nodes)")
    if len(route.obstacles) > budget.max_obstacles:
        raise PlanningError(f"obstacles: {len(route.obstacles)}, more than the planning budget's "
                            f"{budget.max_obstacles} (extra.planning.max_obstacles)")
    vertices = (len(route.area) if route.area else 0) + sum(len(o.polygon) for o in route.obstacles)
    if vertices > budget.max_polygon_vertices:
        raise PlanningError(f"area and obstacles: {vertices} vertices, more than the planning budget's "
                            f"{budget.max_polygon_vertices} (extra.planning.max_polygon_vertices)")
    pts = [(n.north_m, n.east_m) for n in nodes] + list(route.area or ())
    ns, es = [p[0] for p in pts], [p[1] for p in pts]
    extent = max(max(ns) - min(ns), max(es) - min(es))
    if extent > budget.max_extent_m:
        raise PlanningError(f"route: spans {extent:.0f} m, more than the planning budget's {budget.max_extent_m:g} m "
                            "(extra.planning.max_extent_m)")
    length = sum(math.hypot(b.north_m - a.north_m, b.east_m - a.east_m) for a, b in zip(nodes, nodes[1:]))
    if length > budget.max_route_length_m:
        raise PlanningError(f"route: {length:.0f} m from node to node, more than the planning budget's "
                            f"{budget.max_route_length_m:g} m (extra.planning.max_route_length_m)")
