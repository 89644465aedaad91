"""The live stack the way an operator meets it: `lotsen run` at wall-clock pace.

`run_live` starts `python -m lotsen run CONFIG` as a separate program from another working
directory, lets it idle, then does what the operator does through the WebSocket: authenticate as
pilot, upload a route (or use the config's), arm, AUTO, wait for the route's end, RETURN, disarm,
Ctrl-C. Optionally strangers flood the server with `plan` requests, or the web process is killed
mid-route. Afterwards the run's own MCAP log is the evidence: failsafes, estimator sample use,
estimate-versus-truth error against the reported standard deviations, the command rate and its gaps.

Nothing here runs on simulated time: the figures are those of the real processes on this machine
(and under whatever else loads its CPU), which is the point.
"""

from __future__ import annotations

import json
import math
import os
import secrets
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import yaml

from lotsen.errors import ConfigError
from lotsen.files import read_yaml
from lotsen.logs.reader import read_log
from lotsen.messages import (
    ActuatorState, Alert, EstimatorHealth, PlannedRoute, SupervisorStatus, ThrustCommand, Topic, VesselState,
)
from lotsen.model.angles import wrap_angle
from lotsen.runtime.clock import CLOCK_ENV
from lotsen.runtime.lifetime import RUNTIME_DIR_ENV
from lotsen.stack.processes import free_port

WS_PATH = "/ws"
#: a short route from the demo config's harbour (4, 20) inside its 40 m basin, ~30 m, for live runs
SHORT_ROUTE = {"harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0},
               "nodes": [{"north": 10.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5},
                         {"north": 16.0, "east": 24.0, "heading_deg": 60.0, "speed_mps": 0.5},
                         {"north": 22.0, "east": 30.0, "heading_deg": 45.0, "speed_mps": 0.5},
                         {"north": 30.0, "east": 30.0, "heading_deg": 0.0, "speed_mps": 0.5}],
               "area": [[0, 0], [40, 0], [40, 40], [0, 40]]}
#: the short route's first turn (~13 m, ~30 s in AUTO at 0.5 m/s against ~60 s): for live runs whose point
#: is not the route (a flood of strangers, a killed web process, another physics), in `make test`
FIRST_TURN_ROUTE = {**SHORT_ROUTE, "nodes": SHORT_ROUTE["nodes"][:2]}


@dataclass(frozen=True)
class LivePlan:
    """What the operator does, and what else happens, in one live run."""

    config: Path  # launch config; its relative paths resolve from its folder
    idle_s: float = 10.0  # the stack idles this long after start-up before the pilot acts
    route: dict | None = None  # uploaded through the socket; None: the config's route
    return_home: bool = True
    route_timeout_s: float = 600.0
    # the pilot arms this long after the boat reported holding the route (reads the read-back first). A
    # survey's route (the 40 x 30 m one: 78 000 path points) stalled the core's loop 0.15-0.2 s when it
    # arrived (2026-11-28, before it was packed and checked off the loop): an AUTO asked for then was
    # refused (the estimator's health blinked)
    arm_after_route_s: float = 0.0
    # the pilot uploads the route again this long into AUTO: the boat flies the route it holds while the
    # new one is checked, then holds (a new route while moving); the run ends there. Each upload's
    # neighbourhood is judged for the control loop's gaps (`route_arrival_max_gap_ms`)
    reupload_after_auto_s: float | None = None
    seed: int = 0
    environment: dict | None = None  # overrides sim.environment (current, wind)
    flood_viewers: int = 0  # strangers sending maximal valid `plan` requests while the boat is in AUTO
    flood_s: float = 25.0
    flood_route: dict | None = None
    pilot_plans_too: bool = True  # viewers may not plan: the pilot's own page plans at the rate limit too
    kill_web_after_s: float | None = None  # SIGKILL the web process this long after AUTO
    # the pilot's page tries again this long after the kill: a restarted web process can be back within the
    # link timeout (1.5 s), and then no failsafe is due; a page that stays away longer must trip it
    reconnect_after_s: float = 0.0
    allowed_failsafes: tuple[str, ...] = ()  # the failsafes this plan provokes on purpose (e.g. link_lost)
    extra_config: dict = field(default_factory=dict)  # merged into the config's `extra`
    startup_timeout_s: float = 120.0


@dataclass
class LiveReport:
    ok: bool
    failures: list[str]
    figures: dict[str, float]
    timeline: list[tuple[float, str]]  # (runtime s, what happened)
    log_path: str
    output: list[str]  # the program's console

    def summary(self) -> str:
        lines = [f"live run: {'PASS' if self.ok else 'FAIL'} ({self.log_path})"]
        lines += [f"  {k}: {v}" for k, v in self.figures.items()]
        lines += [f"  FAILED: {f}" for f in self.failures]
        return "\n".join(lines)


