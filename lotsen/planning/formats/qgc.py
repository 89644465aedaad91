"""QGroundControl's files: the `.plan` JSON (mission, geofence, rally points; format of QGC's
developer guide, "Plan File Format") and the plain-text `QGC WPL 110` waypoint list that Mission
Planner and MAVProxy write (mission only, line 0 = home). Both parse to a `Plan` of MAVLink items
(lotsen.planning.formats.items) and are written from one."""

from __future__ import annotations

import json
import math
import sys
from typing import Any

from lotsen.errors import ConfigError
from lotsen.files import parse_json
from lotsen.planning.formats.items import (
    FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, NAV_FENCE_CIRCLE_EXCLUSION, NAV_FENCE_CIRCLE_INCLUSION,
    NAV_FENCE_POLYGON_VERTEX_EXCLUSION, NAV_FENCE_POLYGON_VERTEX_INCLUSION, NAV_RALLY_POINT, NAV_WAYPOINT,
    MissionItem, Plan, SurveyItem,
)
from lotsen.settings import Number

WPL_HEADER = "QGC WPL 110"
FIRMWARE_ARDUPILOT = 3
VEHICLE_SURFACE_BOAT = 11  # MAV_TYPE_SURFACE_BOAT
MAX_ITEMS = 2000


_FINITE = Number(-sys.float_info.max, sys.float_info.max)
_MAV_UINT16 = Number(0, 65535, integer=True)  # a MAV_CMD or MAV_FRAME number


def _num(value: Any, where: str, allow_null: bool = False) -> float:
    """A finite number (settings.Number: no NaN, infinity or denormal); null is NaN where allowed."""
    if value is None and allow_null:
        return math.nan  # QGroundControl writes NaN parameters as null
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: expected a number, got {str(value)[:40]!r}")
    return _FINITE.check(value, where)


def _latlon(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) < 2:
        raise ConfigError(f"{where}: expected [latitude, longitude, ...], got {str(value)[:60]}")
    return _num(value[0], f"{where}[0]"), _num(value[1], f"{where}[1]")


def _dict(value: Any, where: str) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"{where}: expected an object, got {type(value).__name__}")
    return value


