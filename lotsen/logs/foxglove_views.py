"""Foxglove well-known views of lotsen messages, so a log or a live stream opened in Foxglove shows
the boat on a map and in 3D without set-up.

The well-known types come from foxglove-sdk (`foxglove.messages`, protobuf-encoded, with the
schema that Foxglove publishes), so they are exactly Foxglove's definitions. Frames: the world
frame "map" is ENU (x east, y north, z up), as Foxglove's 3D panel expects; the boat frames
"boat" (estimate) and "boat_truth" (simulation) are FLU. lotsen's NED heading psi (clockwise from
north) becomes the ENU yaw pi/2 - psi.

Views (channel topic -> schema, from which lotsen topic):

| channel | schema | source |
|---|---|---|
| foxglove/gnss | foxglove.LocationFix | gps_chatter |
| foxglove/gnss_rtk | lotsen.RtkStatus (JSON) | gps_chatter (field note 11: LocationFix has no fix quality) |
| foxglove/estimate_fix | foxglove.LocationFix | state/estimate (needs the geodetic origin) |
| foxglove/tf | foxglove.FrameTransform | state/estimate (map->boat), sim/truth (map->boat_truth) |
| foxglove/pose/estimate, foxglove/pose/truth | foxglove.PoseInFrame | state/estimate, sim/truth |
| foxglove/scene | foxglove.SceneUpdate | planning/path (path), control/status (predicted path), boat hull |
| foxglove/log | foxglove.Log | log |
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable

from lotsen.messages import GnssFixType, Topic
from lotsen.model.geodetic import LocalFrame

try:  # foxglove-sdk is a declared dependency; without it the views are simply absent
    import foxglove.messages as fm
except ImportError:  # pragma: no cover
    fm = None

JSON_VIEWS = {"lotsen.RtkStatus"}

RTK_STATUS_SCHEMA = {
    "title": "lotsen.RtkStatus", "type": "object",
    "description": "GNSS fix quality (Foxglove's LocationFix has no fix-quality field)",
    "properties": {
        "timestamp": {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
        "fix_type": {"type": "integer", "description": "0=NO_FIX 1=DEAD_RECKONING 2=FIX_2D 3=FIX_3D 4=RTK_FLOAT 5=RTK_FIXED"},
        "fix_name": {"type": "string"}, "rtk": {"type": "string", "enum": ["none", "float", "fixed"]},
        "h_acc_m": {"type": ["number", "null"]}, "num_sv": {"type": "integer"},
        "correction_age_s": {"type": ["number", "null"]},
    },
}


@dataclass(frozen=True)
class View:
    topic: str
    schema_name: str
    encoding: str  # "protobuf" or "json"
    data: bytes  # encoded message


def available() -> bool:
    return fm is not None


def schema_of(schema_name: str) -> tuple[str, bytes]:
    """(schema encoding, schema data) for a view schema name."""
    if schema_name == "lotsen.RtkStatus":
        return "jsonschema", json.dumps(RTK_STATUS_SCHEMA).encode()
    cls = getattr(fm, schema_name.split(".", 1)[1])
    s = cls.get_schema()
    return s.encoding, bytes(s.data)


def _ts(t_ns: int) -> Any:
    return fm.Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)


def _quat_yaw(yaw: float) -> Any:
    return fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _fin(x: float) -> float | None:
    return x if math.isfinite(x) else None


class ViewMaker:
    """Turns (topic, message, time) into Foxglove views. Holds a little state (the boat hull is sent
    once per second; the last path is kept to redraw with the predicted path)."""

    def __init__(self, geo_origin: tuple[float, float, float] | None = None) -> None:
        self.geo_origin = geo_origin
        self._frame = LocalFrame(*geo_origin) if geo_origin is not None else None
        self._last_hull_ns = -10**18
        self._handlers: dict[str, Callable[[Any, int], list[View]]] = {
            Topic.GNSS: self._gnss, Topic.STATE: self._state, Topic.TRUTH: self._truth,
            Topic.PATH: self._path, Topic.CONTROL_STATUS: self._control, Topic.LOG: self._log,
        }

    def handles(self, topic: str) -> bool:
        """Whether `topic` has views (the others' messages need not be decoded for them)."""
        return fm is not None and topic in self._handlers

    def views(self, topic: str, msg: Any, t_ns: int) -> list[View]:
        if fm is None:
            return []
        h = self._handlers.get(topic)
        if h is None:
            return []
        try:
            return h(msg, t_ns)
        except (AttributeError, TypeError, ValueError):
            return []  # a message of an unexpected shape gets no view; the raw channel still has it

    # -- GNSS
    def _gnss(self, msg: Any, t_ns: int) -> list[View]:
        ft = GnssFixType(msg.fix_type)
        h = msg.h_acc_m if math.isfinite(msg.h_acc_m) else 0.0
        v = msg.v_acc_m if math.isfinite(msg.v_acc_m) else h
        known = math.isfinite(msg.h_acc_m)
        vel = None
        if math.isfinite(msg.vel_n_mps) and math.isfinite(msg.vel_e_mps):
            vel = fm.Vector3(x=msg.vel_e_mps, y=msg.vel_n_mps, z=0.0)
        fix = fm.LocationFix(
            timestamp=_ts(t_ns), frame_id="gnss", latitude=msg.lat_deg, longitude=msg.lon_deg,
            altitude=msg.height_m if math.isfinite(msg.height_m) else 0.0,
            position_covariance=[h * h, 0, 0, 0, h * h, 0, 0, 0, v * v],
            position_covariance_type=(fm.LocationFixPositionCovarianceType.DiagonalKnown if known
                                      else fm.LocationFixPositionCovarianceType.Unknown),
            velocity=vel)
        rtk = "fixed" if ft == GnssFixType.RTK_FIXED else "float" if ft == GnssFixType.RTK_FLOAT else "none"
        status = {"timestamp": {"sec": t_ns // 10**9, "nsec": t_ns % 10**9}, "fix_type": int(ft),
                  "fix_name": ft.name, "rtk": rtk, "h_acc_m": _fin(msg.h_acc_m), "num_sv": int(msg.num_sv),
                  "correction_age_s": _fin(msg.correction_age_s)}
        return [View("foxglove/gnss", "foxglove.LocationFix", "protobuf", fix.encode()),
                View("foxglove/gnss_rtk", "lotsen.RtkStatus", "json", json.dumps(status).encode())]

    # -- poses
    def _pose_views(self, msg: Any, t_ns: int, child: str, pose_topic: str) -> list[View]:
        yaw = math.pi / 2 - msg.heading_rad
        ts = _ts(t_ns)
        tf = fm.FrameTransform(timestamp=ts, parent_frame_id="map", child_frame_id=child,
                               translation=fm.Vector3(x=msg.east_m, y=msg.north_m, z=0.0), rotation=_quat_yaw(yaw))
        pose = fm.PoseInFrame(timestamp=ts, frame_id="map", pose=fm.Pose(
            position=fm.Vector3(x=msg.east_m, y=msg.north_m, z=0.0), orientation=_quat_yaw(yaw)))
        out = [View("foxglove/tf", "foxglove.FrameTransform", "protobuf", tf.encode()),
               View(pose_topic, "foxglove.PoseInFrame", "protobuf", pose.encode())]
        return out

    def _hull(self, t_ns: int, frame: str, color: tuple[float, float, float, float], ident: str) -> View:
        # a 1 m x 0.25 m box standing for the hull, locked to the boat frame
        cube = fm.CubePrimitive(pose=fm.Pose(position=fm.Vector3(x=0.0, y=0.0, z=0.05), orientation=_quat_yaw(0.0)),
                                size=fm.Vector3(x=1.0, y=0.25, z=0.1), color=fm.Color(r=color[0], g=color[1], b=color[2], a=color[3]))
        arrow = fm.ArrowPrimitive(pose=fm.Pose(position=fm.Vector3(x=0.5, y=0.0, z=0.1), orientation=_quat_yaw(0.0)),
                                  shaft_length=0.3, shaft_diameter=0.04, head_length=0.1, head_diameter=0.1,
                                  color=fm.Color(r=1.0, g=1.0, b=1.0, a=1.0))
        ent = fm.SceneEntity(timestamp=_ts(t_ns), frame_id=frame, id=ident, frame_locked=True, cubes=[cube], arrows=[arrow])
        return View("foxglove/scene", "foxglove.SceneUpdate", "protobuf", fm.SceneUpdate(entities=[ent]).encode())

    def _state(self, msg: Any, t_ns: int) -> list[View]:
        out = self._pose_views(msg, t_ns, "boat", "foxglove/pose/estimate")
        if t_ns - self._last_hull_ns >= 1_000_000_000:
            self._last_hull_ns = t_ns
            out.append(self._hull(t_ns, "boat", (0.1, 0.4, 0.9, 0.9), "boat"))
        if self.geo_origin is not None:
            out.append(self._estimate_fix(msg, t_ns))
        return out

    def _truth(self, msg: Any, t_ns: int) -> list[View]:
        out = self._pose_views(msg, t_ns, "boat_truth", "foxglove/pose/truth")
        if t_ns - getattr(self, "_last_truth_hull_ns", -10**18) >= 1_000_000_000:
            self._last_truth_hull_ns = t_ns
            out.append(self._hull(t_ns, "boat_truth", (0.2, 0.8, 0.2, 0.4), "boat_truth"))
        return out

    def _estimate_fix(self, msg: Any, t_ns: int) -> View:
        lat, lon, h = self._frame.to_geodetic(msg.north_m, msg.east_m)  # type: ignore[union-attr]
        fix = fm.LocationFix(timestamp=_ts(t_ns), frame_id="boat", latitude=float(lat), longitude=float(lon),
                             altitude=float(h), heading=msg.heading_rad % (2 * math.pi),
                             color=fm.Color(r=0.1, g=0.4, b=0.9, a=1.0))
        return View("foxglove/estimate_fix", "foxglove.LocationFix", "protobuf", fix.encode())

    # -- paths
    @staticmethod
    def _line(t_ns: int, ident: str, north: Any, east: Any, color: tuple[float, float, float, float],
              thickness: float) -> Any:
        pts = [fm.Point3(x=float(e), y=float(n), z=0.0) for n, e in zip(north, east)]
        line = fm.LinePrimitive(type=fm.LinePrimitiveLineType.LineStrip, thickness=thickness, scale_invariant=False,
                                points=pts, color=fm.Color(r=color[0], g=color[1], b=color[2], a=color[3]))
        return fm.SceneEntity(timestamp=_ts(t_ns), frame_id="map", id=ident, lines=[line])

    def _path(self, msg: Any, t_ns: int) -> list[View]:
        ent = self._line(t_ns, "path", msg.north_m, msg.east_m, (1.0, 0.6, 0.0, 1.0), 0.05)
        return [View("foxglove/scene", "foxglove.SceneUpdate", "protobuf", fm.SceneUpdate(entities=[ent]).encode())]

    def _control(self, msg: Any, t_ns: int) -> list[View]:
        if not msg.predicted_north_m:
            return []
        ent = self._line(t_ns, "predicted_path", msg.predicted_north_m, msg.predicted_east_m, (0.9, 0.1, 0.9, 1.0), 0.03)
        return [View("foxglove/scene", "foxglove.SceneUpdate", "protobuf", fm.SceneUpdate(entities=[ent]).encode())]

    # -- log
    def _log(self, msg: Any, t_ns: int) -> list[View]:
        level = {"debug": fm.LogLevel.Debug, "info": fm.LogLevel.Info, "warning": fm.LogLevel.Warning,
                 "error": fm.LogLevel.Error, "fatal": fm.LogLevel.Fatal}.get(str(msg.level).lower(), fm.LogLevel.Info)
        text = msg.text + (f" {json.dumps(msg.data, default=str)}" if msg.data else "")
        log = fm.Log(timestamp=_ts(t_ns), level=level, message=text, name=msg.source)
        return [View("foxglove/log", "foxglove.Log", "protobuf", log.encode())]
