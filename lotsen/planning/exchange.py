"""A route and its planned path as one typed message (`PlannedRoute`), planned once and sent as
is: the planner worker builds it, the supervisor checks and follows it, the page compares the
boat's read-back by `route_id`."""

from __future__ import annotations

import hashlib
import json

import numpy as np

from lotsen.errors import ConfigError
from lotsen.messages import PlannedRoute
from lotsen.planning.io import route_to_dict
from lotsen.planning.path import Path
from lotsen.planning.route import Route


def route_id(route: dict | Route) -> str:
    """A short, stable id of a route's content: SHA-256 of its canonical JSON (keys sorted,
    numbers as in `route_to_dict`), so the same route drawn twice has the same id."""
    data = route_to_dict(route) if isinstance(route, Route) else route
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def node_arc_lengths(route: Route, path: Path) -> tuple[float, ...]:
    """Arc length of the path at each planner node (harbour first): the projection of the node,
    searched forwards from the previous one, so a path that crosses itself keeps the order."""
    out = []
    s = 0.0
    half = 0.5 * path.length_m + 1.0
    for node in route.all_nodes():  # search [s, end] only: the window is centred on the hint
        p = path.project(node.north_m, node.east_m, s_hint_m=s + half, window_m=half)
        s = max(s, p.s_m)
        out.append(round(s, 4))
    return tuple(out)


def planned_route_message(route: Route, path: Path, stamp_s: float = 0.0, source: str = "operator") -> PlannedRoute:
    data = route_to_dict(route)
    return PlannedRoute(stamp_s=stamp_s, route_id=route_id(data), route=data,
                        s_m=tuple(path.s_m.tolist()), north_m=tuple(path.north_m.tolist()),
                        east_m=tuple(path.east_m.tolist()), heading_rad=tuple(path.heading_rad.tolist()),
                        curvature_1pm=tuple(path.curvature_1pm.tolist()), speed_mps=tuple(path.speed_mps.tolist()),
                        node_s_m=node_arc_lengths(route, path), source=source)


def path_from_message(msg: PlannedRoute) -> Path:
    """The Path of a PlannedRoute; ConfigError when the arrays are not a valid path."""
    try:
        return Path(north_m=np.asarray(msg.north_m, float), east_m=np.asarray(msg.east_m, float),
                    heading_rad=np.asarray(msg.heading_rad, float), curvature_1pm=np.asarray(msg.curvature_1pm, float),
                    speed_mps=np.asarray(msg.speed_mps, float), s_m=np.asarray(msg.s_m, float))
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"planned route {msg.route_id}: path arrays are not numbers ({exc})") from None
