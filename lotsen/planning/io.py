"""Boundary functions: routes to and from YAML and GeoJSON (the planning algorithm does no I/O).

YAML schema (local NED metres, degrees in the file, radians in memory)::

    origin: {lat_deg: 59.3293, lon_deg: 18.0686, height_m: 0.0}   # optional, for GeoJSON
    harbour: {north: 0.0, east: 0.0, heading_deg: 0.0}
    nodes:
      - {north: 20.0, east: 5.0, heading_deg: 30.0, speed_mps: 0.6}
    area: [[-5, -5], [40, -5], [40, 40], [-5, 40]]        # navigable polygon [north, east]
    obstacles:
      - [[10, 10], [14, 10], [14, 14], [10, 14]]          # inside is forbidden
      - {polygon: [[...], ...], forbidden: outside}       # or say which side is forbidden

GeoJSON (RFC 7946, [lon, lat]): a FeatureCollection of Points (``role``: harbour / node, with
``heading_deg``, ``speed_mps``, ``index``) and Polygons (``role``: area / obstacle, with
``forbidden``); the local origin is kept in the foreign member ``lotsen_origin``.
Conversions use the one geodetic frame (`lotsen.model.geodetic.LocalFrame`, WGS84).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path as FilePath
from typing import Any

import yaml
from shapely.geometry import Polygon

from lotsen.errors import ConfigError
from lotsen.files import parse_json, parse_yaml, read_text
from lotsen.model.geodetic import LocalFrame
from lotsen.settings import Number
from lotsen.planning.route import GeoOrigin, HarbourNode, Region, Route, RouteNode, check_polygon, validate_route

_TOP_KEYS = {"harbour", "nodes", "area", "obstacles", "origin", "survey"}
_FINITE = Number(-sys.float_info.max, sys.float_info.max)
_INDEX = Number(0, 100_000, integer=True)  # a GeoJSON feature's place in the route


# --------------------------------------------------------------------------------------------
# dict <-> Route (strict schema checks with the location of every problem)
# --------------------------------------------------------------------------------------------
def _number(value: Any, where: str) -> float:
    """A finite number, not a denormal (`lotsen.settings.Number`); the route's physical limits are
    `validate_route`'s, which every route passes however it arrives."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: expected a number, got {_short(value)}")
    return _FINITE.check(value, where)


def _short(value: Any, limit: int = 60) -> str:
    """repr for a message, cut short (a hostile file must not produce a megabyte error)."""
    try:
        text = repr(value)
    except RecursionError:
        return f"a deeply nested {type(value).__name__}"
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _mapping(value: Any, where: str, required: set[str], optional: set[str] = frozenset()) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected a mapping with keys {sorted(required | optional)}, "
                          f"got {type(value).__name__}")
    unknown = set(value) - required - optional
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(map(str, unknown))}; "
                          f"allowed: {sorted(required | optional)}")
    missing = required - set(value)
    if missing:
        raise ConfigError(f"{where}: missing key(s) {sorted(missing)}")
    return value


def _polygon(value: Any, where: str) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{where}: expected a list of [north, east] vertices, got {type(value).__name__}")
    out = []
    for j, p in enumerate(value):
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise ConfigError(f"{where}[{j}]: expected [north, east], got {_short(p)}")
        out.append((_number(p[0], f"{where}[{j}][0]"), _number(p[1], f"{where}[{j}][1]")))
    if len(out) > 3 and out[0] == out[-1]:
        out.pop()  # accept closed rings
    if len(out) < 3:
        raise ConfigError(f"{where}: a polygon needs at least 3 vertices, got {len(out)}")
    return tuple(out)


