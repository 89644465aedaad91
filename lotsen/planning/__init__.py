"""Route planning (seed section 3.4): route model, cubic candidates, constraints, speed profile.

Public API::

    from lotsen.planning import Route, PlannerConfig, plan_route, plan_return_route, Path
    from lotsen.planning.io import load_route, save_route, route_to_geojson, route_from_geojson
"""

from lotsen.planning.path import Path, PathPoint, Projection, SegmentMetrics
from lotsen.planning.planner import PlannerConfig, plan_return_route, plan_route
from lotsen.planning.route import GeoOrigin, HarbourNode, Region, Route, RouteNode, validate_route

__all__ = [
    "GeoOrigin", "HarbourNode", "Path", "PathPoint", "PlannerConfig", "Projection", "Region",
    "Route", "RouteNode", "SegmentMetrics", "plan_return_route", "plan_route", "validate_route",
]
