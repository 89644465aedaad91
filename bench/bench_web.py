"""Operator interface telemetry: rate and latency on loopback (issue 7: >= 20 Hz, <= 100 ms).

A realtime stack (simulated boat + web server on a free port) runs in a thread; WebSocket
clients (the `websockets` library, like a browser would) count telemetry frames and, for each
frame, the time from the publication of its pose on the bus (recorded by a bus subscriber on the
executor thread) to the frame's receipt. Also: the pilot's manual command from `send` to its
publication on the bus (the control direction). The last case (full run only) measures `lotsen
run` as built: the core and the web server in their own processes, the telemetry crossing Zenoh.
"""

from __future__ import annotations

import json
import statistics
import threading
import time

from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig, LoggingSection, WebSection
from lotsen.stack.launch import build_stack
from lotsen.stack.web import add_web

TOKEN = "bench-Tq7vLx2Rb9KmZ4wNc8Hs"  # >= 128 bits (a weak token is refused at start)


def _pct(xs: list[float], p: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100 * (len(xs) - 1))))] if xs else float("nan")


def _client(port: int, duration_s: float, published: dict, out: list, pilot: bool = False) -> None:
    from websockets.sync.client import connect

    rx, lat, manual_lat = [], [], []
    with connect(f"ws://127.0.0.1:{port}/ws", max_size=1 << 22) as ws:
        if pilot:
            ws.send(json.dumps({"type": "auth", "token": TOKEN}))
        t_end = time.monotonic() + duration_s
        next_manual = time.monotonic()
        while (now := time.monotonic()) < t_end:
            if pilot and now >= next_manual:
                published["manual_sent"].append(time.monotonic())
                ws.send(json.dumps({"type": "manual", "surge": 0.0, "sway": 0.0, "yaw": 0.0}))
                next_manual = now + 0.1
            try:
                m = json.loads(ws.recv(timeout=0.2))
            except TimeoutError:
                continue
            t_rx = time.monotonic()
            if m.get("type") != "telemetry" or not m.get("pose"):
                continue
            rx.append(t_rx)
            t_pub = published["pose"].get((m["pose"]["src"], m["pose"]["t"]))
            if t_pub is not None:
                lat.append(t_rx - t_pub)
    out.append((rx, lat, manual_lat))