def route_from_dict(data: Any, *, validate: bool = True) -> Route:
    """Build a Route from the YAML schema; ConfigError names the offending key ("nodes[2].speed_mps").

    A route gives `nodes` or a `survey` (lotsen.planning.survey: the nodes are made from it), not both."""
    surveyed = isinstance(data, dict) and data.get("survey") is not None
    data = _mapping(data, "route", {"harbour"} if surveyed else {"harbour", "nodes"}, _TOP_KEYS - {"harbour"})
    h = _mapping(data["harbour"], "harbour", {"north", "east"}, {"heading_deg"})
    harbour = HarbourNode(_number(h["north"], "harbour.north"), _number(h["east"], "harbour.east"),
                          math.radians(_number(h.get("heading_deg", 0.0), "harbour.heading_deg")))
    if surveyed and data.get("nodes"):
        raise ConfigError("route: give nodes or a survey, not both (a survey's nodes are made from its lines)")
    if surveyed:
        data = {**data, "nodes": []}
    if not isinstance(data["nodes"], list):
        raise ConfigError(f"nodes: expected a list of nodes, got {type(data['nodes']).__name__}")
    nodes = []
    for i, n in enumerate(data["nodes"]):
        w = f"nodes[{i}]"
        n = _mapping(n, w, {"north", "east", "heading_deg", "speed_mps"})
        speed = _number(n["speed_mps"], f"{w}.speed_mps")
        if speed < 0:
            raise ConfigError(f"{w}.speed_mps: {speed:g} is negative")
        nodes.append(RouteNode(_number(n["north"], f"{w}.north"), _number(n["east"], f"{w}.east"),
                               math.radians(_number(n["heading_deg"], f"{w}.heading_deg")), speed))
    area = _polygon(data["area"], "area") if data.get("area") is not None else None
    obstacles = []
    obs = data.get("obstacles") or []
    if not isinstance(obs, list):
        raise ConfigError(f"obstacles: expected a list of polygons, got {type(obs).__name__}")
    for i, o in enumerate(obs):
        w = f"obstacles[{i}]"
        if isinstance(o, dict):
            o = _mapping(o, w, {"polygon"}, {"forbidden"})
            forbidden = o.get("forbidden", "inside")
            if forbidden not in ("inside", "outside"):
                raise ConfigError(f"{w}.forbidden: must be 'inside' or 'outside', got {_short(forbidden)}")
            obstacles.append(Region(_polygon(o["polygon"], f"{w}.polygon"), forbidden))
        else:
            obstacles.append(Region(_polygon(o, w), "inside"))
    origin = None
    if data.get("origin") is not None:
        o = _mapping(data["origin"], "origin", {"lat_deg", "lon_deg"}, {"height_m"})
        lat = _number(o["lat_deg"], "origin.lat_deg")
        lon = _number(o["lon_deg"], "origin.lon_deg")
        if not -90 <= lat <= 90 or not -180 <= lon <= 180:
            raise ConfigError(f"origin: latitude {lat:g} / longitude {lon:g} out of range")
        origin = GeoOrigin(lat, lon, _number(o.get("height_m", 0.0), "origin.height_m"))
    route = Route(harbour, tuple(nodes), area, tuple(obstacles), origin)
    if surveyed:
        route = _surveyed(route, data["survey"])
    if validate:
        validate_route(route)
    return route


def _surveyed(route: Route, survey: Any) -> Route:
    """The route with the nodes of its survey (polygons checked first: the lines are clipped to them)."""
    from dataclasses import replace

    from lotsen.planning.route import check_route_limits
    from lotsen.planning.survey import expand_survey, pattern_from_dict

    pattern = pattern_from_dict(survey)
    check_route_limits(route)
    if route.area is not None:
        check_polygon("area", route.area)
    for i, r in enumerate(route.obstacles):
        check_polygon(f"obstacles[{i}]", r.polygon)
    if route.area is None and pattern.polygon is None and pattern.lines is None:
        raise ConfigError("survey: no polygon and no navigable area: give the survey a polygon (or the route an area)")
    plan = expand_survey(pattern, route.harbour, replace(route, survey=pattern).free_region(),
                         Polygon(route.area) if route.area is not None else None)
    return replace(route, nodes=plan.nodes, survey=pattern, survey_lines=plan.lines)


def _deg(rad: float) -> float:
    return round(math.degrees(rad), 9)


def route_to_dict(route: Route) -> dict:
    """The YAML schema as plain data (inverse of route_from_dict)."""
    h = route.harbour
    out: dict[str, Any] = {}
    if route.origin is not None:
        out["origin"] = {"lat_deg": route.origin.lat_deg, "lon_deg": route.origin.lon_deg,
                         "height_m": route.origin.height_m}
    out["harbour"] = {"north": h.north_m, "east": h.east_m, "heading_deg": _deg(h.heading_rad)}
    if route.survey is not None:
        from lotsen.planning.survey import pattern_to_dict

        out["survey"] = pattern_to_dict(route.survey)
    else:
        out["nodes"] = [{"north": n.north_m, "east": n.east_m, "heading_deg": _deg(n.heading_rad),
                         "speed_mps": n.speed_mps} for n in route.nodes]
    if route.area is not None:
        out["area"] = [list(p) for p in route.area]
    if route.obstacles:
        out["obstacles"] = [
            [list(p) for p in r.polygon] if r.forbidden == "inside"
            else {"polygon": [list(p) for p in r.polygon], "forbidden": r.forbidden}
            for r in route.obstacles]
    return out


