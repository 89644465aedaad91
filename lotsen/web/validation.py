"""Validation of messages from the browser: JSON objects with a `type`, known fields only,
each checked for type and range. Every refusal is a `ValidationError` whose message names the
message type and the field, e.g. ``manual.surge: 1.5 outside [-1, 1]``.

Client -> server messages (all may carry an integer `id`, echoed in the reply):

====== ===================================================== =========
type   fields                                                pilot only
====== ===================================================== =========
auth   token: str, takeover: bool (optional)                 no
release                                                      yes
ping   t: number (optional, client clock, echoed)            no
command action: one of lotsen.messages.OPERATOR_ACTIONS      yes
manual surge, sway, yaw: numbers in [-1, 1]                  yes
plan   route: route dict (docs/planning.md schema)           no
route  route: route dict -> RouteMessage ("use this route")  yes
export route: route dict, format: "yaml" | "geojson"         no
import text: str, format: "yaml" | "geojson"                 no
====== ===================================================== =========
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from lotsen.messages import OPERATOR_ACTIONS

MAX_MESSAGE_CHARS = 512 * 1024
MAX_ROUTE_NODES = 200
MAX_POLYGONS = 50
MAX_POLYGON_VERTICES = 1000
MAX_TOKEN_CHARS = 256
MAX_IMPORT_CHARS = 400 * 1024


class ValidationError(Exception):
    def __init__(self, code: str, message: str, mid: int | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.mid = mid  # the message's id when it could be read, so the reply can be matched


@dataclass(frozen=True)
class Field:
    kind: str  # "number", "bool", "str", "enum", "route"
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
    "command": {"action": Field("enum", choices=OPERATOR_ACTIONS)},
    "manual": {"surge": _NUM_UNIT, "sway": _NUM_UNIT, "yaw": _NUM_UNIT},
    "plan": {"route": Field("route")},
    "route": {"route": Field("route")},
    "export": {"route": Field("route"), "format": Field("enum", choices=("yaml", "geojson"))},
    "import": {"text": Field("str", max_len=MAX_IMPORT_CHARS), "format": Field("enum", choices=("yaml", "geojson"))},
}

PILOT_ONLY = frozenset({"release", "command", "manual", "route"})


@dataclass(frozen=True)
class Message:
    type: str
    id: int | None
    fields: dict[str, Any]


def _check_route_size(route: Any, where: str) -> None:
    """Structure caps only (the planner's own loader checks the schema and reports per node)."""
    if not isinstance(route, dict):
        raise ValidationError("wrong_type", f"{where}: expected an object, got {_tname(route)}")
    nodes = route.get("nodes")
    if isinstance(nodes, list) and len(nodes) > MAX_ROUTE_NODES:
        raise ValidationError("too_large", f"{where}.nodes: {len(nodes)} nodes, at most {MAX_ROUTE_NODES}")
    polys = [route.get("area")] if route.get("area") is not None else []
    obstacles = route.get("obstacles")
    if isinstance(obstacles, list):
        if len(obstacles) > MAX_POLYGONS:
            raise ValidationError("too_large", f"{where}.obstacles: {len(obstacles)} polygons, at most {MAX_POLYGONS}")
        polys += [o.get("polygon") if isinstance(o, dict) else o for o in obstacles]
    for p in polys:
        if isinstance(p, list) and len(p) > MAX_POLYGON_VERTICES:
            raise ValidationError("too_large", f"{where}: a polygon has {len(p)} vertices, at most {MAX_POLYGON_VERTICES}")


def _tname(v: Any) -> str:
    return {dict: "object", list: "array", str: "string", bool: "boolean", type(None): "null",
            int: "number", float: "number"}.get(type(v), type(v).__name__)


def _check_field(mtype: str, name: str, spec: Field, value: Any) -> Any:
    where = f"{mtype}.{name}"
    if spec.kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValidationError("wrong_type", f"{where}: expected a number, got {_tname(value)}")
        v = float(value)
        if not math.isfinite(v):
            raise ValidationError("out_of_range", f"{where}: {value!r} is not finite")
        if not spec.lo <= v <= spec.hi:
            raise ValidationError("out_of_range", f"{where}: {v:g} outside [{spec.lo:g}, {spec.hi:g}]")
        return v
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


def parse_message(raw: Any) -> Message:
    """Decode and validate one WebSocket text frame."""
    if not isinstance(raw, str):
        raise ValidationError("bad_json", "expected a JSON text message")
    if len(raw) > MAX_MESSAGE_CHARS:
        raise ValidationError("too_large", f"message of {len(raw)} characters, at most {MAX_MESSAGE_CHARS}")
    try:
        data = json.loads(raw, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as exc:
        raise ValidationError("bad_json", f"not valid JSON: {str(exc)[:120]}") from None
    if not isinstance(data, dict):
        raise ValidationError("bad_json", f"expected a JSON object, got {_tname(data)}")
    mid = data.get("id")
    if mid is not None and (isinstance(mid, bool) or not isinstance(mid, int) or not 0 <= mid < 2**53):
        raise ValidationError("wrong_type", f"id: expected a non-negative integer, got {_tname(mid)}")
    try:
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
    return Message(mtype, mid, fields)


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not allowed")
