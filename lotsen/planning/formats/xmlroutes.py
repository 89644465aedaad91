"""KML (Google Earth, most map tools) and GPX (GPS devices, tracking apps) routes.

KML, read: the one LineString is the route (its first point the harbour, the others the nodes;
a Point named "harbour" or "home" makes every line point a node); Polygons are the area (the
first one not named as an obstacle) and obstacles (named "obstacle ...", the further ones, and the
holes of any polygon); a polygon named "keep inside ..." is a region forbidden outside.
GPX, read: the first route (`rte`), else the first track (`trk`, its segments joined and
simplified to 0.5 m: a recorded track has a point every few decimetres); a waypoint (`wpt`) named
"harbour" or "home" is the harbour. Neither format has node speeds or headings: speeds are the
given default, headings follow the rule of lotsen.planning.formats.items (the bisector of the
legs). Written by lotsen, both carry each node's heading and speed (KML `ExtendedData`, GPX
`extensions`) and are read back exactly. GPX has no polygons: the area and obstacles are not
written (the writer says so).

XML with a DOCTYPE or entities is refused (no entity expansion, no external references)."""

from __future__ import annotations

import math
import sys
import xml.etree.ElementTree as ET
from typing import Any

from shapely.geometry import LineString

from lotsen.errors import ConfigError
from lotsen.model.geodetic import LocalFrame
from lotsen.planning.formats.items import computed_headings
from lotsen.planning.route import GeoOrigin, Route
from lotsen.settings import Number

KML_NS = "http://www.opengis.net/kml/2.2"
GPX_NS = "http://www.topografix.com/GPX/1/1"
LOTSEN_NS = "urn:lotsen:route:1"
TRACK_SIMPLIFY_M = 0.5
HARBOUR_NAMES = ("harbour", "harbor", "home")


def _parse_xml(text: str, where: str) -> ET.Element:
    head = text[:4096].upper()
    if "<!DOCTYPE" in head or "<!ENTITY" in text.upper():
        raise ConfigError(f"{where}: XML with a DOCTYPE or entities is not read")
    try:
        return ET.fromstring(text)
    except ET.ParseError as exc:
        raise ConfigError(f"{where}: not well-formed XML ({exc})") from None


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def _children(el: ET.Element, name: str) -> list[ET.Element]:
    return [c for c in el.iter() if _local(c.tag) == name]


def _text(el: ET.Element | None, name: str) -> str:
    if el is None:
        return ""
    for c in el:
        if _local(c.tag) == name:
            return (c.text or "").strip()
    return ""


def _float(text: str, where: str) -> float:
    """A finite number written in the file (settings.Number: no NaN, infinity or denormal)."""
    if not isinstance(text, str):
        raise ConfigError(f"{where}: {str(text)[:40]!r} is not a number")
    return _FINITE.parse(text, where)


_FINITE = Number(-sys.float_info.max, sys.float_info.max)


def _coords(text: str, where: str) -> list[tuple[float, float]]:
    """KML `coordinates`: 'lon,lat[,alt] lon,lat ...' -> [(lat, lon), ...]."""
    out = []
    for k, tup in enumerate(text.split()):
        parts = tup.split(",")
        if len(parts) < 2:
            raise ConfigError(f"{where}: coordinate {k + 1} {tup[:40]!r} is not lon,lat")
        out.append((_float(parts[1], f"{where}: coordinate {k + 1} latitude"),
                    _float(parts[0], f"{where}: coordinate {k + 1} longitude")))
    return out


class _Frame:
    def __init__(self, origin: GeoOrigin | None, first: tuple[float, float]) -> None:
        self.keep = origin is None
        self.origin = origin or GeoOrigin(first[0], first[1], 0.0)
        self.f = LocalFrame(self.origin.lat_deg, self.origin.lon_deg, self.origin.height_m)

    def ne(self, ll: tuple[float, float], where: str) -> list[float]:
        lat, lon = ll
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise ConfigError(f"{where}: latitude {lat:g} / longitude {lon:g} out of range")
        n, e = self.f.to_ne(lat, lon)
        return [round(n, 4), round(e, 4)]

    def finish(self, route: dict) -> dict:
        if self.keep:
            o = self.origin
            route["origin"] = {"lat_deg": o.lat_deg, "lon_deg": o.lon_deg, "height_m": o.height_m}
        return route


