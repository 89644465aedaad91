"""Bus messages -> JSON for the browser. `TelemetryState` keeps the latest value per topic
(updated by the hub's reader thread) and builds one compact frame per telemetry period;
paths, routes and log events go out as separate messages when they arrive."""

from __future__ import annotations

import math
import threading
from collections import deque
from typing import Any

from lotsen.messages import (
    ActuatorState, Alert, BatteryStatus, CommandAck, ControllerStatus, GnssFix, GnssFixType, LogEvent, MagCalibrationResult,
    MissionProgress, ModelInfo, PathMessage, PlannedRoute, RcOverride, RecorderStatus, RouteMessage, SeaState,
    Sounding, SupervisorStatus, ThrustCommand, Topic, VesselState,
)
from lotsen.web.coverage import CoverageLayer

TOPICS = (Topic.STATE, Topic.TRUTH, Topic.CONTROL_STATUS, Topic.SUPERVISOR, Topic.GNSS, Topic.BATTERY,
          Topic.SHIP_COMMAND, Topic.ACTUATORS, Topic.PATH, Topic.ROUTE, Topic.ACTIVE_ROUTE, Topic.LOG, Topic.RC,
          Topic.MAG_CALIBRATION, Topic.ALERT, Topic.PROGRESS, Topic.MODEL, Topic.OPERATOR_ACK, Topic.RECORDER,
          Topic.SEA_STATE, Topic.SOUNDING)

#: the page's live view: of these only the newest value counts (TelemetryState.latest, the next
#: frame), and only a connected page reads them; the web process decodes them only while a page
#: is connected (ZenohBridge.hold_latest). The rest (routes, paths, logs, alerts, the battery's
#: history, soundings) is taken in always
LIVE_ONLY = (Topic.STATE, Topic.TRUTH, Topic.CONTROL_STATUS, Topic.SUPERVISOR, Topic.GNSS, Topic.SHIP_COMMAND,
             Topic.ACTUATORS)
#: the estimate is shown when it is this fresh; otherwise the simulator's truth (simulation only)
STATE_FRESH_S = 1.0
MAX_LOG_TEXT = 500
#: alerts replayed to a page that connects: the active ones and those of the last minute
ALERT_REPLAY_S = 60.0
SEVERITIES = ("info", "warning", "error", "critical")
#: modes in which the path controller drives (its status line is shown only then)
CONTROLLED_MODES = ("AUTO", "RETURN", "HOLD")


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
    out = {"t": num(s.stamp_s), "n": num(s.north_m), "e": num(s.east_m), "psi": num(s.heading_rad),
           "u": num(s.u_mps), "v": num(s.v_mps), "r": num(s.r_radps), "src": s.source}
    cur = getattr(s, "current_ne_mps", (0.0, 0.0))
    if cur and any(num(c) for c in cur):  # the estimator's water current, when it has one
        out["cur"] = [num(cur[0], 3), num(cur[1], 3)]
    return out


def path_json(p: PathMessage) -> dict:
    return {"type": "path", "t": num(p.stamp_s), "n": [num(v, 3) for v in p.north_m],
            "e": [num(v, 3) for v in p.east_m], "v": [num(v, 3) for v in p.speed_mps]}


def log_json(e: LogEvent) -> dict:
    return {"type": "log", "t": num(e.stamp_s), "level": str(e.level)[:20], "source": str(e.source)[:60],
            "text": str(e.text)[:MAX_LOG_TEXT], "data": plain(e.data)}


def route_json(r: RouteMessage) -> dict:
    """The boat's read-back of the route it holds (planning/active_route)."""
    return {"type": "active_route", "t": num(r.stamp_s), "route": plain(r.route), "source": r.source,
            "route_id": str(r.route_id)[:64]}


def uploaded_json(r: PlannedRoute) -> dict:
    """A route was uploaded (planning/route): its id, so every page knows what to expect back."""
    return {"type": "uploaded", "t": num(r.stamp_s), "route_id": str(r.route_id)[:64], "source": str(r.source)[:40],
            "length_m": num(r.s_m[-1] if r.s_m else 0.0, 2)}