class _Clock:
    """The run's clock, known to the harness because it chooses the time base (LOTSEN_CLOCK_T0)."""

    def __init__(self) -> None:
        self.t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self.t0


class PilotSocket:
    """A WebSocket client of the operator page's protocol, with a reader thread."""

    def __init__(self, url: str, clock: _Clock, on_frame: Callable[[float, dict], None] | None = None) -> None:
        from websockets.sync.client import connect

        self.clock = clock
        self.ws = connect(url, open_timeout=10, max_size=2**24)
        self.on_frame = on_frame
        self.replies: dict[int, dict] = {}
        self.latest: dict[str, Any] = {}
        self.alerts: list[dict] = []
        self.closed = False
        self.close_reason = ""
        self._next_id = 0
        self._cv = threading.Condition()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()
        threading.Thread(target=self._heartbeat, daemon=True).start()

    def _heartbeat(self) -> None:
        """The page pings every 250 ms: the pilot's liveness the link monitor watches."""
        while not self.closed:
            try:
                self.ws.send(json.dumps({"type": "ping", "t": self.clock.now()}))
            except Exception:  # noqa: BLE001 - closed
                return
            time.sleep(0.25)

    def _read(self) -> None:
        try:
            with self.ws:  # the reader owns the connection's lifetime
                self._read_frames()
        except Exception as exc:  # noqa: BLE001 - a closed or killed server ends the reader
            self.close_reason = repr(exc)[:200]
        with self._cv:
            self.closed = True
            self._cv.notify_all()

    def _read_frames(self) -> None:
        for raw in self.ws:
            t = self.clock.now()
            msg = json.loads(raw)
            with self._cv:
                if msg.get("id") is not None and msg.get("type") not in ("telemetry",):
                    self.replies[int(msg["id"])] = msg
                if msg.get("type") == "telemetry":
                    self.latest = msg
                elif msg.get("type") == "alert":
                    self.alerts.append(msg)
                self._cv.notify_all()
            if self.on_frame is not None:
                self.on_frame(t, msg)

    def request(self, msg: dict, timeout_s: float = 30.0) -> dict:
        from websockets.exceptions import ConnectionClosed

        with self._cv:
            self._next_id += 1
            mid = self._next_id
        try:
            self.ws.send(json.dumps({**msg, "id": mid}))
        except ConnectionClosed as exc:
            raise ConnectionError(f"{msg.get('type')}: the connection is closed ({exc})") from None
        with self._cv:
            if not self._cv.wait_for(lambda: mid in self.replies or self.closed, timeout_s):
                raise TimeoutError(f"no reply to {msg.get('type')} within {timeout_s:g} s")
            if mid not in self.replies:
                raise ConnectionError(f"connection closed before the reply to {msg.get('type')}")
            return self.replies.pop(mid)

    def wait_for(self, pred: Callable[[dict], bool], timeout_s: float) -> dict | None:
        """The latest telemetry frame once `pred(frame)` holds, or None at the timeout."""
        with self._cv:
            ok = self._cv.wait_for(lambda: self.closed or (bool(self.latest) and pred(self.latest)), timeout_s)
            return self.latest if ok and not self.closed else None

    def close(self) -> None:
        try:
            self.ws.close()
        except Exception:  # noqa: BLE001
            pass


def _mode(frame: dict) -> tuple[str, str]:
    sup = frame.get("sup") or {}
    return str(sup.get("mode", "")), str(sup.get("reason", ""))


def _left(mode: str) -> Callable[[dict], bool]:
    """A frame whose supervisor status (a restarted web process may not have one yet) is not `mode`."""
    return lambda f: bool(f.get("sup")) and _mode(f)[0] != mode


def derive_run_config(config: Path, work: Path, port: int, token: str | None, *, seed: int | None = None,
                      environment: dict | None = None, extra: dict | None = None, log_dir: Path | None = None) -> Path:
    """The operator's launch config `config` for one run of `lotsen run` started by a harness:
    the page on 127.0.0.1:`port` with pilot token `token` (None: the boat's own credential,
    lotsen.web.pairing), the recorder writing to work/logs (or `log_dir`),
    relative paths made absolute (the copy lives in `work`, as work/launch.yaml); `seed` and
    `environment` (sim.environment) replace the file's when given, `extra` is merged into its
    `extra` section (one level deep). Returns the copy's path."""
    src = Path(config).resolve()
    data = read_yaml(src, ConfigError, "configuration file") or {}
    if isinstance(data.get("route"), str):
        data["route"] = str((src.parent / data["route"]).resolve())
    data.setdefault("web", {}).update(port=port, host="127.0.0.1", enabled=True, **({"pilot_token": token} if token else {}))
    data.setdefault("logging", {}).update(enabled=True, directory=str(log_dir or work / "logs"))
    if seed is not None:
        data["seed"] = seed
    if environment is not None:
        data.setdefault("sim", {})["environment"] = dict(environment)
    for k, v in (extra or {}).items():
        section = data.setdefault("extra", {})
        section[k] = {**section.get(k, {}), **v} if isinstance(v, dict) else v
    out = work / "launch.yaml"
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