def _assemble(frame: _Frame, harbour: list[float], nodes: list[list[float]], speeds: list[float | None],
              headings: list[float | None], default_speed_mps: float, where: str,
              harbour_heading_deg: float | None = None) -> dict:
    if not nodes:
        raise ConfigError(f"{where}: the route has no node after the harbour (at least two points are needed)")
    pts = [tuple(harbour)] + [tuple(n) for n in nodes]
    computed = computed_headings(pts)  # type: ignore[arg-type]
    out_nodes = [{"north": n[0], "east": n[1],
                  "heading_deg": headings[k] if headings[k] is not None else computed[k],
                  "speed_mps": speeds[k] if speeds[k] is not None else default_speed_mps} for k, n in enumerate(nodes)]
    first = nodes[0]
    towards_first = round(math.degrees(math.atan2(first[1] - harbour[1], first[0] - harbour[0])) % 360.0, 6)
    return {"harbour": {"north": harbour[0], "east": harbour[1],
                        "heading_deg": towards_first if harbour_heading_deg is None else harbour_heading_deg},
            "nodes": out_nodes}


def _node_data(values: dict[str, str], n: int, where: str) -> tuple[list[float | None], list[float | None]]:
    """lotsen's own per-node speeds and headings (comma lists) when present and of the right length."""
    def parse(key: str) -> list[float | None]:
        text = values.get(key)
        if not text:
            return [None] * n
        vals = [_float(v, f"{where}: {key}") for v in text.split(",")]
        if len(vals) != n:
            raise ConfigError(f"{where}: {key} has {len(vals)} values for {n} nodes")
        return vals  # type: ignore[return-value]
    return parse("speeds_mps"), parse("headings_deg")


# ------------------------------------------------------------------------------------------------
# KML
# ------------------------------------------------------------------------------------------------
def parse_kml(text: str, origin: GeoOrigin | None = None, default_speed_mps: float = 0.5,
              where: str = "kml") -> dict:
    root = _parse_xml(text, where)
    lines, polygons, harbour_pt = [], [], None
    for pm in _children(root, "Placemark"):
        name = _text(pm, "name")
        data = {d.get("name", ""): _text(d, "value") for d in _children(pm, "Data")}
        for ls in _children(pm, "LineString"):
            lines.append((name, data, _coords(_text(ls, "coordinates"), f"{where}: line {name or len(lines) + 1}")))
        for pg in _children(pm, "Polygon"):
            rings = []
            for boundary in ("outerBoundaryIs", "innerBoundaryIs"):
                for b in [c for c in pg if _local(c.tag) == boundary]:
                    for lr in _children(b, "LinearRing"):
                        rings.append((boundary, _coords(_text(lr, "coordinates"), f"{where}: polygon {name}")))
            polygons.append((name, rings))
        for pt in _children(pm, "Point"):
            if name.strip().lower() in HARBOUR_NAMES:
                c = _coords(_text(pt, "coordinates"), f"{where}: point {name}")
                harbour_pt = c[0] if c else None
    if len(lines) != 1:
        raise ConfigError(f"{where}: {len(lines)} lines (LineString); lotsen takes one route line "
                          "(harbour first, then the nodes)")
    name, data, line = lines[0]
    first = harbour_pt or (line[0] if line else None)
    if first is None:
        raise ConfigError(f"{where}: the route line has no points")
    frame = _Frame(origin, first)
    pts = [frame.ne(p, f"{where}: line point {k + 1}") for k, p in enumerate(line)]
    harbour = frame.ne(harbour_pt, f"{where}: harbour") if harbour_pt else pts[0]
    nodes = pts if harbour_pt else pts[1:]
    speeds, headings = _node_data(data, len(nodes), f"{where}: line {name}")
    hh = data.get("harbour_heading_deg")
    route = _assemble(frame, harbour, nodes, speeds, headings, default_speed_mps, where,
                      _float(hh, f"{where}: harbour_heading_deg") if hh else None)
    area, obstacles = None, []
    for pname, rings in polygons:
        label = pname.strip().lower()
        for kind, ring in rings:
            poly = [frame.ne(p, f"{where}: polygon {pname}") for p in ring]
            if len(poly) > 3 and poly[0] == poly[-1]:
                poly.pop()
            if kind == "innerBoundaryIs" or label.startswith("obstacle"):
                obstacles.append(poly)
            elif label.startswith("keep inside"):
                obstacles.append({"polygon": poly, "forbidden": "outside"})
            elif area is None:
                area = poly
            else:
                obstacles.append(poly)
    if area is not None:
        route["area"] = area
    if obstacles:
        route["obstacles"] = obstacles
    return frame.finish(route)