def parse_plan(text: str, where: str = "plan") -> Plan:
    """A QGroundControl `.plan` file's text as a Plan; ConfigError names the item."""
    data = _dict(parse_json(text, where, ConfigError), where)
    if data.get("fileType") != "Plan":
        raise ConfigError(f"{where}: fileType {str(data.get('fileType'))[:30]!r}; a QGroundControl plan says \"Plan\"")
    plan = Plan()
    # the harbour's heading: lotsen's own key (a .plan's home and rally points have no heading;
    # QGroundControl ignores the key)
    extra = data.get("lotsen") if isinstance(data.get("lotsen"), dict) else {}
    yaw = _num(extra.get("harbour_heading_deg", 0.0), f"{where}.lotsen.harbour_heading_deg")
    mission = _dict(data.get("mission") or {}, f"{where}.mission")
    home = mission.get("plannedHomePosition")
    if home is not None:
        lat, lon = _latlon(home, f"{where}.mission.plannedHomePosition")
        plan.home = MissionItem(0, NAV_WAYPOINT, FRAME_GLOBAL, param4=yaw, lat_deg=lat, lon_deg=lon)
    if mission.get("cruiseSpeed") is not None:
        plan.cruise_speed_mps = _num(mission["cruiseSpeed"], f"{where}.mission.cruiseSpeed")
    items = mission.get("items") or []
    if not isinstance(items, list) or len(items) > MAX_ITEMS:
        raise ConfigError(f"{where}.mission.items: expected a list of at most {MAX_ITEMS} items")
    for k, it in enumerate(items):
        w = f"{where}.mission.items[{k}]"
        it = _dict(it, w)
        if it.get("type") == "ComplexItem" and it.get("complexItemType") == "survey":
            if plan.survey is not None:
                raise ConfigError(f"{w}: a second survey; lotsen flies one survey a route (save each in a plan of its own)")
            plan.survey = parse_survey_item(it, w)
            continue
        if it.get("type") != "SimpleItem":
            raise ConfigError(f"{w}: a {str(it.get('complexItemType') or it.get('type'))[:40]} item is not supported; "
                              "lotsen takes waypoints and surveys (in QGroundControl: convert the pattern to waypoints)")
        if plan.survey is not None:
            raise ConfigError(f"{w}: an item after the survey; lotsen's survey route ends with its last line, where the "
                              "boat holds (send RTL to return)")
        params = it.get("params")
        if not isinstance(params, list) or len(params) != 7:
            raise ConfigError(f"{w}.params: expected 7 numbers")
        p = [_num(v, f"{w}.params[{i}]", allow_null=True) for i, v in enumerate(params)]
        plan.mission.append(MissionItem(k + 1, _MAV_UINT16.check(it.get("command"), f"{w}.command"),
                                        _MAV_UINT16.check(it.get("frame", FRAME_GLOBAL_RELATIVE_ALT), f"{w}.frame"),
                                        p[0], p[1], p[2], p[3], p[4], p[5], p[6], bool(it.get("autoContinue", True))))
    fence = _dict(data.get("geoFence") or {}, f"{where}.geoFence")
    polygons = fence.get("polygons") or []
    if fence.get("polygon"):  # version 1: one inclusion polygon
        polygons = [{"inclusion": True, "polygon": fence["polygon"]}] + list(polygons)
    for k, poly in enumerate(polygons):
        w = f"{where}.geoFence.polygons[{k}]"
        poly = _dict(poly, w)
        corners = poly.get("polygon")
        if not isinstance(corners, list) or len(corners) < 3:
            raise ConfigError(f"{w}.polygon: expected at least 3 [latitude, longitude] corners")
        cmd = NAV_FENCE_POLYGON_VERTEX_INCLUSION if poly.get("inclusion", True) else NAV_FENCE_POLYGON_VERTEX_EXCLUSION
        for j, c in enumerate(corners):
            lat, lon = _latlon(c, f"{w}.polygon[{j}]")
            plan.fence.append(MissionItem(len(plan.fence), cmd, FRAME_GLOBAL, param1=float(len(corners)),
                                          lat_deg=lat, lon_deg=lon))
    for k, circ in enumerate(fence.get("circles") or []):
        w = f"{where}.geoFence.circles[{k}]"
        circ = _dict(circ, w)
        c = _dict(circ.get("circle"), f"{w}.circle")
        lat, lon = _latlon(c.get("center"), f"{w}.circle.center")
        cmd = NAV_FENCE_CIRCLE_INCLUSION if circ.get("inclusion", True) else NAV_FENCE_CIRCLE_EXCLUSION
        plan.fence.append(MissionItem(len(plan.fence), cmd, FRAME_GLOBAL, param1=_num(c.get("radius"), f"{w}.radius"),
                                      lat_deg=lat, lon_deg=lon))
    rally = _dict(data.get("rallyPoints") or {}, f"{where}.rallyPoints")
    for k, pt in enumerate(rally.get("points") or []):
        lat, lon = _latlon(pt, f"{where}.rallyPoints.points[{k}]")
        plan.rally.append(MissionItem(k, NAV_RALLY_POINT, FRAME_GLOBAL_RELATIVE_ALT, param4=yaw, lat_deg=lat,
                                      lon_deg=lon))
    return plan


SURVEY_SPACING = Number(0.1, 100.0, "m")      # lotsen.planning.survey.pattern's ranges
SURVEY_TURNAROUND = Number(0.0, 100.0, "m")
SURVEY_ANGLE = Number(-360.0, 360.0, "deg")
SURVEY_ENTRY = Number(0, 3, integer=True)
MANUAL_CAMERA = "Manual (no camera specs)"    # QGroundControl's CameraCalc name for a spacing set by hand
_LOTSEN_SURVEY_KEYS = {"speed_mps", "turn_radius_m", "margin_m", "side", "entry"}