def _flood(url: str, route: dict, source_ip: str, stop: threading.Event, counts: dict, lock: threading.Lock) -> None:
    """One stranger (from its own address) sending `plan` requests at the documented rate limit."""
    from websockets.sync.client import connect

    host, port = url.split("//", 1)[1].split("/", 1)[0].rsplit(":", 1)

    def count(key: str, n: int = 1) -> None:
        with lock:
            counts[key] = counts.get(key, 0) + n

    try:
        sock = socket.create_connection((host, int(port)), timeout=10, source_address=(source_ip, 0))
        ws = connect(url, sock=sock, open_timeout=10, max_size=2**24)
    except Exception:  # noqa: BLE001 - refused at the door counts too
        count("refused_connections")
        return
    mid = 0
    try:
        with ws:
            while not stop.is_set():
                mid += 1
                ws.send(json.dumps({"type": "plan", "id": mid, "route": route}))
                count("sent")
                t_end = time.monotonic() + 0.2  # 5 requests/s: the documented rate limit
                while (left := t_end - time.monotonic()) > 0:
                    try:
                        reply = json.loads(ws.recv(timeout=left))
                    except TimeoutError:
                        break
                    if reply.get("type") == "plan_result":
                        count("planned" if reply.get("ok", True) else "plan_invalid")
                    elif reply.get("type") == "error":
                        count(f"error_{reply.get('code')}")
    except Exception:  # noqa: BLE001 - the server may close a flooding stranger
        count("closed_by_server")


def _pilot_plans(pilot: PilotSocket, route: dict, stop: threading.Event, counts: dict, lock: threading.Lock) -> None:
    """The pilot's page asking for maximal plans at the rate limit: real planning work in the web
    process's worker, while the boat is in AUTO."""
    while not stop.is_set():
        t_end = time.monotonic() + 0.2
        try:
            reply = pilot.request({"type": "plan", "route": route}, timeout_s=30)
        except (TimeoutError, ConnectionError, OSError):
            return
        key = ("pilot_planned" if reply.get("type") == "plan_result" and reply.get("ok", True)
               else f"pilot_{reply.get('type')}_{reply.get('code', 'invalid')}")
        with lock:
            counts[key] = counts.get(key, 0) + 1
        time.sleep(max(0.0, t_end - time.monotonic()))


def maximal_plan_route(max_nodes: int = 200, spacing_m: float = 4.0) -> dict:
    """A valid route at the planning budget's node count: a slalom northwards, nodes
    `spacing_m` apart with their headings along the curve (800 m for the defaults)."""
    amplitude, wavelength = 15.0, 60.0
    nodes = []
    for k in range(1, max_nodes + 1):
        north = k * spacing_m
        east = 100.0 + amplitude * math.sin(2 * math.pi * north / wavelength)
        slope = amplitude * 2 * math.pi / wavelength * math.cos(2 * math.pi * north / wavelength)
        nodes.append({"north": round(north, 3), "east": round(east, 3),
                      "heading_deg": round(math.degrees(math.atan2(slope, 1.0)), 3), "speed_mps": 0.5})
    top = max_nodes * spacing_m + 20.0
    return {"harbour": {"north": 0.0, "east": 100.0, "heading_deg": nodes[0]["heading_deg"]}, "nodes": nodes,
            "area": [[-10.0, 0.0], [top, 0.0], [top, 200.0], [-10.0, 200.0]]}


