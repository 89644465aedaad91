"""Mission items (MAVLink's MAV_CMD plan items) <-> a lotsen route.

The ground stations' route files (QGroundControl `.plan`, `QGC WPL 110`) and the MAVLink mission
protocol carry the same items: a home position, waypoints, speed changes, fence polygons and
rally points in WGS84. This module is the one translation between them and lotsen's route (the
YAML schema of docs/planning.md, in local metres of a geographic origin):

- the **harbour** is the single rally point when there is one, else home (mission item 0, the
  `.plan`'s `plannedHomePosition`); its heading points at the first node;
- **NAV_WAYPOINT** (and NAV_SPLINE_WAYPOINT) items are the nodes in order; a waypoint's yaw
  (param 4) is the node's heading when it is finite and not 0 (Mission Planner writes 0 and
  QGroundControl NaN for "no yaw", ArduPilot Rover ignores it; write 360 for north); otherwise the
  heading bisects the legs into and out of the node (the last node: the leg into it);
- **DO_CHANGE_SPEED** (param 2, m/s; <= 0 means "no change") sets the speed of the waypoints after
  it; before the first one they get `default_speed_mps` (the ground station's cruise speed);
- **fence**: the first inclusion polygon is the navigable area, further inclusion polygons are
  regions the boat must stay in too (obstacles forbidden outside), exclusion polygons are
  obstacles; circles become 32-corner polygons;
- altitudes are ignored (a boat); what a boat cannot do (take-off, landing, loiters, jumps,
  returns inside a mission, unknown commands) is refused with an error naming the item.

Pure: no I/O. Exports write the inverse (a waypoint per node with its heading as yaw, a speed
change whenever the speed differs from the waypoint before).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable

from lotsen.errors import ConfigError
from lotsen.model.geodetic import LocalFrame
from lotsen.planning.route import GeoOrigin, Route

# MAV_CMD numbers (common.xml); lotsen.planning does not import pymavlink
NAV_WAYPOINT = 16
NAV_LOITER_UNLIM = 17
NAV_LOITER_TURNS = 18
NAV_LOITER_TIME = 19
NAV_RETURN_TO_LAUNCH = 20
NAV_LAND = 21
NAV_TAKEOFF = 22
NAV_LOITER_TO_ALT = 31
NAV_SPLINE_WAYPOINT = 82
DO_JUMP = 177
DO_CHANGE_SPEED = 178
NAV_FENCE_RETURN_POINT = 5000
NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
NAV_FENCE_POLYGON_VERTEX_EXCLUSION = 5002
NAV_FENCE_CIRCLE_INCLUSION = 5003
NAV_FENCE_CIRCLE_EXCLUSION = 5004
NAV_RALLY_POINT = 5100
# MAV_FRAME
FRAME_GLOBAL = 0
FRAME_MISSION = 2
FRAME_GLOBAL_RELATIVE_ALT = 3
FRAME_GLOBAL_INT = 5
FRAME_GLOBAL_RELATIVE_ALT_INT = 6
GLOBAL_FRAMES = (FRAME_GLOBAL, FRAME_GLOBAL_RELATIVE_ALT, FRAME_GLOBAL_INT, FRAME_GLOBAL_RELATIVE_ALT_INT, 10, 11)

MISSION, FENCE, RALLY = "mission", "fence", "rally"
CIRCLE_CORNERS = 32
#: a waypoint yaw of exactly this is north when written by lotsen (0 means "no yaw")
NORTH_YAW_DEG = 360.0

_REFUSED = {
    NAV_TAKEOFF: "take-off: a boat does not take off; start the route from the harbour (home)",
    NAV_LAND: "landing: a boat does not land; end the route at its last waypoint and send RTL to return",
    NAV_LOITER_UNLIM: "loiter: lotsen does not loiter at a waypoint; HOLD (LOITER mode) keeps station",
    NAV_LOITER_TURNS: "loiter turns: lotsen does not circle a waypoint",
    NAV_LOITER_TIME: "loiter time: lotsen does not wait at a waypoint; HOLD (LOITER mode) keeps station",
    NAV_LOITER_TO_ALT: "loiter to altitude: a boat has no altitude",
    NAV_RETURN_TO_LAUNCH: "return to launch inside a mission: a lotsen route ends holding at its last waypoint; "
                          "send RTL when it is done",
    DO_JUMP: "jump: lotsen routes do not loop; repeat the waypoints instead",
}
_COMMAND_NAMES = {NAV_WAYPOINT: "WAYPOINT", NAV_SPLINE_WAYPOINT: "SPLINE_WAYPOINT", DO_CHANGE_SPEED: "DO_CHANGE_SPEED",
                  NAV_FENCE_POLYGON_VERTEX_INCLUSION: "FENCE_POLYGON_VERTEX_INCLUSION",
                  NAV_FENCE_POLYGON_VERTEX_EXCLUSION: "FENCE_POLYGON_VERTEX_EXCLUSION",
                  NAV_FENCE_CIRCLE_INCLUSION: "FENCE_CIRCLE_INCLUSION", NAV_FENCE_CIRCLE_EXCLUSION: "FENCE_CIRCLE_EXCLUSION",
                  NAV_RALLY_POINT: "RALLY_POINT", NAV_FENCE_RETURN_POINT: "FENCE_RETURN_POINT", **{
                      k: v.split(":")[0].upper().replace(" ", "_") for k, v in _REFUSED.items()}}


class MissionItemError(ConfigError):
    """An item a boat cannot do, or one that does not make sense; names the plan and the item."""

    def __init__(self, plan: str, seq: int, text: str) -> None:
        super().__init__(f"{plan} item {seq}: {text}")
        self.plan = plan
        self.seq = seq


@dataclass(frozen=True)
class MissionItem:
    """One plan item: MAV_CMD `command` with its parameters; x/y as latitude/longitude in degrees
    (global frames), z the altitude (ignored by a boat). `seq` is its place in its plan."""

    seq: int
    command: int
    frame: int = FRAME_GLOBAL_RELATIVE_ALT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_m: float = 0.0
    autocontinue: bool = True

    def name(self) -> str:
        return _COMMAND_NAMES.get(self.command, f"MAV_CMD {self.command}")


@dataclass(frozen=True)
class SurveyItem:
    """A ground station's survey pattern (QGroundControl's Survey complex item) in WGS84: the
    polygon's corners (latitude, longitude), the lines' angle (deg clockwise from north), spacing
    and turnaround (m), QGroundControl's entry location (0-3), crosshatch (Refly90Degrees), and
    lotsen's own settings a .plan carries under "lotsen" (speed, turn radius, margin, side)."""

    polygon: tuple[tuple[float, float], ...]
    angle_deg: float
    spacing_m: float
    turnaround_m: float
    entry: int = 0
    crosshatch: bool = False
    extra: dict = field(default_factory=dict)