def _geo(route: Route, origin: GeoOrigin | None) -> LocalFrame:
    o = origin or route.origin
    if o is None:
        raise ConfigError("route has no origin: add 'origin: {lat_deg, lon_deg}' (or give --origin) to write "
                          "latitude and longitude")
    return LocalFrame(o.lat_deg, o.lon_deg, o.height_m)


def _ll(f: LocalFrame, n: float, e: float) -> tuple[float, float]:
    lat, lon, _ = f.to_geodetic(n, e)
    return round(lat, 9), round(lon, 9)


def write_kml(route: Route, origin: GeoOrigin | None = None) -> str:
    f = _geo(route, origin)
    ET.register_namespace("", KML_NS)
    kml = ET.Element(f"{{{KML_NS}}}kml")
    doc = ET.SubElement(kml, f"{{{KML_NS}}}Document")
    ET.SubElement(doc, f"{{{KML_NS}}}name").text = "lotsen route"

    def placemark(name: str) -> ET.Element:
        pm = ET.SubElement(doc, f"{{{KML_NS}}}Placemark")
        ET.SubElement(pm, f"{{{KML_NS}}}name").text = name
        return pm

    def coords(pts: list[tuple[float, float]]) -> str:
        return " ".join(f"{lon:.9f},{lat:.9f},0" for lat, lon in pts)

    h = route.harbour
    pm = placemark("route")
    ext = ET.SubElement(pm, f"{{{KML_NS}}}ExtendedData")
    for key, vals in (("speeds_mps", [n.speed_mps for n in route.nodes]),
                      ("headings_deg", [round(math.degrees(n.heading_rad), 9) for n in route.nodes]),
                      ("harbour_heading_deg", [round(math.degrees(h.heading_rad), 9)])):
        d = ET.SubElement(ext, f"{{{KML_NS}}}Data", name=key)
        ET.SubElement(d, f"{{{KML_NS}}}value").text = ",".join(repr(float(v)) for v in vals)
    ls = ET.SubElement(pm, f"{{{KML_NS}}}LineString")
    ET.SubElement(ls, f"{{{KML_NS}}}coordinates").text = coords(
        [_ll(f, h.north_m, h.east_m)] + [_ll(f, n.north_m, n.east_m) for n in route.nodes])

    def polygon(name: str, ring: Any) -> None:
        pg = ET.SubElement(placemark(name), f"{{{KML_NS}}}Polygon")
        lr = ET.SubElement(ET.SubElement(pg, f"{{{KML_NS}}}outerBoundaryIs"), f"{{{KML_NS}}}LinearRing")
        pts = [_ll(f, p[0], p[1]) for p in ring]
        ET.SubElement(lr, f"{{{KML_NS}}}coordinates").text = coords(pts + pts[:1])

    if route.area is not None:
        polygon("area", route.area)
    for k, r in enumerate(route.obstacles):
        polygon(f"obstacle {k + 1}" if r.forbidden == "inside" else f"keep inside {k + 1}", r.polygon)
    ET.indent(kml)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(kml, encoding="unicode") + "\n"


# ------------------------------------------------------------------------------------------------
# GPX
# ------------------------------------------------------------------------------------------------
def _pt(el: ET.Element, where: str) -> tuple[float, float]:
    return _float(el.get("lat", ""), f"{where} lat"), _float(el.get("lon", ""), f"{where} lon")