class LiveProcess:
    """`python -m lotsen run CONFIG --sim` started from another directory, on a time base the
    harness knows; its console is collected line by line."""

    def __init__(self, plan: LivePlan, work: Path) -> None:
        elsewhere = work / "elsewhere"  # the operator's shell is not in the repository
        elsewhere.mkdir(parents=True, exist_ok=True)
        self.work = work
        self.port, self.token = free_port(), secrets.token_urlsafe(24)
        self.url = f"ws://127.0.0.1:{self.port}{WS_PATH}"
        config = derive_run_config(plan.config, work, self.port, self.token, seed=plan.seed,
                                   environment=plan.environment, extra=plan.extra_config)
        self.clock = _Clock()
        # its own run-lock directory: a harness run is its own boat, whatever else runs here
        env = {**os.environ, CLOCK_ENV: repr(self.clock.t0), "PYTHONUNBUFFERED": "1",
               RUNTIME_DIR_ENV: str(work / "run-locks")}
        self.proc = subprocess.Popen([sys.executable, "-m", "lotsen", "run", str(config), "--sim"], cwd=elsewhere,
                                     env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     stdin=subprocess.DEVNULL)
        self.output: list[str] = []
        self._ready = threading.Event()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line.rstrip())
            if line.startswith("processes:"):
                self._ready.set()
        self._ready.set()

    def wait_ready(self, timeout_s: float) -> dict[str, str]:
        """{role: pid} once every process is up; RuntimeError if the run did not start."""
        if not self._ready.wait(timeout_s) or self.proc.poll() is not None:
            raise RuntimeError("lotsen run did not start:\n" + "\n".join(self.output[-30:]))
        line = next(x for x in self.output if x.startswith("processes:"))
        return dict(kv.split("=") for kv in line.split()[1:])

    def stop(self, failures: list[str]) -> int | None:
        """Ctrl-C, as the operator stops it; the exit code."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                failures.append("lotsen run did not stop within 30 s of Ctrl-C")
                self.proc.kill()
                self.proc.wait(5)
        return self.proc.returncode

    def log_path(self) -> str:
        logs = sorted((self.work / "logs").glob("*.mcap"), key=os.path.getmtime)
        return str(logs[-1]) if logs else ""


def run_live(plan: LivePlan, work_dir: str | os.PathLike | None = None) -> LiveReport:
    """One live run as described by `plan`; the report's `ok` is False when any check failed."""
    work = Path(work_dir or tempfile.mkdtemp(prefix="lotsen-live-"))
    live = LiveProcess(plan, work)
    clock, token, url, output = live.clock, live.token, live.url, live.output
    timeline: list[tuple[float, str]] = []
    failures: list[str] = []
    frames: list[tuple[float, dict]] = []
    figures: dict[str, float] = {}
    note = lambda text: timeline.append((round(clock.now(), 2), text))  # noqa: E731
    pilot: PilotSocket | None = None
    t_auto = t_route_end = math.nan
    flood_counts: dict = {}
    uploads: list[float] = []  # when the pilot sent the route (runtime s)
    try:
        pids = live.wait_ready(plan.startup_timeout_s)
        note(f"started: {pids}")
        time.sleep(plan.idle_s)
        note(f"idled {plan.idle_s:g} s")
        pilot = PilotSocket(url, clock, on_frame=lambda t, m: frames.append((t, m)) if m.get("type") == "telemetry"
                            else None)
        reply = pilot.request({"type": "auth", "token": token})
        if reply.get("type") != "auth_ok":
            raise RuntimeError(f"auth refused: {reply}")
        # as the page shows it: the boat hears its pilot (no link-lost failsafe) before anything else
        if pilot.wait_for(lambda f: "link_lost" not in (f.get("sup") or {}).get("failsafes", ["link_lost"]), 10) is None:
            raise RuntimeError("the boat never reported the pilot's link")
        if plan.route is not None:
            t_upload = clock.now()
            reply = pilot.request({"type": "route", "route": plan.route}, timeout_s=60)
            if reply.get("type") != "route_ok":
                raise RuntimeError(f"route refused: {reply}")
            rid = reply["route_id"]
            uploads.append(t_upload)
            if pilot.wait_for(lambda f: (f.get("sup") or {}).get("route_id") == rid, 10) is None:
                raise RuntimeError("the boat never reported holding the uploaded route")
            note(f"route {rid} held by the boat")
            time.sleep(plan.arm_after_route_s)
        pilot.request({"type": "command", "action": "arm"})
        if pilot.wait_for(lambda f: (f.get("sup") or {}).get("armed") is True, 10) is None:
            raise RuntimeError(f"arm not accepted: {pilot.alerts[-3:]}")
        pilot.request({"type": "command", "action": "auto"})
        if pilot.wait_for(lambda f: _mode(f)[0] == "AUTO", 10) is None:
            raise RuntimeError(f"AUTO not accepted: {_mode(pilot.latest)} {pilot.alerts[-3:]}")
        t_auto = clock.now()
        note("AUTO")

        stop_flood = threading.Event()
        lock = threading.Lock()
        flooders = []
        if plan.flood_viewers:
            route = plan.flood_route or maximal_plan_route()
            # each stranger from its own address (127.0.0.2, ...: all loopback), so the per-address
            # connection limit does not do the defending alone
            flooders = [threading.Thread(target=_flood, args=(url, route, f"127.0.0.{i + 2}", stop_flood, flood_counts,
                                                              lock), daemon=True) for i in range(plan.flood_viewers)]
            for th in flooders:
                th.start()
            if plan.pilot_plans_too:
                flooders.append(threading.Thread(target=_pilot_plans, args=(pilot, route, stop_flood, flood_counts,
                                                                            lock), daemon=True))
                flooders[-1].start()
            note(f"flood: {plan.flood_viewers} strangers start")
        t_flood_end = clock.now() + plan.flood_s
        killed = False
        reuploaded = False
        deadline = clock.now() + plan.route_timeout_s
        while True:
            frame = pilot.wait_for(_left("AUTO"), 0.2)
            now = clock.now()
            if plan.route is not None and plan.reupload_after_auto_s is not None and not reuploaded \
                    and now - t_auto >= plan.reupload_after_auto_s:
                reuploaded = True
                uploads.append(now)
                reply = pilot.request({"type": "route", "route": plan.route}, timeout_s=60)
                note(f"route uploaded again in AUTO: {reply.get('type')}")
                if reply.get("type") != "route_ok":
                    failures.append(f"route refused when uploaded again: {reply}")
                    break
                continue
            if flooders and now >= t_flood_end and not stop_flood.is_set():
                stop_flood.set()
                note("flood ends")
                figures["flood_window_s"] = round(plan.flood_s, 1)
            if plan.kill_web_after_s is not None and not killed and now - t_auto >= plan.kill_web_after_s:
                os.kill(int(pids["web"]), signal.SIGKILL)
                killed = True
                note(f"web process {pids['web']} killed")
                time.sleep(plan.reconnect_after_s)
                pilot = _reconnect(url, token, clock, frames, note, timeout_s=60)
                continue
            if frame is not None:
                mode, reason = _mode(frame)
                t_route_end = clock.now()
                note(f"{mode}: {reason}")
                if reuploaded and mode == "HOLD" and "new route" in reason:
                    break  # what the second upload asks for
                if not (mode == "HOLD" and "finished" in reason):
                    failures.append(f"left AUTO before the route's end: {mode} ({reason})")
                break
            if pilot.closed:
                failures.append(f"the pilot's connection closed during AUTO ({pilot.close_reason or 'no reason'})")
                break
            if now > deadline:
                failures.append(f"route not finished within {plan.route_timeout_s:g} s")
                break
        stop_flood.set()
        for th in flooders:
            th.join(5)
        if plan.return_home and not failures:
            pilot.request({"type": "command", "action": "return"})
            if pilot.wait_for(lambda f: _mode(f)[0] == "RETURN", 10) is None:
                failures.append(f"RETURN not accepted: {_mode(pilot.latest)} {pilot.alerts[-3:]}")
            else:
                note("RETURN")
                frame = pilot.wait_for(_left("RETURN"), plan.route_timeout_s)
                mode, reason = _mode(frame or pilot.latest)
                note(f"{mode}: {reason}")
                if not (mode == "HOLD" and "finished" in reason):
                    failures.append(f"RETURN did not end at the harbour: {mode} ({reason})")
        pilot.request({"type": "command", "action": "disarm"})
        time.sleep(0.5)
    except (RuntimeError, TimeoutError, ConnectionError, OSError) as exc:
        failures.append(f"{type(exc).__name__}: {exc}")
    finally:
        t_stop = clock.now()  # the operator leaves: what follows (link lost while disarmed) is not judged
        if pilot is not None:
            pilot.close()
        code = live.stop(failures)
        note(f"stopped (exit code {code})")
    if code not in (0, None):
        failures.append(f"lotsen run exit code {code}")
    failures += [f"console: {line}" for line in output if "Traceback" in line or "control loop silent" in line]
    log_path = live.log_path()
    if not log_path:
        failures.append("no MCAP log written")
    else:
        figures.update(analyse_log(log_path, t_auto, t_route_end if math.isfinite(t_route_end) else t_stop, t_stop,
                                   failures, plan.allowed_failsafes))
        if uploads:
            figures.update(arrival_gaps(log_path, uploads, failures))
        flown = flown_route(log_path, t_auto, t_route_end) \
            if math.isfinite(t_route_end) and plan.reupload_after_auto_s is None else None
        if flown is not None:
            # the route flown to its end: its keeping and the actuators' work (and a survey's lines)
            figures.update(track_figures(flown))
            if plan.route is not None and plan.route.get("survey") is not None:
                figures.update(survey_figures(flown))
    figures.update(telemetry_figures(frames, t_auto, t_route_end if math.isfinite(t_route_end) else t_stop))
    if flood_counts:
        figures.update({f"flood_{k}": v for k, v in flood_counts.items() if isinstance(v, (int, float))})
    return LiveReport(ok=not failures, failures=failures, figures=figures, timeline=timeline, log_path=log_path,
                      output=output)