@dataclass
class Plan:
    """Home, mission, fence and rally items of one plan (a file, or what a ground station uploaded).
    `survey`: a survey pattern (a .plan's Survey item); `mission` then holds the speed items before
    it (read) or the waypoints it expands to (written, for ground stations that fly items)."""

    home: MissionItem | None = None
    mission: list[MissionItem] = field(default_factory=list)
    fence: list[MissionItem] = field(default_factory=list)
    rally: list[MissionItem] = field(default_factory=list)
    cruise_speed_mps: float | None = None
    survey: SurveyItem | None = None


def command_name(command: int) -> str:
    return _COMMAND_NAMES.get(command, f"MAV_CMD {command}")


def _finite(x: float) -> bool:
    return isinstance(x, (int, float)) and math.isfinite(x)


def _position(frame: LocalFrame, item: MissionItem, plan: str) -> tuple[float, float]:
    if item.frame not in GLOBAL_FRAMES:
        raise MissionItemError(plan, item.seq, f"{item.name()} in frame {item.frame}: only global "
                               "(latitude/longitude) frames are supported")
    if not (_finite(item.lat_deg) and _finite(item.lon_deg)) or not -90 <= item.lat_deg <= 90 \
            or not -180 <= item.lon_deg <= 180 or (item.lat_deg == 0.0 and item.lon_deg == 0.0):
        raise MissionItemError(plan, item.seq, f"{item.name()}: latitude {item.lat_deg:g} / longitude "
                               f"{item.lon_deg:g} is not a position")
    n, e = frame.to_ne(item.lat_deg, item.lon_deg)
    return round(n, 4), round(e, 4)


