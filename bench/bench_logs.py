"""Logs and transport benchmarks (issue 8).

* Zenoh over TCP loopback between two processes (bridge to bridge, what `lotsen` does): messages
  per second delivered, and one-way latency (median, p99) from `bus.publish` on the sender to the
  receiver's bus, for JSON vs ROS 2 CDR encoding, for ImuSample (sensor_msgs/Imu) and VesselState
  (nav_msgs/Odometry). Latency uses CLOCK_MONOTONIC, shared by processes on one machine.
* The MCAP recorder's sustained write rate (writer thread, zstd, fsync every flush), with and
  without the Foxglove views, and the cost it adds to each `bus.publish` on the control thread.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from lotsen.stack.processes import free_port  # noqa: E402  (after the path set-up above)

RECEIVER = r"""
import json, sys, threading, time
from lotsen.runtime import RealtimeExecutor
from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge
ex = RealtimeExecutor()
br = ZenohBridge(BridgeConfig(vessel="rx", connect=(sys.argv[1],), subscribe=("tx/**",), drain_period_s=0.0005,
                              queue_maxlen=100000))
ex.add_node(br)
lat = []
last = [None]
def on_bench(m):
    now = time.monotonic()
    lat.append(now - m.stamp_s)
    last[0] = now
ready = []
def on_warm(m):
    if not ready:
        ready.append(1); print("ready", flush=True)
ex.bus.subscribe("bench", on_bench)
ex.bus.subscribe("warmup", on_warm)
def wait_stdin():
    sys.stdin.read(); ex.stop()