def _reconnect(url: str, token: str, clock: _Clock, frames: list, note: Callable[[str], None],
               timeout_s: float) -> PilotSocket:
    """The pilot's page reconnects to the restarted web process and takes the seat again."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            pilot = PilotSocket(url, clock, on_frame=lambda t, m: frames.append((t, m))
                                if m.get("type") == "telemetry" else None)
            if pilot.request({"type": "auth", "token": token}).get("type") == "auth_ok":
                note("pilot reconnected to the restarted web process")
                return pilot
            pilot.close()
        except Exception:  # noqa: BLE001 - refused or reset while the web process is not up yet
            pass
        if time.monotonic() > deadline:
            raise RuntimeError(f"the web process did not come back within {timeout_s:g} s")
        time.sleep(0.5)


# ------------------------------------------------------------------------------------------------
# evidence from the run's own log
# ------------------------------------------------------------------------------------------------
def analyse_log(path: str, t_from: float, t_to: float, t_stop: float, failures: list[str],
                allowed_failsafes: tuple[str, ...] = ()) -> dict[str, float]:
    """Figures of the AUTO window [t_from, t_to] (runtime seconds) and of the run up to the
    operator leaving at `t_stop`; appends to `failures` what breaks the live-stack bar (docs/runtime.md)."""
    topics = [Topic.STATE, Topic.TRUTH, Topic.ESTIMATOR_HEALTH, Topic.SHIP_COMMAND, Topic.SUPERVISOR, Topic.ALERT]
    by: dict[str, list] = {t: [] for t in topics}
    for topic, msg in read_log(path, topics):
        by[topic].append(msg)
    fig: dict[str, float] = {}

    # judged while the boat is armed and the operator is there (with no pilot yet, "link lost" is
    # simply true, and harmless: disarmed)
    seen = sorted({f for s in by[Topic.SUPERVISOR] if isinstance(s, SupervisorStatus) and s.armed
                   and s.stamp_s <= t_stop for f in s.active_failsafes})
    seen += sorted({a.code.split(":", 1)[-1] for a in by[Topic.ALERT] if isinstance(a, Alert) and a.active
                    and a.code.startswith("failsafe") and t_from <= a.stamp_s <= t_stop} - set(seen))
    fig["failsafes"] = len(seen)
    unexpected = [f for f in seen if f not in allowed_failsafes]
    if unexpected:
        failures.append(f"failsafes during the run: {unexpected}")
    for name in allowed_failsafes:
        fig[f"failsafe_{name}_seen"] = int(name in seen)

    health = [h for h in by[Topic.ESTIMATOR_HEALTH] if isinstance(h, EstimatorHealth)]
    if health:
        sensors = health[-1].sensors
        for i, name in enumerate(sensors):
            used = [h.used_frac[i] for h in health if len(h.used_frac) > i and math.isfinite(h.used_frac[i])]
            if used:
                fig[f"used_frac_{name}"] = round(float(np.mean(used)), 4)
        low = {k: v for k, v in fig.items() if k.startswith("used_frac_") and v < 0.99}
        if low:
            failures.append(f"the estimator used < 99 % of the samples: {low}")
        bad = [h for h in health if not (h.position_ok and h.heading_ok and h.velocity_ok)]
        fig["health_not_ok"] = len(bad)
        if bad:
            failures.append(f"estimator health not ok {len(bad)} times, first: {bad[0].faults}")
    else:
        failures.append("no estimator health in the log")

    est = [s for s in by[Topic.STATE] if isinstance(s, VesselState) and len(s.std) >= 3]
    truth = [s for s in by[Topic.TRUTH] if isinstance(s, VesselState)]
    if est and len(truth) > 2:
        tt = np.array([s.stamp_s for s in truth])
        order = np.argsort(tt)
        tt = tt[order]
        tn = np.array([truth[i].north_m for i in order])
        te = np.array([truth[i].east_m for i in order])
        th = np.unwrap([truth[i].heading_rad for i in order])
        rows = [s for s in est if tt[0] <= s.stamp_s <= tt[-1]]
        t = np.array([s.stamp_s for s in rows])
        # where the estimator says the boat is: its low-frequency pose plus the wave displacement it separated out
        err = np.column_stack([[s.north_m + s.wave_motion[0] for s in rows] - np.interp(t, tt, tn),
                               [s.east_m + s.wave_motion[1] for s in rows] - np.interp(t, tt, te),
                               wrap_angle(np.array([s.heading_rad + s.wave_motion[2] for s in rows]) - np.interp(t, tt, th))])
        std = np.array([s.std[:3] for s in rows])
        z = np.abs(err) / np.maximum(std, 1e-9)
        outside = float(np.mean(np.any(z > 3.0, axis=1)))
        fig["position_error_rms_m"] = round(float(np.sqrt(np.mean(err[:, 0] ** 2 + err[:, 1] ** 2))), 4)
        fig["heading_error_rms_deg"] = round(float(np.degrees(np.sqrt(np.mean(err[:, 2] ** 2)))), 3)
        fig["beyond_3sigma_frac"] = round(outside, 4)
        fig["max_error_over_sigma"] = round(float(np.max(z)), 2)
        # a Gaussian error leaves 3 sigma 0.27 % of the time; more than 1 % is an overconfident filter
        if outside > 0.01:
            failures.append(f"estimate outside its 3-sigma {outside:.1%} of the time (max {np.max(z):.1f} sigma)")
    else:
        failures.append("no estimate/truth pairs in the log")

    cmds = sorted(c.stamp_s for c in by[Topic.SHIP_COMMAND] if isinstance(c, ThrustCommand) and t_from <= c.stamp_s <= t_to)
    if len(cmds) > 2:
        gaps = np.diff(cmds)
        fig["ship_command_hz"] = round((len(cmds) - 1) / (cmds[-1] - cmds[0]), 2)
        fig["ship_command_max_gap_ms"] = round(float(np.max(gaps)) * 1000, 1)
        if fig["ship_command_hz"] < 9.5 or fig["ship_command_max_gap_ms"] > 150:
            failures.append(f"ship_command {fig['ship_command_hz']} Hz, max gap {fig['ship_command_max_gap_ms']} ms "
                            "(bar: >= 9.5 Hz, <= 150 ms)")
    else:
        failures.append("no ship_command in the AUTO window")
    fig["auto_s"] = round(t_to - t_from, 1)
    return fig


#: a route upload's neighbourhood judged for the control loop's gaps: from the request to this long after
#: it (the planner worker plans it first: the 40 x 30 m survey in 0.3-2 s on this machine)
ARRIVAL_WINDOW_S = 10.0


def arrival_gaps(path: str, uploads: list[float], failures: list[str]) -> dict[str, float]:
    """The largest gap between ship_commands within ARRIVAL_WINDOW_S after each route upload (the
    route's arrival in the core, its check, the switch), against the live-stack bar of 150 ms."""
    cmds = np.array(sorted(c.stamp_s for _, c in read_log(path, [Topic.SHIP_COMMAND]) if isinstance(c, ThrustCommand)))
    fig: dict[str, float] = {}
    worst = 0.0
    for k, t in enumerate(uploads):
        inside = cmds[(cmds >= t) & (cmds <= t + ARRIVAL_WINDOW_S)]
        gap = float(np.max(np.diff(inside))) * 1000 if len(inside) > 2 else math.inf
        fig[f"route_arrival_{k + 1}_max_gap_ms"] = round(gap, 1)
        worst = max(worst, gap)
    fig["route_arrival_max_gap_ms"] = round(worst, 1)
    if worst > 150:
        failures.append(f"ship_command gap {worst:.1f} ms when a route arrived (bar: <= 150 ms)")
    return fig


@dataclass(frozen=True)
class FlownRoute:
    """What the boat flew in an AUTO window, by its log (`flown_route`)."""

    route: Any  # the route it held (lotsen.planning.route.Route)
    path: Any  # that route's planned path
    duration_s: float  # the window's length
    t: np.ndarray  # the true track's times from the window's start (s)
    s_m: np.ndarray  # their arc length on the path
    cross_track_m: np.ndarray  # their signed cross-track error on the path
    actuators: list  # the achieved actuators (ActuatorState) in the window, in time order


def flown_route(path: str, t_from: float, t_to: float) -> FlownRoute | None:
    """What the boat flew in [t_from, t_to] by its log (read once for every figure of it): the route it
    held (its last `planning/route` before t_from) and that route's path, the true track on the path and
    the achieved actuators. None without a route or a track."""
    from lotsen.planning.exchange import path_from_message
    from lotsen.planning.io import route_from_dict
    from lotsen.planning.survey.keeping import track_on_path

    by: dict[str, list] = {t: [] for t in (Topic.ROUTE, Topic.TRUTH, Topic.ACTUATORS)}
    for topic, msg in read_log(path, list(by)):
        by[topic].append(msg)
    routes = [r for r in by[Topic.ROUTE] if isinstance(r, PlannedRoute) and r.stamp_s <= t_from]
    truth = sorted((s for s in by[Topic.TRUTH] if isinstance(s, VesselState) and t_from <= s.stamp_s <= t_to),
                   key=lambda s: s.stamp_s)
    if not routes or len(truth) < 2:
        return None
    route, route_path = route_from_dict(routes[-1].route), path_from_message(routes[-1])
    t = np.array([s.stamp_s for s in truth]) - t_from
    s_m, cte = track_on_path(route_path, np.array([s.north_m for s in truth]), np.array([s.east_m for s in truth]))
    act = sorted((a for a in by[Topic.ACTUATORS] if isinstance(a, ActuatorState) and t_from <= a.stamp_s <= t_to),
                 key=lambda a: a.stamp_s)
    return FlownRoute(route, route_path, t_to - t_from, t, s_m, cte, act)


#: the boat has joined its route once its true track is this close to it (track_figures)
JOINED_M = 0.05


def track_figures(flown: FlownRoute) -> dict[str, Any]:
    """How the boat kept the route it flew (AUTO until the route's end, `flown_route`), on the simulator's
    (or the external physics's) truth: the cross-track RMS and max, over the whole window and from the first
    time within JOINED_M of the route (and when that was), and the actuators' activity over it
    (`lotsen.sim.activity.actuator_activity` on the achieved values: servo travel, propeller speed change,
    reversals, energy), the measures of a mission report and of bench waves."""
    from lotsen.sim.activity import actuator_activity

    t, cte, act = flown.t, flown.cross_track_m, flown.actuators
    out: dict[str, Any] = {"cross_track_rms_m": round(float(np.sqrt(np.mean(cte ** 2))), 4),
                           "cross_track_max_m": round(float(np.max(np.abs(cte))), 4)}
    # a boat that drifted while the stack idled (disarmed, in a current and wind) starts AUTO off its route:
    # the keeping once it has joined the route is the figure to compare between runs
    joined = np.flatnonzero(np.abs(cte) <= JOINED_M)
    if joined.size:
        k = int(joined[0])
        out["joined_after_s"] = round(float(t[k]), 2)
        out["cross_track_joined_rms_m"] = round(float(np.sqrt(np.mean(cte[k:] ** 2))), 4)
        out["cross_track_joined_max_m"] = round(float(np.max(np.abs(cte[k:]))), 4)
    if len(act) > 1:
        out.update(actuator_activity(np.array([a.stamp_s for a in act]), np.array(
            [(a.alpha1_rad, a.alpha2_rad, a.n1_rps, a.n2_rps, a.nt_rps) for a in act])))
    return out


def survey_figures(flown: FlownRoute) -> dict[str, Any]:
    """The line keeping of the survey the boat flew (AUTO until the route's end, `flown_route`), on the
    simulator's truth against the planned route the boat held."""
    from lotsen.planning.survey.keeping import line_keeping, line_spans

    summary = line_keeping(line_spans(flown.route, flown.path), flown.t, flown.s_m, flown.cross_track_m,
                           flown.duration_s).summary()
    out: dict[str, Any] = {f"survey_{k}": v for k, v in summary.items() if k != "per_line"}
    out["survey_per_line"] = summary.get("per_line", [])
    return out


def telemetry_figures(frames: list[tuple[float, dict]], t_from: float, t_to: float) -> dict[str, float]:
    """Rate and age of the telemetry the pilot's page received in [t_from, t_to]: the age is the
    receive time minus the estimate's stamp in the core (core -> Zenoh -> web process -> socket)."""
    inside = [(t, f) for t, f in frames if t_from <= t <= t_to]
    if len(inside) < 3:
        return {}
    ts = np.array([t for t, _ in inside])
    age = np.array([t - f["pose"]["t"] for t, f in inside if f.get("pose") and f["pose"].get("t") is not None])
    out = {"telemetry_hz": round((len(ts) - 1) / (ts[-1] - ts[0]), 2)}
    if age.size:
        out["telemetry_age_p50_ms"] = round(float(np.percentile(age, 50)) * 1000, 1)
        out["telemetry_age_p95_ms"] = round(float(np.percentile(age, 95)) * 1000, 1)
    sea = [f["sea"] for _, f in frames if isinstance(f.get("sea"), dict)]
    if sea:  # the sea state the page showed last (the whole run: it needs ~40 s of data)
        for key in ("hs", "tp", "from"):
            if sea[-1].get(key) is not None:
                out[f"page_sea_{key}"] = sea[-1][key]
    return out