def parse_survey_item(it: dict, w: str) -> SurveyItem:
    """QGroundControl's Survey complex item (versions 4 and 5: `polygon`, `angle`, `entryLocation`,
    `flyAlternateTransects`, TransectStyleComplexItem's `TurnAroundDistance`, `Refly90Degrees` and
    CameraCalc's `AdjustedFootprintSide`, the line spacing whether typed or computed from a camera's
    footprint). lotsen makes its own lines from these (with the boat's turns); the item's saved
    `Items` (QGroundControl's expansion for its vehicle) are not flown."""
    version = it.get("version")
    if version not in (4, 5):
        raise ConfigError(f"{w}: survey item version {str(version)[:10]}; lotsen reads versions 4 and 5 (QGroundControl "
                          "4.x; open and save the plan in a current QGroundControl)")
    corners = it.get("polygon")
    if not isinstance(corners, list):
        raise ConfigError(f"{w}.polygon: expected a list of [latitude, longitude] corners")
    if len(corners) > 3 and corners[0] == corners[-1]:
        corners = corners[:-1]
    if len(corners) < 3:
        raise ConfigError(f"{w}.polygon: {len(corners)} corner(s) do not close a polygon (a survey area needs at least 3)")
    if len(corners) > MAX_ITEMS:
        raise ConfigError(f"{w}.polygon: {len(corners)} corners, at most {MAX_ITEMS}")
    ring = tuple(_latlon(c, f"{w}.polygon[{j}]") for j, c in enumerate(corners))
    if it.get("flyAlternateTransects"):
        raise ConfigError(f"{w}.flyAlternateTransects: true; lotsen turns between neighbouring lines itself (the "
                          "boat's turns are part of its plan): set it false")
    transect = _dict(it.get("TransectStyleComplexItem"), f"{w}.TransectStyleComplexItem")
    camera = _dict(transect.get("CameraCalc"), f"{w}.TransectStyleComplexItem.CameraCalc")
    spacing = SURVEY_SPACING.check(camera.get("AdjustedFootprintSide"),
                                   f"{w}.TransectStyleComplexItem.CameraCalc.AdjustedFootprintSide (line spacing)")
    turnaround = SURVEY_TURNAROUND.check(transect.get("TurnAroundDistance", 0.0),
                                         f"{w}.TransectStyleComplexItem.TurnAroundDistance")
    refly = transect.get("Refly90Degrees", False)
    if not isinstance(refly, bool):
        raise ConfigError(f"{w}.TransectStyleComplexItem.Refly90Degrees: expected true or false")
    extra = it.get("lotsen") or {}
    if not isinstance(extra, dict) or set(map(str, extra)) - _LOTSEN_SURVEY_KEYS:
        raise ConfigError(f"{w}.lotsen: expected a mapping with keys {sorted(_LOTSEN_SURVEY_KEYS)}")
    return SurveyItem(ring, float(SURVEY_ANGLE.check(it.get("angle"), f"{w}.angle")), float(spacing),
                      float(turnaround), int(SURVEY_ENTRY.check(it.get("entryLocation", 0), f"{w}.entryLocation")),
                      refly, dict(extra))


def survey_item_json(survey: SurveyItem, items: list[dict], speed_mps: float | None) -> dict:
    """QGroundControl's Survey complex item (version 5) for `survey`; `items`: the waypoints it
    expands to (QGroundControl shows and flies these, lotsen makes its lines from the pattern)."""
    points = [[it["params"][4], it["params"][5]] for it in items if it["command"] == NAV_WAYPOINT]
    extra = dict(survey.extra)
    if speed_mps:
        extra["speed_mps"] = speed_mps
    return {"type": "ComplexItem", "complexItemType": "survey", "version": 5,
            "polygon": [list(c) for c in survey.polygon], "angle": survey.angle_deg,
            "entryLocation": survey.entry, "flyAlternateTransects": False, "splitConcavePolygons": False,
            "TransectStyleComplexItem": {
                "version": 1, "TurnAroundDistance": survey.turnaround_m, "Refly90Degrees": survey.crosshatch,
                "CameraTriggerInTurnAround": False, "HoverAndCapture": False, "FollowTerrain": False, "CameraShots": 0,
                "CameraCalc": {"version": 1, "CameraName": MANUAL_CAMERA, "AdjustedFootprintSide": survey.spacing_m,
                               "AdjustedFootprintFrontal": survey.spacing_m, "DistanceToSurface": 0,
                               "DistanceToSurfaceRelative": True},
                "Items": items, "VisualTransectPoints": points},
            "lotsen": extra}