# --------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------
def load_route(path: str | FilePath, origin: GeoOrigin | None = None, default_speed_mps: float | None = None) -> Route:
    """Read a route from YAML (.yaml/.yml), GeoJSON (.geojson/.json) or a ground station's file
    (QGroundControl .plan, QGC WPL 110 .waypoints/.txt, .kml, .gpx: lotsen.planning.formats, in
    the frame of `origin` or else of the file's harbour, node speeds `default_speed_mps` where
    the file has none)."""
    from lotsen.planning import formats

    path = FilePath(path)
    text = read_text(path, ConfigError, "route file")
    fmt = formats.SUFFIXES.get(path.suffix.lower(), "yaml")  # a file of no known suffix: YAML, as ever
    if text.lstrip().startswith("QGC WPL"):
        fmt = "wpl"
    if fmt in formats.GROUND_STATION_FORMATS:
        speed = formats.DEFAULT_SPEED_MPS if default_speed_mps is None else default_speed_mps
        return _prefixed(path, lambda t: route_from_dict(formats.read_route_text(t, fmt, origin, speed, str(path))),
                         text)
    if fmt == "geojson":
        return _prefixed(path, route_from_geojson, parse_json(text, path, ConfigError))
    return _prefixed(path, route_from_dict, parse_yaml(text, path, ConfigError))


def _prefixed(path: FilePath, fn, data):
    try:
        return fn(data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None


def save_route(route: Route, path: str | FilePath, origin: GeoOrigin | None = None) -> list[str]:
    """Write a route in the format its suffix names: YAML, GeoJSON (.geojson/.json) or a ground
    station's (.plan, .waypoints, .kml, .gpx; latitude/longitude from the route's origin, else
    `origin`). Returns notes on what the format could not carry."""
    from lotsen.planning import formats

    path = FilePath(path)
    fmt = formats.SUFFIXES.get(path.suffix.lower(), "yaml")
    notes: list[str] = []
    if fmt in formats.GROUND_STATION_FORMATS:
        text, notes = formats.write_route_text(route, fmt, origin)
    elif fmt == "geojson":
        text = json.dumps(route_to_geojson(route, origin), indent=1)
    else:
        text = yaml.safe_dump(route_to_dict(route), sort_keys=False, default_flow_style=None)
    path.write_text(text, encoding="utf-8")
    return notes


# --------------------------------------------------------------------------------------------
# GeoJSON
# --------------------------------------------------------------------------------------------
def _to_lonlat(north: float, east: float, o: GeoOrigin) -> list[float]:
    lat, lon, _ = LocalFrame(o.lat_deg, o.lon_deg, o.height_m).to_geodetic(north, east)
    return [float(lon), float(lat)]


def _to_ne(lonlat: Any, o: GeoOrigin, where: str) -> tuple[float, float]:
    if not isinstance(lonlat, (list, tuple)) or len(lonlat) < 2:
        raise ConfigError(f"{where}: expected [longitude, latitude], got {_short(lonlat)}")
    lon, lat = _number(lonlat[0], f"{where}[0]"), _number(lonlat[1], f"{where}[1]")
    return LocalFrame(o.lat_deg, o.lon_deg, o.height_m).to_ne(lat, lon)


def route_to_geojson(route: Route, origin: GeoOrigin | None = None) -> dict:
    """FeatureCollection of the route in WGS84 [lon, lat]; needs route.origin or ``origin``."""
    o = origin or route.origin
    if o is None:
        raise ConfigError("route has no origin: add 'origin: {lat_deg, lon_deg}' to export GeoJSON")
    h = route.harbour
    feats = [{"type": "Feature", "geometry": {"type": "Point", "coordinates": _to_lonlat(h.north_m, h.east_m, o)},
              "properties": {"role": "harbour", "heading_deg": _deg(h.heading_rad)}}]
    for i, n in enumerate(route.nodes):
        feats.append({"type": "Feature",
                      "geometry": {"type": "Point", "coordinates": _to_lonlat(n.north_m, n.east_m, o)},
                      "properties": {"role": "node", "index": i, "heading_deg": _deg(n.heading_rad),
                                     "speed_mps": n.speed_mps}})

    def ring(poly):
        pts = [_to_lonlat(p[0], p[1], o) for p in poly]
        return [pts + [pts[0]]]

    if route.area is not None:
        feats.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": ring(route.area)},
                      "properties": {"role": "area"}})
    for i, r in enumerate(route.obstacles):
        feats.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": ring(r.polygon)},
                      "properties": {"role": "obstacle", "index": i, "forbidden": r.forbidden}})
    return {"type": "FeatureCollection", "features": feats,
            "lotsen_origin": {"lat_deg": o.lat_deg, "lon_deg": o.lon_deg, "height_m": o.height_m}}


def _geo_origin(lat: float, lon: float, height: float, where: str) -> GeoOrigin:
    if not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 180.0:
        raise ConfigError(f"{where}: latitude {lat:g} / longitude {lon:g} out of range ([-90, 90], [-180, 180])")
    return GeoOrigin(lat, lon, height)


