"""The planner as the UI sees it: plan a drawn route, tie each error to the node it names,
and convert routes to and from YAML / GeoJSON text (lotsen.planning.io does the real work)."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import yaml

from lotsen.errors import ConfigError, LotsenError
from lotsen.files import parse_json, parse_yaml
from lotsen.planning import GeoOrigin, PlannerConfig, plan_route
from lotsen.planning.exchange import planned_route_message, route_id
from lotsen.planning.formats import GROUND_STATION_FORMATS, read_route_text, write_route_text
from lotsen.planning.io import route_from_dict, route_from_geojson, route_to_dict, route_to_geojson
from lotsen.web.validation import ValidationError, check_json_tree

DISPLAY_SPACING_M = 0.2  # the planner's 1 cm points, thinned for drawing

_SEGMENT = re.compile(r"segment \d+ \((harbour|nodes\[\d+\]) -> (harbour|nodes\[(\d+)\])\)")
_NODE = re.compile(r"nodes\[(\d+)\]")
_OBSTACLE = re.compile(r"obstacles\[(\d+)\]")


_FIELD_WORDS = {"speed_mps": "speed", "heading_deg": "bearing", "north": "north", "east": "east"}
_SPEED_OVER = re.compile(r"(harbour|nodes\[(\d+)\])\.speed_mps: (\S+) exceeds speed_max_mps (\S+)")
_NODE_FIELD = re.compile(r"nodes\[(\d+)\]\.(\w+)")
_LEG = re.compile(r"segment \d+ \((harbour|nodes\[\d+\]) -> (harbour|nodes\[\d+\])\)")


def operator_text(message: str) -> str:
    """A planner message in the operator's words: nodes counted from 1 as on the page ("node 4",
    not "nodes[3]"), legs by their ends, field names as the table heads them, speeds with units."""
    def node(label: str) -> str:
        m = _NODE.fullmatch(label)
        return f"node {int(m.group(1)) + 1}" if m else label

    text = _SPEED_OVER.sub(lambda m: f"{node(m.group(1))}: speed {m.group(3)} m/s exceeds the boat's "
                                     f"{m.group(4)} m/s", message)
    text = _LEG.sub(lambda m: f"the leg from {node(m.group(1))} to {node(m.group(2))}", text)
    text = _NODE_FIELD.sub(lambda m: f"node {int(m.group(1)) + 1} {_FIELD_WORDS.get(m.group(2), m.group(2))}", text)
    text = _NODE.sub(lambda m: f"node {int(m.group(1)) + 1}", text)
    text = _OBSTACLE.sub(lambda m: f"obstacle {int(m.group(1)) + 1}", text)
    return text.replace("speed_max_mps", "the speed limit").replace("speed_mps", "speed")


def locate_error(message: str) -> dict[str, Any]:
    """Which drawn element an error names: a segment error belongs to the node it leads to."""
    m = _SEGMENT.search(message)
    if m:
        return {"kind": "node", "index": int(m.group(3))} if m.group(3) else {"kind": "harbour"}
    m = _NODE.search(message)
    if m:
        return {"kind": "node", "index": int(m.group(1))}
    if re.search(r"\bharbour\b", message):
        return {"kind": "harbour"}
    m = _OBSTACLE.search(message)
    if m:
        return {"kind": "obstacle", "index": int(m.group(1))}
    if re.search(r"\barea\b", message):
        return {"kind": "area"}
    return {"kind": "route"}


def _error(exc: BaseException) -> dict[str, Any]:
    """The operator's message (1-based nodes) and where it points (`index` 0-based, for the page's
    arrays; `field` the table column to mark)."""
    text = str(exc)
    out = {"message": operator_text(text), "error_class": type(exc).__name__, **locate_error(text)}
    m = _NODE_FIELD.search(text)
    if m and m.group(2) in _FIELD_WORDS:
        out["field"] = m.group(2)
    elif re.search(r"harbour\.(\w+)", text):
        out["field"] = re.search(r"harbour\.(\w+)", text).group(1)
    return out


def _display(route, path, config: PlannerConfig) -> dict[str, Any]:
    step = max(1, int(round(DISPLAY_SPACING_M / max(float(np.median(np.diff(path.s_m))), 1e-4))))
    idx = np.unique(np.r_[np.arange(0, len(path), step), len(path) - 1])
    first = route.nodes[0].speed_mps if route.nodes else 0.0
    a = config.a_long_max_mps2
    out = {
        "ok": True,
        "route": route_to_dict(route),
        "route_id": route_id(route),
        "path": {"n": np.round(path.north_m[idx], 3).tolist(), "e": np.round(path.east_m[idx], 3).tolist(),
                 "v": np.round(path.speed_mps[idx], 3).tolist(), "s": np.round(path.s_m[idx], 2).tolist()},
        "length_m": round(path.length_m, 2),
        "duration_s": round(path.duration_s(), 1),
        "segments": [{"label": operator_text(s.label), "length_m": round(s.length_m, 2),
                      "straight_m": round(s.straight_m, 2), "detour": bool(s.detour),
                      "s0": round(s.s_start_m, 2), "s1": round(s.s_end_m, 2)} for s in path.segments],
        "detours": detours(route, path.segments),
        # leaving the harbour: from rest to the first node's speed at the acceleration limit
        "start_ramp": {"speed_mps": first, "accel_mps2": a, "distance_m": round(first**2 / (2 * a), 3),
                       "time_s": round(first / a, 2)},
    }
    if route.survey is not None:
        out["survey"] = survey_json(route, path)
    return out


def survey_json(route: Any, path: Any) -> dict[str, Any]:
    """What the page's survey tool shows: the lines (as flown), their length and time at the line
    speed, the share of the planned time on lines, the polygon they cover (the drawn one, or the
    area shrunk to leave room to turn) and the turn radius."""
    from lotsen.planning.survey import survey_polygon

    p = route.survey
    on_lines = sum(ln.length_m for ln in route.survey_lines)
    duration = max(path.duration_s(), 1e-9)
    poly = p.polygon
    if poly is None and p.lines is None:
        poly = tuple(survey_polygon(p, route.free_region()).exterior.coords[:-1])
    return {"count": len(route.survey_lines), "line_length_m": round(on_lines, 1),
            "line_time_s": round(on_lines / p.speed_mps, 1), "share_on_lines": round(on_lines / p.speed_mps / duration, 3),
            "turn_radius_m": round(p.turn_radius(), 2), "speed_mps": p.speed_mps, "spacing_m": p.spacing_m,
            "polygon": [[round(c, 3) for c in v] for v in poly] if poly is not None else None,
            "lines": [[[round(c, 3) for c in a], [round(c, 3) for c in b]] for ln in route.survey_lines
                      for a, b in ln.pieces][:2000]}


def detours(route: Any, segments: list) -> list[dict[str, Any]]:
    """The legs the planner routed round an obstacle or an area edge: which leg, where on the path
    (arc length s0..s1), its length and the straight line's (the operator is told and sees it)."""
    def point(label: str) -> Any:
        m = _NODE.fullmatch(label)
        return route.nodes[int(m.group(1))] if m else route.harbour

    out: list[dict[str, Any]] = []
    for seg in segments:
        m = _LEG.search(seg.label)
        if not seg.detour or m is None:
            continue
        leg = operator_text(m.group(0))
        if out and out[-1]["leg"] == leg:  # the parts of one detour
            out[-1].update(s1=round(seg.s_end_m, 2), length_m=round(out[-1]["length_m"] + seg.length_m, 2))
            continue
        a, b = point(m.group(1)), point(m.group(2))
        out.append({"leg": leg, "s0": round(seg.s_start_m, 2), "s1": round(seg.s_end_m, 2),
                    "length_m": round(seg.length_m, 2),
                    "straight_m": round(float(np.hypot(b.north_m - a.north_m, b.east_m - a.east_m)), 2)})
    return out