def _measure(n_clients: int, duration_s: float, rate_hz: float, full: bool) -> dict:
    cfg = LaunchConfig(web=WebSection(port=0, pilot_token=TOKEN, telemetry_rate_hz=rate_hz),
                       logging=LoggingSection(enabled=False))
    stack = build_stack(cfg, realtime=True, parts=None if full else ())
    server = stack.services.get("web") or add_web(stack)
    published: dict = {"pose": {}, "manual_sent": [], "manual_bus": []}

    def on_pose(msg) -> None:  # executor thread: the moment of publication
        published["pose"][(msg.source, round(msg.stamp_s, 4))] = time.monotonic()

    stack.bus.subscribe(Topic.TRUTH, on_pose)
    stack.bus.subscribe(Topic.STATE, on_pose)
    stack.bus.subscribe(Topic.MANUAL, lambda m: published["manual_bus"].append(time.monotonic()))
    runner = threading.Thread(target=stack.executor.run, daemon=True)
    runner.start()
    out: list = []
    try:
        threads = [threading.Thread(target=_client, args=(server.port, duration_s, published, out, i == 0))
                   for i in range(n_clients)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        stack.executor.stop()
        runner.join(timeout=5)
        for stop in stack.services.get("on_shutdown", []):
            stop()
    rates, lats = [], []
    for rx, lat, _ in out:
        if len(rx) > 2:
            rates.append((len(rx) - 1) / (rx[-1] - rx[0]))
        lats += lat
    sent, bus = published["manual_sent"], published["manual_bus"]
    ctl = [b - s for s, b in zip(sent, bus)]  # in order; the zero sent at close comes last
    lat_ms = [x * 1000 for x in lats]
    p95 = _pct(lat_ms, 95)
    min_rate = min(rates) if rates else 0.0
    return {
        "case": f"{'full stack' if full else 'sim boat only'}, {n_clients} client{'s' if n_clients > 1 else ''}",
        "nodes": "+".join(stack.nodes),
        "rate_hz_min": round(min_rate, 1),
        "latency_p50_ms": round(_pct(lat_ms, 50), 1),
        "latency_p95_ms": round(p95, 1),
        "latency_max_ms": round(max(lat_ms), 1) if lat_ms else float("nan"),
        "manual_to_bus_p50_ms": round(statistics.median(ctl) * 1000, 1) if ctl else float("nan"),
        "frames": sum(len(r) for r, _, _ in out),
        "target": f">= {rate_hz:g} Hz (-5 % jitter), p95 <= 100 ms",
        "pass": bool(min_rate >= 0.95 * rate_hz and p95 <= 100.0),
    }


def _measure_processes(duration_s: float, rate_hz: float = 20.0) -> dict:
    """`lotsen run` as built: the control core and the web server in their own processes, the
    telemetry crossing Zenoh. Latency here is the data age at receipt: the runtime clock (shared
    by every process of the run, LOTSEN_CLOCK_T0) minus the stamp of the pose in the frame."""
    from websockets.sync.client import connect

    from lotsen.stack.processes import Launcher, free_port

    port = free_port()
    cfg = LaunchConfig(web=WebSection(port=port, pilot_token=TOKEN, telemetry_rate_hz=rate_hz),
                       logging=LoggingSection(enabled=False))
    launcher = Launcher(cfg, ("core", "web"), out=lambda line: None)
    rx, age = [], []
    try:
        launcher.start()
        with connect(f"ws://127.0.0.1:{port}/ws", max_size=1 << 22) as ws:
            t_first_pose = time.monotonic() + 60.0
            t_end = t_warm = None
            while True:
                now = time.monotonic()
                if (t_end is not None and now >= t_end) or now > t_first_pose:
                    break
                try:
                    m = json.loads(ws.recv(timeout=0.5))
                except TimeoutError:
                    continue
                if m.get("type") != "telemetry" or not m.get("pose"):
                    continue
                t_rx = time.monotonic()
                if t_end is None:  # count from the first pose on, after a 1 s warm-up (connection,
                    t_end = t_rx + 1.0 + duration_s  # Zenoh discovery, the first estimates)
                    t_warm = t_rx + 1.0
                if t_rx < t_warm:
                    continue
                rx.append(t_rx)
                age.append((t_rx - launcher.clock_t0 - m["pose"]["t"]) * 1000.0)
    finally:
        launcher.stop()
    rate = (len(rx) - 1) / (rx[-1] - rx[0]) if len(rx) > 2 else 0.0
    p95 = _pct(age, 95)
    return {
        "case": "lotsen run: core and web processes, 1 client",
        "nodes": "core, web processes (Zenoh)",
        "rate_hz_min": round(rate, 1),
        "latency_p50_ms": round(_pct(age, 50), 1),
        "latency_p95_ms": round(p95, 1),
        "latency_max_ms": round(max(age), 1) if age else float("nan"),
        "manual_to_bus_p50_ms": float("nan"),
        "frames": len(rx),
        "target": f">= {rate_hz:g} Hz (-5 % jitter), p95 <= 100 ms (data age)",
        "pass": bool(rate >= 0.95 * rate_hz and p95 <= 100.0),
    }


def run(quick: bool = False) -> list[dict]:
    duration = 3.0 if quick else 10.0
    rows = [_measure(1, duration, 20.0, full=True)]
    if not quick:
        rows.append(_measure(5, duration, 20.0, full=True))
        rows.append(_measure(1, duration, 20.0, full=False))
        rows.append(_measure_processes(duration))
    return rows


if __name__ == "__main__":
    import sys

    if "--processes" in sys.argv:
        print(_measure_processes(5.0))
    else:
        for row in run(quick=True):
            print(row)