def route_from_geojson(data: Any, origin: GeoOrigin | None = None) -> Route:
    """Inverse of route_to_geojson. Origin: argument, else ``lotsen_origin``, else the harbour point."""
    if not isinstance(data, dict) or data.get("type") != "FeatureCollection":
        raise ConfigError("geojson: expected a FeatureCollection")
    feats = data.get("features")
    if not isinstance(feats, list):
        raise ConfigError("geojson.features: expected a list")
    by_role: dict[str, list[tuple[int, dict, dict]]] = {"harbour": [], "node": [], "area": [], "obstacle": []}
    for j, f in enumerate(feats):
        where = f"geojson.features[{j}]"
        if not isinstance(f, dict) or not isinstance(f.get("geometry"), dict):
            raise ConfigError(f"{where}: expected a Feature with a geometry")
        props = f.get("properties")
        if props is None:
            props = {}
        if not isinstance(props, dict):
            raise ConfigError(f"{where}.properties: expected a mapping, got {_short(props)}")
        role = props.get("role")
        if not isinstance(role, str) or role not in by_role:
            raise ConfigError(f"{where}.properties.role: expected one of {sorted(by_role)}, got {_short(role)}")
        gtype = "Point" if role in ("harbour", "node") else "Polygon"
        if f["geometry"].get("type") != gtype:
            raise ConfigError(f"{where}: a {role} must be a {gtype}, got {_short(f['geometry'].get('type'))}")
        if "index" in props:  # the order of the nodes: a whole number, not any float
            _INDEX.check(props["index"], f"{where}.properties.index")
        by_role[role].append((j, f, props))
    if len(by_role["harbour"]) != 1:
        raise ConfigError(f"geojson: expected exactly one harbour point, got {len(by_role['harbour'])}")
    if len(by_role["area"]) > 1:
        raise ConfigError(f"geojson: expected at most one area polygon, got {len(by_role['area'])}")
    if origin is None and data.get("lotsen_origin") is not None:
        lo = _mapping(data["lotsen_origin"], "geojson.lotsen_origin", {"lat_deg", "lon_deg"}, {"height_m"})
        origin = _geo_origin(_number(lo["lat_deg"], "lotsen_origin.lat_deg"),
                             _number(lo["lon_deg"], "lotsen_origin.lon_deg"),
                             _number(lo.get("height_m", 0.0), "lotsen_origin.height_m"), "geojson.lotsen_origin")
    j_h, f_h, props_h = by_role["harbour"][0]
    if origin is None:
        c = f_h["geometry"].get("coordinates")
        where = f"geojson.features[{j_h}].coordinates"
        if not isinstance(c, (list, tuple)) or len(c) < 2:
            raise ConfigError(f"{where}: expected [longitude, latitude], got {_short(c)}")
        origin = _geo_origin(_number(c[1], f"{where}[1]"), _number(c[0], f"{where}[0]"), 0.0, where)

    def point(j: int, f: dict) -> tuple[float, float]:
        return _to_ne(f["geometry"].get("coordinates"), origin, f"geojson.features[{j}].coordinates")

    def polygon(j: int, f: dict) -> list[list[float]]:
        rings = f["geometry"].get("coordinates")
        where = f"geojson.features[{j}].coordinates"
        if not isinstance(rings, list) or not rings or not isinstance(rings[0], list):
            raise ConfigError(f"{where}: expected a list of rings")
        return [list(_to_ne(p, origin, f"{where}[0][{k}]")) for k, p in enumerate(rings[0])]

    def order(items: list[tuple[int, dict, dict]]) -> list[tuple[int, dict, dict]]:
        return sorted(items, key=lambda jfp: float(jfp[2].get("index", jfp[0])))

    hn, he = point(j_h, f_h)
    d: dict[str, Any] = {
        "harbour": {"north": hn, "east": he, "heading_deg": props_h.get("heading_deg", 0.0)},
        "nodes": [], "obstacles": []}
    for j, f, p in order(by_role["node"]):
        n, e = point(j, f)
        if "speed_mps" not in p or "heading_deg" not in p:
            raise ConfigError(f"geojson.features[{j}].properties: a node needs heading_deg and speed_mps")
        d["nodes"].append({"north": n, "east": e, "heading_deg": p["heading_deg"], "speed_mps": p["speed_mps"]})
    if by_role["area"]:
        j, f, _ = by_role["area"][0]
        d["area"] = polygon(j, f)
    for j, f, p in order(by_role["obstacle"]):
        d["obstacles"].append({"polygon": polygon(j, f), "forbidden": p.get("forbidden", "inside")})
    d["origin"] = {"lat_deg": origin.lat_deg, "lon_deg": origin.lon_deg, "height_m": origin.height_m}
    return route_from_dict(d)
