"""What an operator asks of a survey: an area (a polygon) covered by parallel lines, or lines given
one by one (a re-run over holes), with the spacing, direction, speed and turn room the boat needs.

Pure data and its checks: every number is a `lotsen.settings.Number` with its physical range, and
every refusal names the key (`survey.spacing_m: 0 m outside the allowed range 0.1 to 100 m`). The
lines themselves are made by `lotsen.planning.survey.lines`, the route nodes by
`lotsen.planning.survey.expand`.

Conventions: local NED metres [north, east]; `angle_deg` is the direction the lines run, clockwise
from north, as QGroundControl's Survey `angle` (0: north-south lines, 90: east-west lines).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import shapely
from shapely.geometry import Polygon

from lotsen.errors import ConfigError
from lotsen.settings import Number

Side = Literal["both", "port", "starboard"]
SIDES = ("both", "port", "starboard")
#: QGroundControl's entry locations (SurveyComplexItem::EntryLocation), in the lines' own frame:
#: "left" is the first line on the port side of the line direction, "top" starts it at its far end
ENTRY_CORNERS = ("top_left", "top_right", "bottom_left", "bottom_right")

SPACING = Number(0.1, 100.0, "m")
ANGLE = Number(-360.0, 360.0, "deg")
SPEED = Number(0.05, 5.0, "m/s")          # lotsen.planning.route's node speed set-points
TURNAROUND = Number(0.0, 100.0, "m")
TURN_RADIUS = Number(1.5, 100.0, "m")     # 1.5 x the planner's default minimum turn radius: the cubics between turn nodes fit
MARGIN = Number(0.0, 50.0, "m")
COORDINATE = Number(-2000.0, 2000.0, "m")  # lotsen.planning.route.MAX_COORDINATE_M
ENTRY = Number(0, 3, integer=True)
#: a survey asks for at most this many lines (all passes): beyond it the route is kilometres long
MAX_LINES = 400
#: the lateral acceleration the default turn radius is sized for (the planner's default a_lat_max):
#: at this radius the boat keeps its line speed through the turn
TURN_LATERAL_ACCEL_MPS2 = 0.3
#: the default turn radius is at least this (twice the planner's default minimum turn radius, so
#: the cubic pieces between turn nodes keep well inside the curvature bound)
MIN_DEFAULT_TURN_RADIUS_M = 2.0


@dataclass(frozen=True)
class SurveyPattern:
    """A survey: parallel lines over `polygon` (None: the route's navigable area, shrunk so the
    boat can turn inside it), or the explicit `lines` [((n0, e0), (n1, e1)), ...] flown in order.

    spacing_m: distance between neighbouring lines; for a one-sided sensor (`side` port or
        starboard: side-scan on one side) the width the sensor covers on that side.
    turnaround_m: straight run before each line starts and after it ends (lead-in/out), so the boat
        is on the line, at speed and heading, where the line starts.
    turn_radius_m: radius of the turns between lines (None: from the speed, see `turn_radius`).
    margin_m: lines end this far from obstacles and the area's edge (the planner's clearance).
    entry: which corner the first line starts at (0-3, QGroundControl's entryLocation; None: the
        corner nearest the harbour).
    crosshatch: fly the area again with lines at angle + 90 deg (QGroundControl's Refly90Degrees).
    """

    spacing_m: float = 2.0
    angle_deg: float = 0.0
    speed_mps: float = 0.5
    polygon: tuple[tuple[float, float], ...] | None = None
    lines: tuple[tuple[tuple[float, float], tuple[float, float]], ...] | None = None
    turnaround_m: float = 2.0
    turn_radius_m: float | None = None
    margin_m: float = 0.5
    entry: int | None = None
    crosshatch: bool = False
    side: Side = "both"

    def turn_radius(self) -> float:
        """The turn radius in use: given, else the one at which the line speed needs no more than
        `TURN_LATERAL_ACCEL_MPS2` (v^2 / a), at least `MIN_DEFAULT_TURN_RADIUS_M`."""
        if self.turn_radius_m is not None:
            return self.turn_radius_m
        return max(MIN_DEFAULT_TURN_RADIUS_M, round(self.speed_mps**2 / TURN_LATERAL_ACCEL_MPS2 * 1.1, 3))


_KEYS = {"spacing_m", "angle_deg", "speed_mps", "polygon", "lines", "turnaround_m", "turn_radius_m", "margin_m",
         "entry", "crosshatch", "side"}


def _point(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where}: expected [north, east], got {str(value)[:60]}")
    return COORDINATE.check(value[0], f"{where}[0]"), COORDINATE.check(value[1], f"{where}[1]")


def check_survey_polygon(ring: Any, where: str) -> tuple[tuple[float, float], ...]:
    """A survey polygon: at least 3 corners that close a simple polygon of non-zero area; a ring
    written closed (first corner repeated last) is accepted. ConfigError naming what is wrong."""
    if not isinstance(ring, (list, tuple)):
        raise ConfigError(f"{where}: expected a list of [north, east] corners, got {type(ring).__name__}")
    pts = [_point(p, f"{where}[{j}]") for j, p in enumerate(ring)]
    if len(pts) > 3 and pts[0] == pts[-1]:
        pts.pop()
    if len(pts) < 3:
        raise ConfigError(f"{where}: {len(pts)} corner(s) do not close a polygon (a survey area needs at least 3)")
    poly = Polygon(pts)
    if not poly.is_valid:
        raise ConfigError(f"{where}: the corners do not close a simple polygon: its edges cross "
                          f"({shapely.is_valid_reason(poly)}); list the corners in order around the area")
    if poly.area < 1e-3:
        raise ConfigError(f"{where}: the polygon has no area (its corners lie on a line)")
    return tuple(pts)


def pattern_from_dict(data: Any, where: str = "survey") -> SurveyPattern:
    """A SurveyPattern from the route file's `survey:` mapping; ConfigError names the key."""
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping with keys {sorted(_KEYS)}, got {type(data).__name__}")
    unknown = set(map(str, data)) - _KEYS
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_KEYS)}")
    if data.get("polygon") is not None and data.get("lines") is not None:
        raise ConfigError(f"{where}: give a polygon (lines are made over it) or lines, not both")
    kw: dict[str, Any] = {}
    for key, number in (("spacing_m", SPACING), ("angle_deg", ANGLE), ("speed_mps", SPEED),
                        ("turnaround_m", TURNAROUND), ("margin_m", MARGIN)):
        if key in data:
            kw[key] = float(number.check(data[key], f"{where}.{key}"))
    if data.get("turn_radius_m") is not None:
        kw["turn_radius_m"] = float(TURN_RADIUS.check(data["turn_radius_m"], f"{where}.turn_radius_m"))
    if data.get("entry") is not None:
        entry = data["entry"]
        kw["entry"] = ENTRY_CORNERS.index(entry) if entry in ENTRY_CORNERS else ENTRY.check(entry, f"{where}.entry")
    if "crosshatch" in data:
        if not isinstance(data["crosshatch"], bool):
            raise ConfigError(f"{where}.crosshatch: expected true or false, got {str(data['crosshatch'])[:30]}")
        kw["crosshatch"] = data["crosshatch"]
    if "side" in data:
        if data["side"] not in SIDES:
            raise ConfigError(f"{where}.side: expected one of {', '.join(SIDES)}, got {str(data['side'])[:30]}")
        kw["side"] = data["side"]
    if data.get("polygon") is not None:
        kw["polygon"] = check_survey_polygon(data["polygon"], f"{where}.polygon")
    if data.get("lines") is not None:
        lines = data["lines"]
        if not isinstance(lines, (list, tuple)) or not lines:
            raise ConfigError(f"{where}.lines: expected a list of [[north, east], [north, east]] lines")
        if len(lines) > MAX_LINES:
            raise ConfigError(f"{where}.lines: {len(lines)} lines, more than a survey may have ({MAX_LINES})")
        out = []
        for i, ln in enumerate(lines):
            if not isinstance(ln, (list, tuple)) or len(ln) != 2:
                raise ConfigError(f"{where}.lines[{i}]: expected [[north, east], [north, east]] (start, end)")
            a, b = _point(ln[0], f"{where}.lines[{i}][0]"), _point(ln[1], f"{where}.lines[{i}][1]")
            if math.hypot(b[0] - a[0], b[1] - a[1]) < 0.1:
                raise ConfigError(f"{where}.lines[{i}]: start and end are {math.hypot(b[0] - a[0], b[1] - a[1]):.2f} m "
                                  "apart; a line is at least 0.1 m long")
            out.append((a, b))
        kw["lines"] = tuple(out)
    return SurveyPattern(**kw)


def pattern_to_dict(p: SurveyPattern) -> dict:
    """The route file's `survey:` mapping (inverse of `pattern_from_dict`)."""
    out: dict[str, Any] = {"spacing_m": p.spacing_m, "angle_deg": p.angle_deg, "speed_mps": p.speed_mps,
                           "turnaround_m": p.turnaround_m, "margin_m": p.margin_m}
    if p.polygon is not None:
        out["polygon"] = [list(v) for v in p.polygon]
    if p.lines is not None:
        out["lines"] = [[list(a), list(b)] for a, b in p.lines]
    if p.turn_radius_m is not None:
        out["turn_radius_m"] = p.turn_radius_m
    if p.entry is not None:
        out["entry"] = ENTRY_CORNERS[p.entry]
    if p.crosshatch:
        out["crosshatch"] = True
    if p.side != "both":
        out["side"] = p.side
    return out