def alert_json(a: Alert) -> dict:
    sev = a.severity if a.severity in SEVERITIES else "warning"
    return {"type": "alert", "t": num(a.stamp_s), "severity": sev, "code": str(a.code)[:80],
            "text": str(a.text)[:MAX_LOG_TEXT], "source": str(a.source)[:40], "active": bool(a.active)}


def progress_json(p: MissionProgress) -> dict:
    return {"t": num(p.stamp_s), "mode": str(p.mode)[:20], "length": num(p.path_length_m, 2),
            "done": num(p.progress_m, 2), "left": num(p.remaining_m, 2), "eta": num(p.eta_s, 1),
            "next": p.next_node, "to_next": num(p.distance_to_next_node_m, 2), "route_id": str(p.route_id)[:64]}


def _blocked(items: tuple[str, ...]) -> dict[str, str]:
    """("auto: no route", ...) -> {"auto": "no route"} (a pre-arm refusal lists every failing check: long)."""
    out = {}
    for item in list(items)[:40]:
        action, _, why = str(item).partition(":")
        out[action.strip()[:30]] = why.strip()[:MAX_LOG_TEXT] or "not possible now"
    return out


class BatteryEstimator:
    """Time left on the battery: remaining fraction x capacity / current when the capacity is
    configured; else the capacity is estimated from the charge drawn while the fraction fell
    (sum I dt / -d frac over the last `window_s`), needing a drop of at least `min_drop`."""

    def __init__(self, capacity_ah: float | None = None, window_s: float = 300.0, min_drop: float = 0.002) -> None:
        self.capacity_ah = capacity_ah
        self.window_s = window_s
        self.min_drop = min_drop
        self.samples: deque[tuple[float, float, float]] = deque()  # (t, frac, current)
        self.current_avg_a = float("nan")

    def update(self, b: BatteryStatus) -> None:
        t, frac, cur = float(b.stamp_s), float(b.remaining_frac), float(b.current_a)
        if not (math.isfinite(t) and math.isfinite(cur)):
            return
        if self.samples and t < self.samples[-1][0]:
            self.samples.clear()  # clock restarted
        self.samples.append((t, frac, cur))
        while self.samples and t - self.samples[0][0] > self.window_s:
            self.samples.popleft()
        recent = [c for (ts, _, c) in self.samples if t - ts <= 10.0]
        self.current_avg_a = sum(recent) / len(recent)

    def capacity(self) -> tuple[float, str] | None:
        if self.capacity_ah is not None:
            return self.capacity_ah, "capacity"
        pts = [(t, f, c) for (t, f, c) in self.samples if math.isfinite(f)]
        if len(pts) < 3:
            return None
        drop = pts[0][1] - pts[-1][1]
        if drop < self.min_drop:
            return None
        charge_ah = sum(0.5 * (c0 + c1) * (t1 - t0) for (t0, _, c0), (t1, _, c1) in zip(pts, pts[1:])) / 3600.0
        return charge_ah / drop, "discharge"

    def time_left_s(self, frac: float) -> tuple[float | None, str]:
        cap = self.capacity()
        if cap is None or not math.isfinite(frac) or not math.isfinite(self.current_avg_a) or self.current_avg_a <= 0.01:
            return None, ""
        return frac * cap[0] * 3600.0 / self.current_avg_a, cap[1]


def magcal_json(m: MagCalibrationResult) -> dict:
    return {"type": "magcal", "t": num(m.stamp_s), "ok": bool(m.ok), "center": plain(m.center),
            "matrix": plain(m.matrix), "residual": num(m.residual, 5), "coverage_deg": num(m.coverage_deg, 1),
            "text": str(m.text)[:MAX_LOG_TEXT], "samples": plain(getattr(m, "samples", ()))[:400],
            "decision": str(getattr(m, "decision", ""))[:20]}