def _json_num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def write_plan(plan: Plan) -> str:
    """A `.plan` file (QGroundControl's JSON) of `plan`, for ArduPilot Rover on a surface boat."""
    items = [{"type": "SimpleItem", "autoContinue": it.autocontinue, "command": it.command, "doJumpId": k + 1,
              "frame": it.frame, "params": [_json_num(v) for v in (it.param1, it.param2, it.param3, it.param4,
                                                                     it.lat_deg, it.lon_deg, it.alt_m)],
              **({"Altitude": 0, "AltitudeMode": 1, "AMSLAltAboveTerrain": None} if it.command == NAV_WAYPOINT else {})}
             for k, it in enumerate(plan.mission)]
    if plan.survey is not None:
        items = [survey_item_json(plan.survey, items, plan.cruise_speed_mps)]
    polygons, circles = [], []
    i = 0
    while i < len(plan.fence):
        it = plan.fence[i]
        if it.command in (NAV_FENCE_POLYGON_VERTEX_INCLUSION, NAV_FENCE_POLYGON_VERTEX_EXCLUSION):
            n = int(it.param1)
            polygons.append({"version": 1, "inclusion": it.command == NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                             "polygon": [[v.lat_deg, v.lon_deg] for v in plan.fence[i:i + n]]})
            i += n
            continue
        if it.command in (NAV_FENCE_CIRCLE_INCLUSION, NAV_FENCE_CIRCLE_EXCLUSION):
            circles.append({"version": 1, "inclusion": it.command == NAV_FENCE_CIRCLE_INCLUSION,
                            "circle": {"center": [it.lat_deg, it.lon_deg], "radius": it.param1}})
        i += 1
    home = plan.home
    data = {"fileType": "Plan", "version": 1, "groundStation": "lotsen",
            "mission": {"version": 2, "firmwareType": FIRMWARE_ARDUPILOT, "vehicleType": VEHICLE_SURFACE_BOAT,
                        "cruiseSpeed": plan.cruise_speed_mps or 0.5, "hoverSpeed": 0, "globalPlanAltitudeMode": 1,
                        "plannedHomePosition": [home.lat_deg, home.lon_deg, 0] if home else None, "items": items},
            "geoFence": {"version": 2, "polygons": polygons, "circles": circles},
            "rallyPoints": {"version": 2, "points": [[r.lat_deg, r.lon_deg, 0] for r in plan.rally]}}
    if home is not None and math.isfinite(home.param4) and home.param4:
        data["lotsen"] = {"harbour_heading_deg": home.param4}
    return json.dumps(data, indent=2, allow_nan=False)


def parse_wpl(text: str, where: str = "waypoints") -> Plan:
    """`QGC WPL 110` text (tab- or space-separated): line 0 is home, the rest the mission."""
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines or not lines[0].strip().startswith("QGC WPL"):
        raise ConfigError(f"{where}: the first line must be '{WPL_HEADER}'")
    if lines[0].split()[-1] != "110":
        raise ConfigError(f"{where}: version {lines[0].split()[-1]!r}; only {WPL_HEADER} is read")
    if len(lines) - 1 > MAX_ITEMS:
        raise ConfigError(f"{where}: {len(lines) - 1} items, at most {MAX_ITEMS}")
    plan = Plan()
    for k, line in enumerate(lines[1:], start=2):
        f = line.split()
        if len(f) != 12:
            raise ConfigError(f"{where}: line {k}: expected 12 fields (index, current, frame, command, 4 params, "
                              f"latitude, longitude, altitude, autocontinue), got {len(f)}")
        try:
            seq, _, frame, cmd = (_MAV_UINT16.parse(v, f"{where}: line {k}") for v in f[:4])
            # a parameter may be NaN (unused, as ArduPilot writes it); position and altitude finite
            vals = [float(v) if v.lower() == "nan" and i < 4 else _FINITE.parse(v, f"{where}: line {k}")
                    for i, v in enumerate(f[4:11])]
            auto = bool(_MAV_UINT16.parse(f[11], f"{where}: line {k}"))
        except ValueError:
            raise ConfigError(f"{where}: line {k}: a field is not a number: {line[:80]!r}") from None
        item = MissionItem(seq, cmd, frame, *vals, auto)
        if seq == 0 and plan.home is None and not plan.mission:
            plan.home = item
        else:
            plan.mission.append(item)
    return plan


def write_wpl(plan: Plan) -> str:
    """`QGC WPL 110` text: home as line 0 (current = 1), then the mission items."""
    out = [WPL_HEADER]
    items = ([plan.home] if plan.home is not None else []) + plan.mission
    for k, it in enumerate(items):
        vals = (it.param1, it.param2, it.param3, it.param4, it.lat_deg, it.lon_deg, it.alt_m)
        out.append("\t".join([str(k), "1" if k == 0 else "0", str(it.frame), str(it.command),
                              *(f"{v:.9f}" if math.isfinite(v) else "nan" for v in vals), "1" if it.autocontinue else "0"]))
    return "\n".join(out) + "\n"