threading.Thread(target=wait_stdin, daemon=True).start()
ex.run()
print(json.dumps({"n": len(lat), "lat": lat, "t_last": last[0], "dropped_in": br.stats.dropped_in}), flush=True)
br.close()
"""



def _pct(xs: list[float], p: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(round(p / 100 * (len(xs) - 1))))]


def _zenoh_case(kind: str, encoding: str, n: int, rate_hz: float | None) -> dict:
    from lotsen import messages as M
    from lotsen.runtime import SimExecutor
    from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge

    ep = f"tcp/127.0.0.1:{free_port()}"
    ex = SimExecutor()
    tx = ZenohBridge(BridgeConfig(vessel="tx", listen=(ep,), publish=("bench", "warmup"), encoding=encoding,
                                  queue_maxlen=100000))
    ex.add_node(tx)
    rx = subprocess.Popen([sys.executable, "-c", RECEIVER, ep], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                          text=True, env={**os.environ, "PYTHONPATH": str(REPO)})

    def make(t: float):
        if kind == "ImuSample":
            return M.ImuSample(stamp_s=t, gyro_radps=(0.01, -0.02, 0.03), accel_mps2=(0.1, 0.2, -9.81))
        return M.VesselState(stamp_s=t, north_m=12.3, east_m=-4.5, heading_rad=1.2, u_mps=1.1, v_mps=0.05,
                             r_radps=0.02, source="ekf", std=(0.01,) * 6)

    try:
        ready = threading.Event()
        threading.Thread(target=lambda: (rx.stdout.readline(), ready.set()), daemon=True).start()
        deadline = time.monotonic() + 20
        while not ready.is_set() and time.monotonic() < deadline:
            ex.bus.publish("warmup", make(time.monotonic()))
            time.sleep(0.05)
        if not ready.is_set():
            raise RuntimeError("receiver did not connect")
        t0 = time.monotonic()
        for i in range(n):
            if rate_hz:
                target = t0 + i / rate_hz
                while time.monotonic() < target:
                    time.sleep(max(0.0, min(0.001, target - time.monotonic())))
            ex.bus.publish("bench", make(time.monotonic()))
        t_sent = time.monotonic()
        time.sleep(1.0 if rate_hz else 2.0 + n / 3000)  # let a flood drain (queues hold it all)
        rx.stdin.close()
        out = json.loads(rx.stdout.readline())
        rx.wait(20)
    finally:
        if rx.poll() is None:
            rx.kill()
        tx.close()
    lat = out["lat"]
    got = out["n"]
    row = {"case": f"zenoh {kind} {encoding.upper() if encoding == 'json' else 'CDR'}",
           "mode": f"{rate_hz:.0f} Hz" if rate_hz else "flood", "sent": n, "received": got,
           "dropped_tx": tx.stats.dropped_out}
    row["dropped_rx"] = out["dropped_in"]
    if rate_hz is None and got:
        # delivered rate over the burst: from the sender's first publish to the last arrival
        row["delivered_msgs_per_s"] = round(got / max(1e-9, out["t_last"] - t0))
    if lat:
        row["latency_p50_ms"] = round(statistics.median(lat) * 1e3, 3)
        row["latency_p99_ms"] = round(_pct(lat, 99) * 1e3, 3)
    return row


def _recorder_case(n: int, views: bool) -> dict:
    from lotsen import messages as M
    from lotsen.logs.recorder import McapRecorder, RecorderConfig
    from lotsen.runtime import Bus

    msgs = []
    for i in range(n):
        t = i * 0.01
        if i % 5 == 4:
            msgs.append(("state/estimate", M.VesselState(stamp_s=t, north_m=i * 0.01, east_m=0.0, heading_rad=0.1,
                                                         u_mps=1.0, v_mps=0.0, r_radps=0.0, source="ekf", std=(0.01,) * 6)))
        else:
            msgs.append(("imu/data_raw", M.ImuSample(stamp_s=t, gyro_radps=(0.01, 0.0, 0.02), accel_mps2=(0.0, 0.1, -9.81))))
    with tempfile.TemporaryDirectory() as d:
        bus = Bus()
        rec = McapRecorder(RecorderConfig(queue_maxlen=n + 10, foxglove_views=views, fsync=True)).attach(bus)
        rec.start(Path(d) / "bench.mcap")
        t0 = time.perf_counter()
        for topic, m in msgs:
            bus.publish(topic, m)
        t_pub = time.perf_counter() - t0
        stats = rec.stop()
        t_all = time.perf_counter() - t0
        size = (Path(d) / "bench.mcap").stat().st_size
    bare = Bus()
    t0 = time.perf_counter()
    for topic, m in msgs:
        bare.publish(topic, m)
    t_bare = time.perf_counter() - t0
    return {"case": f"recorder{' + foxglove views' if views else ''}", "mode": "sustained (zstd, fsync 2 Hz)",
            "sent": n, "received": stats.written, "dropped_tx": stats.dropped,
            "write_msgs_per_s": round(stats.written / t_all), "write_MB_per_s": round(size / t_all / 1e6, 2),
            "bytes_per_msg": round(size / max(1, stats.written), 1),
            "publish_overhead_us": round((t_pub - t_bare) / n * 1e6, 2)}


def run(quick: bool = False) -> list[dict]:
    rows = []
    n_rate = 200 if quick else 1000
    n_flood = 2000 if quick else 10000
    for kind in ("ImuSample", "VesselState"):
        for enc in ("json", "cdr"):
            rows.append(_zenoh_case(kind, enc, n_rate, 200.0))
            rows.append(_zenoh_case(kind, enc, n_flood, None))
    # peers side by side: CDR relative to JSON on the same machine in the same run
    by = {(r["case"], r["mode"]): r for r in rows}
    for kind in ("ImuSample", "VesselState"):
        j, c = by.get((f"zenoh {kind} JSON", "flood")), by.get((f"zenoh {kind} CDR", "flood"))
        if j and c and j.get("delivered_msgs_per_s"):
            c["cdr_vs_json_rate"] = round(c["delivered_msgs_per_s"] / j["delivered_msgs_per_s"], 2)
    n_rec = 5000 if quick else 30000
    rows.append(_recorder_case(n_rec, views=False))
    rows.append(_recorder_case(n_rec, views=True))
    # target: the sim stack publishes ~1.5 k msg/s (100 Hz IMU, 50 Hz mag, truth, ...): 3x margin
    for r in rows[-2:]:
        r["target"] = ">= 4500 msg/s"
        r["pass"] = r["write_msgs_per_s"] >= 4500
    return rows


if __name__ == "__main__":
    for r in run(quick="--quick" in sys.argv):
        print(r)
