"""The planner as the UI sees it: plan a drawn route, tie each error to the node it names,
and convert routes to and from YAML / GeoJSON text (lotsen.planning.io does the real work)."""

from __future__ import annotations

import json
import re
from typing import Any

import numpy as np
import yaml

from lotsen.errors import LotsenError
from lotsen.planning import GeoOrigin, PlannerConfig, plan_route
from lotsen.planning.io import route_from_dict, route_from_geojson, route_to_dict, route_to_geojson

DISPLAY_SPACING_M = 0.2  # the planner's 1 cm points, thinned for drawing

_SEGMENT = re.compile(r"segment \d+ \((harbour|nodes\[\d+\]) -> (harbour|nodes\[(\d+)\])\)")
_NODE = re.compile(r"nodes\[(\d+)\]")
_OBSTACLE = re.compile(r"obstacles\[(\d+)\]")


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
    text = str(exc)
    return {"message": text, "error_class": type(exc).__name__, **locate_error(text)}


def plan_for_display(route_data: dict, config: PlannerConfig | None = None) -> dict[str, Any]:
    """{"ok": True, "route", "path": {n, e, v}, "length_m", "duration_s", "segments"} or
    {"ok": False, "errors": [{message, kind, index?}]}. Never raises for bad input."""
    try:
        route = route_from_dict(route_data)
        path = plan_route(route, config or PlannerConfig())
    except LotsenError as exc:  # ConfigError (schema, geometry) and PlanningError (segments)
        return {"ok": False, "errors": [_error(exc)]}
    except Exception as exc:  # noqa: BLE001 - a planner bug must reach the operator, not kill the server
        return {"ok": False, "errors": [{"message": f"planner failed: {exc!r}", "error_class": type(exc).__name__,
                                          "kind": "route"}]}
    step = max(1, int(round(DISPLAY_SPACING_M / max(float(np.median(np.diff(path.s_m))), 1e-4))))
    idx = np.unique(np.r_[np.arange(0, len(path), step), len(path) - 1])
    ds = np.diff(path.s_m)
    v_mid = np.maximum(0.5 * (path.speed_mps[1:] + path.speed_mps[:-1]), 0.05)
    return {
        "ok": True,
        "route": route_to_dict(route),
        "path": {"n": np.round(path.north_m[idx], 3).tolist(), "e": np.round(path.east_m[idx], 3).tolist(),
                 "v": np.round(path.speed_mps[idx], 3).tolist()},
        "length_m": round(path.length_m, 2),
        "duration_s": round(float(np.sum(ds / v_mid)), 1),
        "segments": [{"label": s.label, "length_m": round(s.length_m, 2), "detour": bool(s.detour)}
                     for s in path.segments],
    }


def export_route(route_data: dict, fmt: str, origin: GeoOrigin | None = None) -> str:
    """YAML or GeoJSON text of a drawn route (validated first). GeoJSON needs a geographic
    origin: the route's own, else `origin` (the stack's GNSS origin). Raises LotsenError."""
    route = route_from_dict(route_data)
    if fmt == "geojson":
        return json.dumps(route_to_geojson(route, origin=route.origin or origin), indent=1)
    return yaml.safe_dump(route_to_dict(route), sort_keys=False, default_flow_style=None)


def import_route(text: str, fmt: str) -> dict:
    """Route dict from YAML or GeoJSON text. Raises LotsenError with the location of the problem."""
    from lotsen.errors import ConfigError

    try:
        data = json.loads(text) if fmt == "geojson" else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as exc:
        raise ConfigError(f"import: not valid {fmt.upper()}: {str(exc)[:200]}") from None
    route = route_from_geojson(data) if fmt == "geojson" else route_from_dict(data)
    return route_to_dict(route)