def parse_gpx(text: str, origin: GeoOrigin | None = None, default_speed_mps: float = 0.5,
              where: str = "gpx") -> dict:
    root = _parse_xml(text, where)
    if _local(root.tag) != "gpx":
        raise ConfigError(f"{where}: the root element is <{_local(root.tag)}>, not <gpx>")
    harbour_pt = None
    for w in [c for c in root if _local(c.tag) == "wpt"]:
        if _text(w, "name").lower() in HARBOUR_NAMES:
            harbour_pt = _pt(w, f"{where}: waypoint {_text(w, 'name')}")
    rtes = [c for c in root if _local(c.tag) == "rte"]
    trks = [c for c in root if _local(c.tag) == "trk"]
    speeds: list[float | None] = []
    headings: list[float | None] = []
    harbour_heading = None
    if rtes:
        pts = [_pt(p, f"{where}: route point {k + 1}") for k, p in enumerate(_children(rtes[0], "rtept"))]
        for p in _children(rtes[0], "rtept"):
            mark = next((c for c in p.iter() if _local(c.tag) == "harbour" and c.tag.startswith(f"{{{LOTSEN_NS}}}")), None)
            if mark is not None:
                harbour_heading = _float(mark.get("heading_deg", ""), f"{where}: harbour heading")
            node = next((c for c in p.iter() if _local(c.tag) == "node" and c.tag.startswith(f"{{{LOTSEN_NS}}}")), None)
            speeds.append(_float(node.get("speed_mps", ""), f"{where}: speed") if node is not None else None)
            headings.append(_float(node.get("heading_deg", ""), f"{where}: heading") if node is not None else None)
        simplify = False
    elif trks:
        pts = [_pt(p, f"{where}: track point {k + 1}") for k, p in enumerate(_children(trks[0], "trkpt"))]
        simplify = True
    else:
        raise ConfigError(f"{where}: no route (rte) and no track (trk)")
    if not pts:
        raise ConfigError(f"{where}: the route has no points")
    frame = _Frame(origin, harbour_pt or pts[0])
    ne = [frame.ne(p, f"{where}: point {k + 1}") for k, p in enumerate(pts)]
    if simplify and len(ne) > 2:
        ne = [[round(x, 4), round(y, 4)] for x, y in LineString(ne).simplify(TRACK_SIMPLIFY_M).coords]
        speeds = headings = []
    if harbour_pt is not None:
        harbour, nodes = frame.ne(harbour_pt, f"{where}: harbour"), ne
    else:
        harbour, nodes = ne[0], ne[1:]
        speeds, headings = speeds[1:], headings[1:]
    if len(speeds) != len(nodes):
        speeds = headings = [None] * len(nodes)
    return frame.finish(_assemble(frame, harbour, nodes, speeds, headings, default_speed_mps, where, harbour_heading))


def write_gpx(route: Route, origin: GeoOrigin | None = None) -> str:
    """A GPX 1.1 route (`rte`): the harbour, then the nodes, each with its heading and speed in
    lotsen's extension. The area and obstacles are not written (GPX has no polygons)."""
    f = _geo(route, origin)
    ET.register_namespace("", GPX_NS)
    ET.register_namespace("lotsen", LOTSEN_NS)
    gpx = ET.Element(f"{{{GPX_NS}}}gpx", version="1.1", creator="lotsen")
    rte = ET.SubElement(gpx, f"{{{GPX_NS}}}rte")
    ET.SubElement(rte, f"{{{GPX_NS}}}name").text = "lotsen route"
    h = route.harbour
    points = [("harbour", h.north_m, h.east_m, None)] + [
        (f"node {k + 1}", n.north_m, n.east_m, n) for k, n in enumerate(route.nodes)]
    for name, north, east, node in points:
        lat, lon = _ll(f, north, east)
        p = ET.SubElement(rte, f"{{{GPX_NS}}}rtept", lat=f"{lat:.9f}", lon=f"{lon:.9f}")
        ET.SubElement(p, f"{{{GPX_NS}}}name").text = name
        ext = ET.SubElement(p, f"{{{GPX_NS}}}extensions")
        if node is None:
            ET.SubElement(ext, f"{{{LOTSEN_NS}}}harbour", heading_deg=repr(round(math.degrees(h.heading_rad), 9)))
        else:
            ET.SubElement(ext, f"{{{LOTSEN_NS}}}node", heading_deg=repr(round(math.degrees(node.heading_rad), 9)),
                          speed_mps=repr(float(node.speed_mps)))
    ET.indent(gpx)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(gpx, encoding="unicode") + "\n"
