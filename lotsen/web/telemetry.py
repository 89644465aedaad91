"""Bus messages -> JSON for the browser. `TelemetryState` keeps the latest value per topic
(updated by the hub's reader thread) and builds one compact frame per telemetry period;
paths, routes and log events go out as separate messages when they arrive."""

from __future__ import annotations

import math
from typing import Any

from lotsen.messages import (
    ActuatorState, BatteryStatus, ControllerStatus, GnssFix, GnssFixType, LogEvent, MagCalibrationResult,
    PathMessage,
    RcOverride, RouteMessage, SupervisorStatus, ThrustCommand, Topic, VesselState,
)

TOPICS = (Topic.STATE, Topic.TRUTH, Topic.CONTROL_STATUS, Topic.SUPERVISOR, Topic.GNSS, Topic.BATTERY,
          Topic.SHIP_COMMAND, Topic.ACTUATORS, Topic.PATH, Topic.ROUTE, Topic.LOG, Topic.RC,
          Topic.MAG_CALIBRATION)

#: the estimate is shown when it is this fresh; otherwise the simulator's truth (simulation only)
STATE_FRESH_S = 1.0
MAX_LOG_TEXT = 500


def num(x: Any, digits: int = 4) -> float | None:
    """JSON has no NaN: non-finite -> null."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return round(v, digits) if math.isfinite(v) else None


def plain(value: Any, depth: int = 0) -> Any:
    """LogEvent.data made JSON-safe (numbers, strings, lists, dicts; anything else as text)."""
    if depth > 4:
        return str(value)[:100]
    if value is None or isinstance(value, (bool, str)):
        return value if not isinstance(value, str) else value[:MAX_LOG_TEXT]
    if isinstance(value, (int, float)):
        return num(value, 6)
    if isinstance(value, dict):
        return {str(k)[:60]: plain(v, depth + 1) for k, v in list(value.items())[:50]}
    if isinstance(value, (list, tuple)):
        return [plain(v, depth + 1) for v in list(value)[:200]]
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return plain(value.tolist(), depth + 1)
    return str(value)[:MAX_LOG_TEXT]


def pose_json(s: VesselState) -> dict:
    return {"t": num(s.stamp_s), "n": num(s.north_m), "e": num(s.east_m), "psi": num(s.heading_rad),
            "u": num(s.u_mps), "v": num(s.v_mps), "r": num(s.r_radps), "src": s.source}


def path_json(p: PathMessage) -> dict:
    return {"type": "path", "t": num(p.stamp_s), "n": [num(v, 3) for v in p.north_m],
            "e": [num(v, 3) for v in p.east_m], "v": [num(v, 3) for v in p.speed_mps]}


def log_json(e: LogEvent) -> dict:
    return {"type": "log", "t": num(e.stamp_s), "level": str(e.level)[:20], "source": str(e.source)[:60],
            "text": str(e.text)[:MAX_LOG_TEXT], "data": plain(e.data)}


def route_json(r: RouteMessage) -> dict:
    return {"type": "active_route", "t": num(r.stamp_s), "route": plain(r.route), "source": r.source}


def magcal_json(m: MagCalibrationResult) -> dict:
    return {"type": "magcal", "t": num(m.stamp_s), "ok": bool(m.ok), "center": plain(m.center),
            "matrix": plain(m.matrix), "residual": num(m.residual, 5), "coverage_deg": num(m.coverage_deg, 1),
            "text": str(m.text)[:MAX_LOG_TEXT]}


class TelemetryState:
    def __init__(self) -> None:
        self.latest: dict[str, Any] = {}
        self.events: list[dict] = []  # path / route / log messages to send as they come
        self.pose_updated = False

    def update(self, topic: str, msg: Any) -> None:
        if topic == Topic.PATH and isinstance(msg, PathMessage):
            self.events.append(path_json(msg))
        elif topic == Topic.ROUTE and isinstance(msg, RouteMessage):
            self.events.append(route_json(msg))
        elif topic == Topic.MAG_CALIBRATION and isinstance(msg, MagCalibrationResult):
            self.events.append(magcal_json(msg))
        elif topic == Topic.LOG and isinstance(msg, LogEvent):
            if len(self.events) < 50:  # a storm of log events must not flood the browsers
                self.events.append(log_json(msg))
        else:
            self.latest[topic] = msg
            # a frame goes out when the pose it shows is new: the estimate, or the truth when
            # no estimate flows (triggering on both would send the estimate up to a period late)
            if topic == Topic.STATE:
                self.pose_updated = True
            elif topic == Topic.TRUTH and isinstance(msg, VesselState):
                est = self.latest.get(Topic.STATE)
                if not isinstance(est, VesselState) or msg.stamp_s - est.stamp_s >= STATE_FRESH_S:
                    self.pose_updated = True

    def take_events(self) -> list[dict]:
        ev, self.events = self.events, []
        return ev

    def frame(self, now_s: float, link: dict) -> dict:
        """One telemetry frame: the latest of everything, as compact JSON-ready dicts."""
        self.pose_updated = False
        L = self.latest
        est, truth = L.get(Topic.STATE), L.get(Topic.TRUTH)
        use_est = isinstance(est, VesselState) and now_s - est.stamp_s < STATE_FRESH_S
        pose = est if use_est else truth if isinstance(truth, VesselState) else None
        out: dict[str, Any] = {"type": "telemetry", "t": num(now_s), "link": link,
                               "pose": pose_json(pose) if pose is not None else None,
                               "truth": pose_json(truth) if use_est and isinstance(truth, VesselState) else None}
        c = L.get(Topic.CONTROL_STATUS)
        if isinstance(c, ControllerStatus):
            out["ctrl"] = {"t": num(c.stamp_s), "controller": c.controller, "xte": num(c.cross_track_error_m),
                           "hdg_err": num(c.heading_error_rad), "speed": num(c.speed_mps),
                           "speed_ref": num(c.speed_ref_mps), "progress": num(c.progress_m, 2),
                           "solve_ms": num(c.solve_time_ms, 2), "status": c.status, "failures": c.failures,
                           "pred_n": [num(v, 2) for v in c.predicted_north_m[:200]],
                           "pred_e": [num(v, 2) for v in c.predicted_east_m[:200]]}
        s = L.get(Topic.SUPERVISOR)
        if isinstance(s, SupervisorStatus):
            out["sup"] = {"t": num(s.stamp_s), "mode": s.mode, "reason": s.reason, "armed": s.armed,
                          "warnings": list(s.warnings)[:20], "failsafes": list(s.active_failsafes)[:20]}
        g = L.get(Topic.GNSS)
        if isinstance(g, GnssFix):
            try:
                fix = GnssFixType(g.fix_type).name
            except ValueError:
                fix = str(g.fix_type)
            out["gnss"] = {"t": num(g.stamp_s), "fix": fix, "h_acc": num(g.h_acc_m, 3), "sv": g.num_sv,
                           "corr_age": num(g.correction_age_s, 1)}
        b = L.get(Topic.BATTERY)
        if isinstance(b, BatteryStatus):
            out["bat"] = {"t": num(b.stamp_s), "v": num(b.voltage_v, 2), "a": num(b.current_a, 2),
                          "frac": num(b.remaining_frac, 3)}
        for topic, key in ((Topic.SHIP_COMMAND, "cmd"), (Topic.ACTUATORS, "act")):
            m = L.get(topic)
            if isinstance(m, (ThrustCommand, ActuatorState)):
                out[key] = {"t": num(m.stamp_s), "a1": num(m.alpha1_rad), "a2": num(m.alpha2_rad),
                            "n1": num(m.n1_rps, 2), "n2": num(m.n2_rps, 2), "nt": num(m.nt_rps, 2)}
        rc = L.get(Topic.RC)
        if isinstance(rc, RcOverride):
            out["rc"] = {"t": num(rc.stamp_s), "active": rc.active}
        return out