def _bearing_deg(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.degrees(math.atan2(b[1] - a[1], b[0] - a[0])) % 360.0


def computed_headings(points: list[tuple[float, float]]) -> list[float]:
    """Headings (deg) of nodes 1.. of `points` (harbour first): the bisector of the legs into and
    out of each node, the last node the leg into it; a U-turn (opposite legs) takes the leg in."""
    out = []
    for i in range(1, len(points)):
        a, b = points[i - 1], points[i]
        lin = math.atan2(b[1] - a[1], b[0] - a[0])
        if i + 1 < len(points):
            c = points[i + 1]
            lout = math.atan2(c[1] - b[1], c[0] - b[0])
            x, y = math.cos(lin) + math.cos(lout), math.sin(lin) + math.sin(lout)
            h = math.atan2(y, x) if math.hypot(x, y) > 1e-6 else lin
        else:
            h = lin
        out.append(round(math.degrees(h) % 360.0, 6))
    return out


def route_from_plan(plan: Plan, origin: GeoOrigin | None = None, default_speed_mps: float = 0.5,
                    base: dict | None = None) -> dict:
    """The route dict (docs/planning.md's YAML schema) of `plan` in the local frame of `origin`
    (default: the harbour's position, and the dict then carries it as `origin`). `base`: a route
    dict whose parts the plan does not carry are kept (a mission upload keeps the fence the boat
    holds, a fence upload its waypoints). MissionItemError names the item a boat cannot do."""
    rally_pts = [i for i in plan.rally if i.command == NAV_RALLY_POINT]
    for i in plan.rally:
        if i.command != NAV_RALLY_POINT:
            raise MissionItemError(RALLY, i.seq, f"{i.name()}: a rally plan holds RALLY_POINT items only")
    if len(rally_pts) > 1:
        raise MissionItemError(RALLY, rally_pts[1].seq, f"lotsen returns to one harbour: upload one rally point "
                               f"(got {len(rally_pts)})")
    harbour_item = rally_pts[0] if rally_pts else plan.home
    keep_origin = origin is None
    if origin is None:
        if harbour_item is None:
            raise ConfigError("mission: no home position and no rally point: the harbour is unknown")
        origin = GeoOrigin(harbour_item.lat_deg, harbour_item.lon_deg, 0.0)
    frame = LocalFrame(origin.lat_deg, origin.lon_deg, origin.height_m)
    route: dict[str, Any] = {k: v for k, v in (base or {}).items() if k != "origin"}

    if plan.survey is not None:
        route.pop("nodes", None)
        route["survey"] = _survey(plan.survey, plan.mission, frame, default_speed_mps)
    elif plan.home is not None or plan.mission:
        nodes = _nodes(plan.mission, frame, default_speed_mps)
        if not nodes:
            raise ConfigError("mission: no waypoint (a route needs at least one after home)")
        route["nodes"] = nodes
    if harbour_item is not None:
        harbour = _position(frame, harbour_item, RALLY if rally_pts else MISSION)
    elif "harbour" in route:
        harbour = (float(route["harbour"]["north"]), float(route["harbour"]["east"]))
    else:
        raise ConfigError("mission: no home position and no rally point: the harbour is unknown")
    if "nodes" not in route and "survey" not in route:
        raise ConfigError("mission: no waypoints yet (upload the mission)")
    given = _yaw(harbour_item.param4) if harbour_item is not None else route.get("harbour", {}).get("heading_deg")
    if "survey" in route:
        ring = route["survey"]["polygon"]
        centre = (sum(p[0] for p in ring) / len(ring), sum(p[1] for p in ring) / len(ring))
        route["harbour"] = {"north": harbour[0], "east": harbour[1],
                            "heading_deg": given if given is not None else round(_bearing_deg(harbour, centre), 6)}
    else:
        pts = [harbour] + [(float(n["north"]), float(n["east"])) for n in route["nodes"]]
        route["harbour"] = {"north": harbour[0], "east": harbour[1],
                            "heading_deg": given if given is not None else round(_bearing_deg(harbour, pts[1]), 6)}
        _fill_headings(route["nodes"], pts)
    if plan.fence:
        route.pop("area", None)
        route.pop("obstacles", None)
        route.update(_fence(plan.fence, frame))
    if keep_origin:
        route["origin"] = {"lat_deg": origin.lat_deg, "lon_deg": origin.lon_deg, "height_m": origin.height_m}
    return route


def _nodes(items: list[MissionItem], frame: LocalFrame, default_speed_mps: float) -> list[dict]:
    speed = default_speed_mps
    nodes: list[dict] = []
    for it in items:
        if it.command in (NAV_WAYPOINT, NAV_SPLINE_WAYPOINT):
            n, e = _position(frame, it, MISSION)
            nodes.append({"north": n, "east": e, "heading_deg": _yaw(it.param4), "speed_mps": round(speed, 4),
                          "_seq": it.seq})
        elif it.command == DO_CHANGE_SPEED:
            if _finite(it.param2) and it.param2 > 0:
                speed = float(it.param2)
            elif not _finite(it.param2):
                raise MissionItemError(MISSION, it.seq, f"DO_CHANGE_SPEED: speed {it.param2!r} is not a number")
        elif it.command in _REFUSED:
            raise MissionItemError(MISSION, it.seq, _REFUSED[it.command])
        else:
            raise MissionItemError(MISSION, it.seq, f"MAV_CMD {it.command}: not supported by lotsen (waypoints and "
                                   "DO_CHANGE_SPEED only)")
    return nodes


def _survey(item: SurveyItem, before: list[MissionItem], frame: LocalFrame, default_speed_mps: float) -> dict:
    """The route file's `survey:` mapping of a survey item; the speed items before it set its speed
    (else the plan's cruise speed). Any other item beside a survey is refused naming it."""
    speed = default_speed_mps
    for it in before:
        if it.command == DO_CHANGE_SPEED:
            if not _finite(it.param2):
                raise MissionItemError(MISSION, it.seq, f"DO_CHANGE_SPEED: speed {it.param2!r} is not a number")
            if it.param2 > 0:
                speed = float(it.param2)
        elif it.command in _REFUSED:
            raise MissionItemError(MISSION, it.seq, _REFUSED[it.command])
        else:
            raise MissionItemError(MISSION, it.seq, f"{it.name()} beside a survey: lotsen flies a survey as one route "
                                   "from the harbour (put waypoints in a plan of their own)")
    corners = []
    for j, (lat, lon) in enumerate(item.polygon):
        if not (_finite(lat) and _finite(lon)) or not -90 <= lat <= 90 or not -180 <= lon <= 180:
            raise ConfigError(f"survey polygon[{j}]: latitude {lat:g} / longitude {lon:g} is not a position")
        n, e = frame.to_ne(lat, lon)
        corners.append([round(n, 4), round(e, 4)])
    out = {"polygon": corners, "angle_deg": item.angle_deg, "spacing_m": item.spacing_m,
           "turnaround_m": item.turnaround_m, "entry": item.entry, "crosshatch": item.crosshatch,
           "speed_mps": round(speed, 4)}
    out.update(item.extra)
    return out


def _yaw(yaw: float) -> float | None:
    """A waypoint's yaw as a heading (deg), None for "no yaw" (NaN or 0; 360 is north)."""
    return None if not _finite(yaw) or yaw == 0.0 else round(float(yaw) % 360.0, 6)


def _heading_yaw(heading_rad: float) -> float:
    """A heading as a waypoint's yaw: degrees in (0, 360], north written as 360 (0 means no yaw)."""
    yaw = round(math.degrees(heading_rad) % 360.0, 6) % 360.0
    return yaw if yaw else NORTH_YAW_DEG


def _fill_headings(nodes: list[dict], pts: list[tuple[float, float]]) -> None:
    computed = computed_headings(pts)
    for node, h in zip(nodes, computed):
        if node.get("heading_deg") is None:
            node["heading_deg"] = h
        node.pop("_seq", None)


def waypoint_seqs(items: Iterable[MissionItem]) -> list[int]:
    """The mission sequence numbers of the waypoints, in order (route node k is waypoint k)."""
    return [i.seq for i in items if i.command in (NAV_WAYPOINT, NAV_SPLINE_WAYPOINT)]


def _place(area: Any, obstacles: list, poly: list, inclusion: bool) -> Any:
    """One fence polygon in its place: the first inclusion is the area, further inclusions regions
    forbidden outside, exclusions obstacles. Returns the area."""
    if not inclusion:
        obstacles.append(poly)
    elif area is None:
        return poly
    else:
        obstacles.append({"polygon": poly, "forbidden": "outside"})
    return area


def _fence(items: list[MissionItem], frame: LocalFrame) -> dict:
    area = None
    obstacles: list[Any] = []
    i = 0
    while i < len(items):
        it = items[i]
        if it.command in (NAV_FENCE_POLYGON_VERTEX_INCLUSION, NAV_FENCE_POLYGON_VERTEX_EXCLUSION):
            count = int(it.param1) if _finite(it.param1) else 0
            if count < 3:
                raise MissionItemError(FENCE, it.seq, f"{it.name()}: vertex count {it.param1:g} (a polygon needs >= 3)")
            ring = items[i:i + count]
            if len(ring) < count or any(v.command != it.command or not _finite(v.param1) or int(v.param1) != count
                                        for v in ring):
                raise MissionItemError(FENCE, it.seq, f"{it.name()}: the polygon's {count} vertices are not "
                                       "consecutive items of the same kind and count")
            area = _place(area, obstacles, [list(_position(frame, v, FENCE)) for v in ring],
                          it.command == NAV_FENCE_POLYGON_VERTEX_INCLUSION)
            i += count
            continue
        if it.command in (NAV_FENCE_CIRCLE_INCLUSION, NAV_FENCE_CIRCLE_EXCLUSION):
            r = it.param1
            if not _finite(r) or r <= 0:
                raise MissionItemError(FENCE, it.seq, f"{it.name()}: radius {r!r} must be a positive number")
            c = _position(frame, it, FENCE)
            poly = [[round(c[0] + r * math.cos(2 * math.pi * k / CIRCLE_CORNERS), 4),
                     round(c[1] + r * math.sin(2 * math.pi * k / CIRCLE_CORNERS), 4)] for k in range(CIRCLE_CORNERS)]
            area = _place(area, obstacles, poly, it.command == NAV_FENCE_CIRCLE_INCLUSION)
        elif it.command == NAV_FENCE_RETURN_POINT:
            pass  # lotsen holds inside the area on a breach (docs/failsafes.md); the return point is not used
        else:
            raise MissionItemError(FENCE, it.seq, f"{it.name()}: a fence holds polygon or circle items only")
        i += 1
    out: dict[str, Any] = {}
    if area is not None:
        out["area"] = area
    elif obstacles:
        # exclusions without an inclusion fence: the boat's water is unbounded but for them
        pass
    if obstacles:
        out["obstacles"] = obstacles
    return out


# --------------------------------------------------------------------------------------------
# route -> items
# --------------------------------------------------------------------------------------------
def plan_from_route(route: Route, origin: GeoOrigin) -> Plan:
    """The items of `route` in WGS84 (`origin`: the geographic origin of its local frame): home
    (the harbour), waypoints with their headings as yaw and a DO_CHANGE_SPEED whenever the speed
    changes; the area and obstacles as fence polygons; the harbour as the one rally point."""
    frame = LocalFrame(origin.lat_deg, origin.lon_deg, origin.height_m)

    def ll(n: float, e: float) -> tuple[float, float]:
        lat, lon, _ = frame.to_geodetic(n, e)
        return round(lat, 9), round(lon, 9)

    h = route.harbour
    hl = ll(h.north_m, h.east_m)
    home = MissionItem(0, NAV_WAYPOINT, FRAME_GLOBAL, param4=_heading_yaw(h.heading_rad), lat_deg=hl[0], lon_deg=hl[1])
    mission: list[MissionItem] = []
    speed = None
    for node in route.nodes:
        if speed is None or abs(node.speed_mps - speed) > 1e-9:
            speed = node.speed_mps
            mission.append(MissionItem(len(mission) + 1, DO_CHANGE_SPEED, FRAME_MISSION, param1=1.0,
                                       param2=round(speed, 6), param3=-1.0))
        lat, lon = ll(node.north_m, node.east_m)
        mission.append(MissionItem(len(mission) + 1, NAV_WAYPOINT, FRAME_GLOBAL_RELATIVE_ALT,
                                   param4=_heading_yaw(node.heading_rad), lat_deg=lat, lon_deg=lon))
    fence: list[MissionItem] = []

    def polygon(ring: Any, command: int) -> None:
        for p in ring:
            lat, lon = ll(p[0], p[1])
            fence.append(MissionItem(len(fence), command, FRAME_GLOBAL, param1=float(len(ring)), lat_deg=lat,
                                     lon_deg=lon))

    if route.area is not None:
        polygon(route.area, NAV_FENCE_POLYGON_VERTEX_INCLUSION)
    for r in route.obstacles:
        polygon(r.polygon, NAV_FENCE_POLYGON_VERTEX_EXCLUSION if r.forbidden == "inside"
                else NAV_FENCE_POLYGON_VERTEX_INCLUSION)
    if route.area is None and any(r.forbidden == "outside" for r in route.obstacles):
        raise ConfigError("route: a region forbidden outside without a navigable area cannot be written as a fence "
                          "(the first inclusion polygon is the area); add an area")
    rally = [MissionItem(0, NAV_RALLY_POINT, FRAME_GLOBAL_RELATIVE_ALT, param4=_heading_yaw(h.heading_rad),
                         lat_deg=hl[0], lon_deg=hl[1])]
    speeds = [n.speed_mps for n in route.nodes]
    return Plan(home=home, mission=mission, fence=fence, rally=rally,
                cruise_speed_mps=max(set(speeds), key=speeds.count) if speeds else None,
                survey=_survey_item(route, ll))


def _survey_item(route: Route, ll: Any) -> SurveyItem | None:
    """The survey item of a survey route whose lines cover a polygon (explicit lines, a re-run,
    have no Survey item: they are written as their waypoints)."""
    p = route.survey
    if p is None or p.lines is not None:
        return None
    from lotsen.planning.survey import survey_polygon

    ring = p.polygon or tuple(tuple(c) for c in survey_polygon(p, route.free_region()).exterior.coords[:-1])
    extra: dict[str, Any] = {"margin_m": p.margin_m}
    if p.entry is None:
        extra["entry"] = None   # the corner nearest the harbour (QGroundControl's entryLocation says 0)
    if p.turn_radius_m is not None:
        extra["turn_radius_m"] = p.turn_radius_m
    if p.side != "both":
        extra["side"] = p.side
    return SurveyItem(tuple(ll(c[0], c[1]) for c in ring), p.angle_deg, p.spacing_m, p.turnaround_m,
                      p.entry if p.entry is not None else 0, p.crosshatch, extra)


def fence_parts(items: list[MissionItem], origin: GeoOrigin) -> dict:
    """The `area` / `obstacles` of a route dict from fence items alone (a fence uploaded before
    any mission), in the local frame of `origin`."""
    return _fence(items, LocalFrame(origin.lat_deg, origin.lon_deg, origin.height_m))


def local_frame(origin: GeoOrigin) -> LocalFrame:
    """The local frame of a route's geographic origin (WGS84 <-> north/east metres)."""
    return LocalFrame(origin.lat_deg, origin.lon_deg, origin.height_m)
