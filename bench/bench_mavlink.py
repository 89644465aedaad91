"""MAVLink telemetry does not slow the control loop (issue 40): `lotsen run --sim --mavlink` at
wall-clock pace with a ground station asking for every telemetry message at 10 Hz while 20
strangers' pages flood the web process with `plan` requests and the pilot's page runs the short
route in AUTO; judged by the run's own MCAP log (lotsen.stack.soak), as bench_live's flood row.

Rows: with the ground station (ours), and the same run without the MAVLink endpoint (peer, same
session, shown beside it). Bar: ship_command >= 9.5 Hz with no gap over 150 ms, no failsafe; the
ground station's received message rate is reported.
"""

from __future__ import annotations

import os
import socket
import tempfile
import threading
import time
from pathlib import Path

from lotsen.stack.soak import SHORT_ROUTE, LivePlan, run_live

CONFIG = Path(__file__).resolve().parents[1] / "config" / "sim.yaml"
#: every telemetry message the endpoint sends, asked at 10 Hz (HEARTBEAT stays 1 Hz)
TELEMETRY_IDS = (1, 147, 24, 33, 30, 74, 242, 42, 62)


def _watch(port: int, stop: threading.Event, counts: dict) -> None:
    """An unsigned ground station (it watches: the page's pilot keeps the seat) on udpin:port."""
    os.environ.setdefault("MAVLINK20", "1")
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255, source_component=190,
                                      dialect="ardupilotmega")
    asked = False
    t_first = None
    while not stop.is_set():
        m = conn.recv_match(blocking=True, timeout=0.2)
        if m is None or m.get_type() == "BAD_DATA":
            continue
        t_first = t_first or time.monotonic()
        counts["messages"] = counts.get("messages", 0) + 1
        if not asked:
            for mid in TELEMETRY_IDS:
                conn.mav.command_long_send(1, 1, 511, 0, mid, 100_000, 0, 0, 0, 0, 0)
            asked = True
        if time.monotonic() - counts.get("beat", 0.0) > 1.0:
            conn.mav.heartbeat_send(6, 8, 0, 0, 0)
            counts["beat"] = time.monotonic()
    counts["seconds"] = time.monotonic() - (t_first or time.monotonic())
    conn.close()


def _row(name: str, mavlink: bool, quick: bool) -> dict:
    counts: dict = {}
    stop = threading.Event()
    extra = {}
    watcher = None
    if mavlink:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        extra = {"mavlink": {"endpoints": [f"udpout:127.0.0.1:{port}"]}}
        watcher = threading.Thread(target=_watch, args=(port, stop, counts), daemon=True)
        watcher.start()
    plan = LivePlan(config=CONFIG, idle_s=3.0, route=SHORT_ROUTE, flood_viewers=20, flood_s=15.0 if quick else 25.0,
                    return_home=False, extra_config=extra)
    with tempfile.TemporaryDirectory(prefix="lotsen-bench-mavlink-") as work:
        r = run_live(plan, work)
    stop.set()
    if watcher is not None:
        watcher.join(5)
    f = r.figures
    rate = counts.get("messages", 0) / counts["seconds"] if counts.get("seconds") else None
    return {"table": "control loop with a ground station and 20 flooding pages", "case": name,
            "role": "ours" if mavlink else "peer", "ship_command_hz": f.get("ship_command_hz"),
            "max_gap_ms": f.get("ship_command_max_gap_ms"), "failsafes": f.get("failsafes"),
            "gcs_messages_per_s": round(rate, 1) if rate else None, "telemetry_hz": f.get("telemetry_hz"),
            "flood_requests": f.get("flood_sent"), "target": ">= 9.5 Hz, gap <= 150 ms, no failsafe",
            "pass": bool(r.ok) if mavlink else None, "failures": "; ".join(r.failures)[:300]}


def run(quick: bool = False) -> list[dict]:
    rows = [_row("MAVLink endpoint, a ground station at 10 Hz per message, 20 pages flooding, AUTO", True, quick)]
    rows.append(_row("the same without the MAVLink endpoint", False, quick))
    return rows