def plan_for_display(route_data: dict, config: PlannerConfig | None = None) -> dict[str, Any]:
    """{"ok": True, "route", "route_id", "path": {n, e, v, s}, "length_m", "duration_s", "segments",
    "start_ramp"} or {"ok": False, "errors": [{message, kind, index?}]}. Never raises for bad input."""
    config = config or PlannerConfig()
    try:
        route = route_from_dict(route_data)
        path = plan_route(route, config)
    except LotsenError as exc:  # ConfigError (schema, geometry) and PlanningError (segments)
        return {"ok": False, "errors": [_error(exc)]}
    except Exception as exc:  # noqa: BLE001 - a planner bug must reach the operator, not kill the server
        return {"ok": False, "errors": [{"message": f"planner failed: {exc!r}"[:500], "error_class": type(exc).__name__,
                                          "kind": "route"}]}
    return _display(route, path, config)


def plan_for_upload(route_data: dict, config: PlannerConfig | None = None, stamp_s: float = 0.0,
                    source: str = "web") -> dict[str, Any]:
    """Plan once for the upload: the display result (as `plan_for_display`) and, when it
    succeeded, `"message"`: the `PlannedRoute` built from the very same path (picklable, so this
    runs in the planner worker process)."""
    config = config or PlannerConfig()
    try:
        route = route_from_dict(route_data)
        path = plan_route(route, config)
    except LotsenError as exc:
        return {"ok": False, "errors": [_error(exc)]}
    except Exception as exc:  # noqa: BLE001
        return {"ok": False, "errors": [{"message": f"planner failed: {exc!r}"[:500], "error_class": type(exc).__name__,
                                          "kind": "route"}]}
    out = _display(route, path, config)
    out["message"] = planned_route_message(route, path, stamp_s=stamp_s, source=source)
    return out


def export_route(route_data: dict, fmt: str, origin: GeoOrigin | None = None) -> str:
    """YAML, GeoJSON or a ground station's file (.plan, QGC WPL 110, KML, GPX) of a drawn route
    (validated first). All but YAML need a geographic origin: the route's own, else `origin`
    (the stack's GNSS origin). Raises LotsenError."""
    route = route_from_dict(route_data)
    if fmt in GROUND_STATION_FORMATS:
        return write_route_text(route, fmt, origin)[0]
    if fmt == "geojson":
        return json.dumps(route_to_geojson(route, origin=route.origin or origin), indent=1)
    return yaml.safe_dump(route_to_dict(route), sort_keys=False, default_flow_style=None)


def import_route(text: str, fmt: str, origin: GeoOrigin | None = None) -> dict:
    """Route dict from YAML, GeoJSON or a ground station's file text (in the frame of `origin`, the
    stack's, so the route lands where the page draws the boat). Raises LotsenError with the
    location of the problem."""
    if fmt in GROUND_STATION_FORMATS:
        if text.lstrip().startswith("QGC WPL"):
            fmt = "wpl"
        return route_to_dict(route_from_dict(read_route_text(text, fmt, origin, where="import")))
    if fmt == "geojson":
        data = parse_json(text, "import", ConfigError)
    else:
        data = parse_yaml(text, "import", ConfigError, aliases=False)
    try:
        check_json_tree(data, ("import",))
    except ValidationError as exc:
        raise ConfigError(str(exc)) from None
    route = route_from_geojson(data) if fmt == "geojson" else route_from_dict(data)
    return route_to_dict(route)
