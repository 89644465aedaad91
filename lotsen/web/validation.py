"""Validation of messages from the browser: JSON objects with a `type`, known fields only,
each checked for type and range. Every refusal is a `ValidationError` whose message names the
message type and the field, e.g. ``manual.surge: 1.5 outside [-1, 1]``.

Client -> server messages (all may carry an integer `id`, echoed in the reply):

============= ======================================================== =========
type          fields                                                   who
============= ======================================================== =========
auth          token: str, takeover: bool (optional)                    anyone
release                                                                pilot
ping          t: number (optional, client clock, echoed)               anyone
command       action: one of lotsen.messages.OPERATOR_ACTIONS          pilot
manual        surge, sway, yaw: numbers in [-1, 1]                     pilot
plan          route: route dict (docs/planning.md schema)              pilot
route         route: route dict -> PlannedRoute (upload)               pilot
export        route: route dict, format: ROUTE_FORMATS                  anyone
import        text: str, format: ROUTE_FORMATS                         anyone
tiles_preload south, west, north, east (deg), zoom_min, zoom_max        pilot
tiles_cancel                                                           pilot
params        name: an editable setting (lotsen.web.settings), value: number pilot
============= ======================================================== =========

Before any of this the raw text is size-checked (512 kB for the pilot, 64 kB for viewers) and
the decoded JSON is walked once (iteratively, no recursion): nesting at most 16 levels, at most
200 000 values, integers within +-2^53 (a 1e400 integer is refused here, never reaches float()),
every number finite.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from lotsen.messages import OPERATOR_ACTIONS
from lotsen.planning.route import MAX_COORDINATE_M

#: route files the page reads and writes: lotsen's own and the ground stations' (lotsen.planning.formats)
ROUTE_FORMATS = ("yaml", "geojson", "plan", "wpl", "kml", "gpx")
from lotsen.web.settings import EDITABLE_NAMES

MAX_MESSAGE_CHARS = 512 * 1024
VIEWER_MAX_MESSAGE_CHARS = 64 * 1024  # a viewer needs no more (auth, ping, small conversions)
MAX_JSON_DEPTH = 16
MAX_JSON_VALUES = 200_000
MAX_SAFE_INT = 2**53
MAX_ROUTE_NODES = 200
MAX_POLYGONS = 50
MAX_POLYGON_VERTICES = 1000
MAX_TOTAL_VERTICES = 5000
#: every coordinate of a route within this distance of the local origin: the route's own limit
MAX_EXTENT_M = MAX_COORDINATE_M
MAX_TOKEN_CHARS = 256
MAX_IMPORT_CHARS = 400 * 1024


class ValidationError(Exception):
    def __init__(self, code: str, message: str, mid: int | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.mid = mid  # the message's id when it could be read, so the reply can be matched


@dataclass(frozen=True)
class Field:
    kind: str  # "number", "int", "bool", "str", "enum", "route"
    required: bool = True
    lo: float = -math.inf
    hi: float = math.inf
    choices: tuple[str, ...] = ()
    max_len: int = 0


_NUM_UNIT = Field("number", lo=-1.0, hi=1.0)

SCHEMAS: dict[str, dict[str, Field]] = {
    "auth": {"token": Field("str", max_len=MAX_TOKEN_CHARS), "takeover": Field("bool", required=False)},
    "release": {},
    "ping": {"t": Field("number", required=False)},
    # request: the page's id of this press (a resend carries the same one; the boat acts once)
    "command": {"action": Field("enum", choices=OPERATOR_ACTIONS), "request": Field("str", required=False, max_len=40)},
    "manual": {"surge": _NUM_UNIT, "sway": _NUM_UNIT, "yaw": _NUM_UNIT},
    "plan": {"route": Field("route")},
    "route": {"route": Field("route")},
    "export": {"route": Field("route"), "format": Field("enum", choices=ROUTE_FORMATS)},
    "import": {"text": Field("str", max_len=MAX_IMPORT_CHARS), "format": Field("enum", choices=ROUTE_FORMATS)},
    "tiles_preload": {"south": Field("number", lo=-85.0, hi=85.0), "north": Field("number", lo=-85.0, hi=85.0),
                      "west": Field("number", lo=-180.0, hi=180.0), "east": Field("number", lo=-180.0, hi=180.0),
                      "zoom_min": Field("int", lo=0, hi=22), "zoom_max": Field("int", lo=0, hi=22)},
    "tiles_cancel": {},
    "params": {"name": Field("enum", choices=EDITABLE_NAMES), "value": Field("number", lo=-1e6, hi=1e6)},
    # the pairing QR code for another phone: the page's own origin (scheme://host:port)
    "pair_qr": {"origin": Field("str", max_len=200)},
    "rerun": {},  # the route over the held survey's holes
    "predict": {"route": Field("route")},  # its time and energy on the model in use, in the estimated current
}

#: everything that plans, commands or downloads on the boat's behalf needs the pilot seat
PILOT_ONLY = frozenset({"release", "command", "manual", "plan", "route", "tiles_preload", "tiles_cancel",
                        "params", "pair_qr", "rerun", "predict"})
#: what a viewer may send (docs/web.md, "Access rules")
VIEWER_ALLOWED = frozenset(SCHEMAS) - PILOT_ONLY


@dataclass(frozen=True)
class Message:
    type: str
    id: int | None
    fields: dict[str, Any]


def _tname(v: Any) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null",
            int: "number", float: "number"}.get(type(v), type(v).__name__)


def _where(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "message"


def check_json_tree(data: Any, root: tuple = ()) -> None:
    """Bounds on decoded JSON, checked iteratively (no recursion, so no RecursionError): depth,
    number of values, integer magnitude (Python ints are unbounded: 10**400 would overflow
    float() later), finite floats. Raises ValidationError naming the place."""
    stack: list[tuple[Any, tuple, int]] = [(data, root, 0)]
    count = 0
    while stack:
        value, path, depth = stack.pop()
        count += 1
        if count > MAX_JSON_VALUES:
            raise ValidationError("too_large", f"message: more than {MAX_JSON_VALUES} values")
        if isinstance(value, bool) or value is None or isinstance(value, str):
            continue
        if isinstance(value, int):
            if not -MAX_SAFE_INT <= value <= MAX_SAFE_INT:
                digits = len(str(abs(value))) if abs(value) < 10**4000 else 4000
                raise ValidationError("out_of_range", f"{_where(path)}: integer of {digits} digits is out of "
                                      f"range (at most 2^53 = {MAX_SAFE_INT})")
            continue
        if isinstance(value, float):
            if not math.isfinite(value):
                raise ValidationError("out_of_range", f"{_where(path)}: number out of range (not a finite "
                                      "double, e.g. 1e400)")
            continue
        if depth >= MAX_JSON_DEPTH:
            raise ValidationError("too_large", f"{_where(path)}: nested more than {MAX_JSON_DEPTH} levels deep")
        if isinstance(value, dict):
            stack.extend((v, path + (str(k)[:40],), depth + 1) for k, v in value.items())
        elif isinstance(value, list):
            stack.extend((v, path + (i,), depth + 1) for i, v in enumerate(value))


def _check_coordinate(value: Any, where: str) -> None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) > MAX_EXTENT_M:
        raise ValidationError("out_of_range", f"{where}: {value:g} m outside [-{MAX_EXTENT_M:g}, {MAX_EXTENT_M:g}] "
                              "(routes stay within 2 km of the origin)")


def _check_route_size(route: Any, where: str) -> None:
    """Structure caps and extent only (the planner's own loader checks the schema and reports per node)."""
    if not isinstance(route, dict):
        raise ValidationError("wrong_type", f"{where}: expected an object, got {_tname(route)}")
    nodes = route.get("nodes")
    if isinstance(nodes, list):
        if len(nodes) > MAX_ROUTE_NODES:
            raise ValidationError("too_large", f"{where}.nodes: {len(nodes)} nodes, at most {MAX_ROUTE_NODES}")
        for i, n in enumerate(nodes):
            if isinstance(n, dict):
                for k in ("north", "east"):
                    _check_coordinate(n.get(k), f"{where}.nodes[{i}].{k}")
    harbour = route.get("harbour")
    if isinstance(harbour, dict):
        for k in ("north", "east"):
            _check_coordinate(harbour.get(k), f"{where}.harbour.{k}")
    polys = [("area", route.get("area"))] if route.get("area") is not None else []
    survey = route.get("survey")
    if isinstance(survey, dict):
        if survey.get("polygon") is not None:
            polys.append(("survey.polygon", survey.get("polygon")))
        lines = survey.get("lines")
        if isinstance(lines, list):
            if len(lines) > MAX_ROUTE_NODES:
                raise ValidationError("too_large", f"{where}.survey.lines: {len(lines)} lines, at most {MAX_ROUTE_NODES}")
            polys += [(f"survey.lines[{i}]", ln) for i, ln in enumerate(lines)]
    obstacles = route.get("obstacles")
    if isinstance(obstacles, list):
        if len(obstacles) > MAX_POLYGONS:
            raise ValidationError("too_large", f"{where}.obstacles: {len(obstacles)} polygons, at most {MAX_POLYGONS}")
        polys += [(f"obstacles[{i}]", o.get("polygon") if isinstance(o, dict) else o) for i, o in enumerate(obstacles)]
    total = 0
    for name, p in polys:
        if isinstance(p, list):
            total += len(p)
            if len(p) > MAX_POLYGON_VERTICES:
                raise ValidationError("too_large", f"{where}.{name}: {len(p)} vertices, at most {MAX_POLYGON_VERTICES}")
            for j, v in enumerate(p):
                if isinstance(v, list):
                    for c in v[:2]:
                        _check_coordinate(c, f"{where}.{name}[{j}]")
    if total > MAX_TOTAL_VERTICES:
        raise ValidationError("too_large", f"{where}: {total} polygon vertices in all, at most {MAX_TOTAL_VERTICES}")


def _check_field(mtype: str, name: str, spec: Field, value: Any) -> Any:
    where = f"{mtype}.{name}"
    if spec.kind in ("number", "int"):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValidationError("wrong_type", f"{where}: expected a number, got {_tname(value)}")
        if spec.kind == "int" and not (isinstance(value, int) or float(value).is_integer()):
            raise ValidationError("wrong_type", f"{where}: expected an integer, got {value!r}")
        v = float(value)  # finite and bounded: check_json_tree ran first
        if not math.isfinite(v):
            raise ValidationError("out_of_range", f"{where}: {value!r} is not finite")
        if not spec.lo <= v <= spec.hi:
            raise ValidationError("out_of_range", f"{where}: {v:g} outside [{spec.lo:g}, {spec.hi:g}]")
        return int(v) if spec.kind == "int" else v
    if spec.kind == "bool":
        if not isinstance(value, bool):
            raise ValidationError("wrong_type", f"{where}: expected true or false, got {_tname(value)}")
        return value
    if spec.kind == "str":
        if not isinstance(value, str):
            raise ValidationError("wrong_type", f"{where}: expected a string, got {_tname(value)}")
        if len(value) > spec.max_len:
            raise ValidationError("too_large", f"{where}: {len(value)} characters, at most {spec.max_len}")
        return value
    if spec.kind == "enum":
        if not isinstance(value, str):
            raise ValidationError("wrong_type", f"{where}: expected a string, got {_tname(value)}")
        if value not in spec.choices:
            raise ValidationError("out_of_range", f"{where}: {value[:40]!r} is not one of {', '.join(spec.choices)}")
        return value
    if spec.kind == "route":
        _check_route_size(value, where)
        return value
    raise AssertionError(spec.kind)


def parse_message(raw: Any, max_chars: int = MAX_MESSAGE_CHARS) -> Message:
    """Decode and validate one WebSocket text frame (`max_chars`: the sender's size limit)."""
    if not isinstance(raw, str):
        raise ValidationError("bad_json", "expected a JSON text message")
    if len(raw) > max_chars:
        raise ValidationError("too_large", f"message of {len(raw)} characters, at most {max_chars}"
                              + (" for a viewer" if max_chars < MAX_MESSAGE_CHARS else ""))
    try:
        data = json.loads(raw, parse_constant=_reject_constant)
    except RecursionError:
        raise ValidationError("too_large", f"message: nested more than {MAX_JSON_DEPTH} levels deep") from None
    except ValueError as exc:  # incl. an integer literal of more than 4300 digits
        raise ValidationError("bad_json", f"not valid JSON: {str(exc)[:120]}") from None
    if not isinstance(data, dict):
        raise ValidationError("bad_json", f"expected a JSON object, got {_tname(data)}")
    mid = data.get("id")
    if mid is not None and (isinstance(mid, bool) or not isinstance(mid, int) or not 0 <= mid < 2**53):
        raise ValidationError("wrong_type", f"id: expected a non-negative integer, got {_tname(mid)}")
    mtype = data.get("type")
    try:
        check_json_tree(data, (mtype[:40],) if isinstance(mtype, str) else ("message",))
        return _parse_fields(data, mid)
    except ValidationError as exc:
        exc.mid = mid
        raise


def _parse_fields(data: dict, mid: int | None) -> Message:
    mtype = data.get("type")
    if not isinstance(mtype, str):
        raise ValidationError("missing_field", "message: 'type' (a string) is required")
    schema = SCHEMAS.get(mtype)
    if schema is None:
        raise ValidationError("unknown_type", f"message: unknown type {mtype[:40]!r}; known: {', '.join(SCHEMAS)}")
    unknown = [k for k in data if k not in schema and k not in ("type", "id")]
    if unknown:
        allowed = ", ".join(schema) or "none"
        raise ValidationError("unknown_field", f"{mtype}: unknown field {str(unknown[0])[:40]!r} (allowed: {allowed})")
    fields = {}
    for name, spec in schema.items():
        if name not in data:
            if spec.required:
                raise ValidationError("missing_field", f"{mtype}.{name}: required")
            continue
        fields[name] = _check_field(mtype, name, spec, data[name])
    if mtype == "tiles_preload":
        if fields["south"] >= fields["north"] or fields["west"] >= fields["east"]:
            raise ValidationError("out_of_range", "tiles_preload: expected south < north and west < east")
        if fields["zoom_min"] > fields["zoom_max"]:
            raise ValidationError("out_of_range", "tiles_preload: zoom_min > zoom_max")
    return Message(mtype, mid, fields)


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not allowed")
