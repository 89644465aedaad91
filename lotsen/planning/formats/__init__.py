"""Route files the ground stations write: QGroundControl `.plan`, `QGC WPL 110` waypoint text
(Mission Planner, MAVProxy), KML and GPX, read into lotsen's route (docs/planning.md's YAML
schema) and written from one. The rules (harbour, headings, speeds, fences) are those of
`lotsen.planning.formats.items`, shared with the MAVLink mission protocol (docs/mavlink.md)."""

from __future__ import annotations

from pathlib import Path

from lotsen.errors import ConfigError
from lotsen.planning.formats.items import Plan, plan_from_route, route_from_plan
from lotsen.planning.formats.qgc import parse_plan, parse_wpl, write_plan, write_wpl
from lotsen.planning.formats.xmlroutes import parse_gpx, parse_kml, write_gpx, write_kml
from lotsen.planning.route import GeoOrigin, Route

#: the formats of this package (lotsen.planning.io reads and writes yaml and geojson)
GROUND_STATION_FORMATS = ("plan", "wpl", "kml", "gpx")
SUFFIXES = {".plan": "plan", ".waypoints": "wpl", ".wpl": "wpl", ".txt": "wpl", ".kml": "kml", ".gpx": "gpx",
            ".yaml": "yaml", ".yml": "yaml", ".geojson": "geojson", ".json": "geojson"}
DEFAULT_SPEED_MPS = 0.5

__all__ = ["GROUND_STATION_FORMATS", "SUFFIXES", "Plan", "format_of", "read_route_text", "write_route_text",
           "plan_from_route", "route_from_plan"]


def format_of(path: str | Path) -> str:
    """The format a file name says (yaml, geojson, plan, wpl, kml, gpx); ConfigError otherwise."""
    suffix = Path(path).suffix.lower()
    if suffix not in SUFFIXES:
        raise ConfigError(f"{path}: unknown route file type {suffix or '(none)'!r}; known: "
                          f"{', '.join(sorted(SUFFIXES))}")
    return SUFFIXES[suffix]


def read_route_text(text: str, fmt: str, origin: GeoOrigin | None = None,
                    default_speed_mps: float = DEFAULT_SPEED_MPS, where: str = "route") -> dict:
    """A route dict from a ground station's file text. `origin`: the local frame's geographic
    origin (the stack's); None: the harbour's position, kept in the dict as `origin`."""
    if fmt == "plan":
        plan = parse_plan(text, where)
        return route_from_plan(plan, origin, plan.cruise_speed_mps or default_speed_mps)
    if fmt == "wpl":
        return route_from_plan(parse_wpl(text, where), origin, default_speed_mps)
    if fmt == "kml":
        return parse_kml(text, origin, default_speed_mps, where)
    if fmt == "gpx":
        return parse_gpx(text, origin, default_speed_mps, where)
    raise ConfigError(f"{where}: unknown format {fmt!r} (one of {', '.join(GROUND_STATION_FORMATS)})")


def write_route_text(route: Route, fmt: str, origin: GeoOrigin | None = None) -> tuple[str, list[str]]:
    """(text, notes): `route` in a ground station's format; `notes` say what the format cannot
    carry (WPL: no fence; GPX: no polygons). Latitude/longitude from the route's origin, else
    `origin`; ConfigError without either."""
    o = route.origin or origin
    if o is None:
        raise ConfigError("route has no origin: add 'origin: {lat_deg, lon_deg}' to the route (or give the "
                          "origin) to write latitude and longitude")
    notes = []
    if fmt == "plan":
        return write_plan(plan_from_route(route, o)), notes
    if fmt == "wpl":
        if route.area is not None or route.obstacles:
            notes.append("QGC WPL 110 has no fence: the area and obstacles are not written (use .plan)")
        return write_wpl(plan_from_route(route, o)), notes
    if fmt == "kml":
        return write_kml(route, o), notes
    if fmt == "gpx":
        if route.area is not None or route.obstacles:
            notes.append("GPX has no polygons: the area and obstacles are not written (use .plan or .kml)")
        return write_gpx(route, o), notes
    raise ConfigError(f"unknown format {fmt!r} (one of {', '.join(GROUND_STATION_FORMATS)})")