def model_json(m: ModelInfo) -> dict:
    """The model in use and where it came from (model/in_use, latched)."""
    return {"type": "model", "t": num(m.stamp_s), "source": str(m.source)[:300],
            "file_modified_utc": str(m.file_modified_utc)[:40], "parameters": plain(m.parameters),
            "std": plain(m.std), "verdict": str(m.verdict)[:MAX_LOG_TEXT], "boat": str(m.boat)[:MAX_LOG_TEXT]}


class TelemetryState:
    def __init__(self, battery_capacity_ah: float | None = None) -> None:
        self.latest: dict[str, Any] = {}
        self.events: list[dict] = []  # path / route / log messages to send as they come
        self.pose_updated = False
        self.battery = BatteryEstimator(battery_capacity_ah)
        self._lock = threading.Lock()  # the replay state below is read from the event loop
        self.alerts: dict[str, dict] = {}  # code -> latest alert (active or recently cleared)
        self.replay: dict[str, dict] = {}  # "active_route" / "path" / "uploaded" / "magcal" -> latest event
        self.coverage = CoverageLayer()  # soundings gridded for the page (lotsen.web.coverage)

    def update(self, topic: str, msg: Any) -> None:
        event = None
        if topic == Topic.SOUNDING and isinstance(msg, Sounding):
            self.coverage.add(msg)
            return
        if topic == Topic.ACTIVE_ROUTE and isinstance(msg, RouteMessage):
            self.coverage.set_route(msg.route)
        if topic == Topic.PATH and isinstance(msg, PathMessage):
            event = path_json(msg)
        elif topic == Topic.ACTIVE_ROUTE and isinstance(msg, RouteMessage):
            event = route_json(msg)
        elif topic == Topic.ROUTE and isinstance(msg, PlannedRoute):
            event = uploaded_json(msg)
        elif topic == Topic.ROUTE and isinstance(msg, RouteMessage):  # an older core: the upload as is
            event = {"type": "uploaded", "t": num(msg.stamp_s), "route_id": msg.route_id, "source": msg.source}
        elif topic == Topic.MAG_CALIBRATION and isinstance(msg, MagCalibrationResult):
            event = magcal_json(msg)
        elif topic == Topic.MODEL and isinstance(msg, ModelInfo):
            event = model_json(msg)
        elif topic == Topic.ALERT and isinstance(msg, Alert):
            a = alert_json(msg)
            with self._lock:
                self.alerts[a["code"]] = a
                if len(self.alerts) > 200:  # forget the oldest cleared ones
                    for code in [c for c, v in self.alerts.items() if not v["active"]][:50]:
                        del self.alerts[code]
            if len(self.events) < 100:
                self.events.append(a)
            return
        elif topic == Topic.OPERATOR_ACK and isinstance(msg, CommandAck):
            # the boat's answer to a request (every page: each matches its own request ids)
            self.events.append({"type": "confirmed", "t": num(msg.stamp_s), "request": str(msg.request_id)[:40],
                                "action": str(msg.action)[:30], "accepted": bool(msg.accepted),
                                "reason": str(msg.reason)[:MAX_LOG_TEXT], "mode": str(msg.mode)[:20],
                                "armed": bool(msg.armed)})
            return
        elif topic == Topic.LOG and isinstance(msg, LogEvent):
            if len(self.events) < 50:  # a storm of log events must not flood the browsers
                self.events.append(log_json(msg))
            return
        if event is not None:
            with self._lock:
                self.replay[event["type"]] = event
            self.events.append(event)
        else:
            self.latest[topic] = msg
            if topic == Topic.BATTERY and isinstance(msg, BatteryStatus):
                self.battery.update(msg)
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

    def coverage_event(self) -> dict | None:
        return self.coverage.take_update()

    def replay_events(self, now_s: float) -> list[dict]:
        """What a page that connects now needs at once: the boat's route and path, the last upload,
        the magnetometer fit, the active alerts and those of the last minute (most severe first)."""
        with self._lock:
            out = [self.replay[k] for k in ("model", "uploaded", "active_route", "path", "magcal") if k in self.replay]
            alerts = [a for a in self.alerts.values()
                      if a["active"] or (a["t"] is not None and now_s - a["t"] < ALERT_REPLAY_S)]
        cov = self.coverage.replay()
        if cov is not None:
            out.append(cov)
        alerts.sort(key=lambda a: (-SEVERITIES.index(a["severity"]), -(a["t"] or 0.0)))
        return out + alerts

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
        s = L.get(Topic.SUPERVISOR)
        mode = s.mode if isinstance(s, SupervisorStatus) else None
        c = L.get(Topic.CONTROL_STATUS)
        # the path controller's status only while it drives (in MANUAL "mpc ok, xte 0" would be stale)
        if isinstance(c, ControllerStatus) and (mode is None or mode in CONTROLLED_MODES):
            out["ctrl"] = {"t": num(c.stamp_s), "controller": c.controller, "xte": num(c.cross_track_error_m),
                           "hdg_err": num(c.heading_error_rad), "speed": num(c.speed_mps),
                           "speed_ref": num(c.speed_ref_mps), "progress": num(c.progress_m, 2),
                           "solve_ms": num(c.solve_time_ms, 2), "status": c.status, "failures": c.failures,
                           "pred_n": [num(v, 2) for v in c.predicted_north_m[:200]],
                           "pred_e": [num(v, 2) for v in c.predicted_east_m[:200]]}
        if isinstance(s, SupervisorStatus):
            out["sup"] = {"t": num(s.stamp_s), "mode": s.mode, "reason": s.reason, "armed": bool(s.armed),
                          "escs_armed": bool(s.escs_armed), "warnings": list(s.warnings)[:20],
                          "failsafes": list(s.active_failsafes)[:20],
                          "available": [str(a)[:30] for a in list(s.available_actions)[:40]],
                          "blocked": _blocked(s.blocked_actions), "route_id": str(s.route_id)[:64]}
        p = L.get(Topic.PROGRESS)
        if isinstance(p, MissionProgress):
            out["prog"] = progress_json(p)
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
            left, basis = self.battery.time_left_s(b.remaining_frac)
            out["bat"] = {"t": num(b.stamp_s), "v": num(b.voltage_v, 2), "a": num(b.current_a, 2),
                          "a_avg": num(self.battery.current_avg_a, 2), "frac": num(b.remaining_frac, 3),
                          "left_s": num(left, 0), "left_basis": basis}
        for topic, key in ((Topic.SHIP_COMMAND, "cmd"), (Topic.ACTUATORS, "act")):
            m = L.get(topic)
            if isinstance(m, (ThrustCommand, ActuatorState)):
                out[key] = {"t": num(m.stamp_s), "a1": num(m.alpha1_rad), "a2": num(m.alpha2_rad),
                            "n1": num(m.n1_rps, 2), "n2": num(m.n2_rps, 2), "nt": num(m.nt_rps, 2)}
        r = L.get(Topic.RECORDER)
        if isinstance(r, RecorderStatus):
            out["rec"] = {"t": num(r.stamp_s), "recording": bool(r.recording), "file": str(r.file)[:200],
                          "free": int(r.free_bytes), "written": int(r.written_bytes), "error": str(r.error)[:300],
                          "kept": str(r.kept)[:300], "dir": str(r.directory)[:200]}
        sea = L.get(Topic.SEA_STATE)
        if isinstance(sea, SeaState) and sea.valid:
            out["sea"] = {"t": num(sea.stamp_s), "hs": num(sea.hs_m, 3), "tp": num(sea.tp_s, 2),
                          "tp_enc": num(sea.tp_encounter_s, 2), "from": num(sea.from_deg, 0),
                          "roll": num(sea.roll_std_deg, 1), "pitch": num(sea.pitch_std_deg, 1)}
        rc = L.get(Topic.RC)
        if isinstance(rc, RcOverride):
            out["rc"] = {"t": num(rc.stamp_s), "active": rc.active, "estop": rc.estop, "link": rc.link}
        return out
