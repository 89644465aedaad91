"""Operator interface telemetry: rate and latency on loopback (issue 7: >= 20 Hz, <= 100 ms).

A realtime stack (simulated boat + web server on a free port) runs in a thread; WebSocket
clients (the `websockets` library, like a browser would) count telemetry frames and, for each
frame, the time from the publication of its pose on the bus (recorded by a bus subscriber on the
executor thread) to the frame's receipt. Also: the pilot's manual command from `send` to its
publication on the bus (the control direction).
"""

from __future__ import annotations

import json
import statistics
import threading
import time

from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig, LoggingSection, WebSection
from lotsen.runtime.launch import build_stack
from lotsen.web.part import add_web

TOKEN = "bench-token"


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


def run(quick: bool = False) -> list[dict]:
    duration = 3.0 if quick else 10.0
    rows = [_measure(1, duration, 20.0, full=True)]
    if not quick:
        rows.append(_measure(5, duration, 20.0, full=True))
        rows.append(_measure(1, duration, 20.0, full=False))
    return rows


if __name__ == "__main__":
    for row in run(quick=True):
        print(row)
