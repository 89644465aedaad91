"""Simulator real-time factor (vessel + actuators + sensors) on one core; target >= 1000x.

Rows: the simulator alone (`Simulator.advance`, set-points held for 1 s chunks: the vessel and
actuators integrated in one compiled call, the sensors sampled per step in Python) at two IMU
rates and truth only; the runtime's node graph (one step per timer tick, every sensor message
delivered on the bus: what `lotsen sim` and the full stack pay); and the same truth-only run with
numba switched off (the pure-Python peer of the same code) for the speed-up ratio.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

TARGET_RTF = 1000.0


def _rtf_simulator(seconds: float, imu_rate_hz: float, sensors: bool = True) -> float:
    from lotsen.sim import ImuConfig, SimConfig, Simulator

    sim = Simulator(config=SimConfig(seed=1, sensors=sensors, imu=ImuConfig(rate_hz=imu_rate_hz)))
    sim.command([0.1, 0.1, 60, 60, 10])
    sim.advance(1.0)  # compile and warm up
    best = 0.0
    for _ in range(3):
        t = time.perf_counter()
        # one-second chunks whose messages are handed on and dropped, as a consumer does; holding
        # all of a 600 s run's messages at once would measure Python's garbage collector instead
        for _ in range(int(seconds)):
            sim.advance(1.0)
        best = max(best, seconds / (time.perf_counter() - t))
    return best


def _rtf_runtime(seconds: float) -> float:
    from lotsen.runtime.config import LaunchConfig
    from lotsen.stack.launch import build_stack
    from lotsen.stack.schedule import DEMO_SCHEDULE, ScheduleNode

    stack = build_stack(LaunchConfig(), realtime=False, parts=())
    stack.add(ScheduleNode(DEMO_SCHEDULE))
    stack.executor.run_until(1.0)
    t = time.perf_counter()
    stack.executor.run_until(1.0 + seconds)
    return seconds / (time.perf_counter() - t)


def _rtf_pure_python(seconds: float) -> float:
    code = ("import json,sys; sys.path.insert(0, '.'); from bench.bench_sim import _rtf_simulator; "
            f"print(json.dumps(_rtf_simulator({seconds}, 100.0, sensors=False)))")
    env = {**os.environ, "LOTSEN_NO_JIT": "1"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return float(json.loads(out.stdout.strip().splitlines()[-1]))


def run(quick: bool = False) -> list[dict]:
    seconds = 60.0 if quick else 600.0
    rows = []
    rtf_jit_truth = _rtf_simulator(seconds, 100.0, sensors=False)
    for label, rtf, targeted in (
        ("simulator, IMU 100 Hz, mag 50 Hz, GNSS 8 Hz, tacho 20 Hz", _rtf_simulator(seconds, 100.0), True),
        ("simulator, IMU 50 Hz (other sensors as above)", _rtf_simulator(seconds, 50.0), True),
        ("simulator, truth only (no sensors)", rtf_jit_truth, True),
        # the bus, executor and per-step timer cost more than the physics: shown for scale
        ("runtime node graph: sim node + schedule + bus, IMU 100 Hz", _rtf_runtime(seconds / 4), False),
    ):
        rows.append({"case": label, "sim_seconds": seconds, "real_time_factor": round(rtf, 1),
                     "target": TARGET_RTF if targeted else None, "pass": rtf >= TARGET_RTF if targeted else None})
    py = _rtf_pure_python(seconds / 10)
    rows.append({"case": "truth only, pure Python (LOTSEN_NO_JIT=1): peer of the same code",
                 "sim_seconds": seconds / 10, "real_time_factor": round(py, 1), "target": None, "pass": None,
                 "numba_speedup": round(rtf_jit_truth / py, 1)})
    return rows
