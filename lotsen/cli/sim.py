"""`lotsen sim`: run the simulated boat under an open-loop input schedule and write its trajectory."""

from __future__ import annotations

import argparse
import csv
import math
import sys
import time
from pathlib import Path

from lotsen.errors import ConfigError
from lotsen.files import atomic_output, check_output
from lotsen.messages import Topic
from lotsen.settings import SEED, Number
from lotsen.stack.config import config_files, load_stack_config
from lotsen.stack.launch import build_stack
from lotsen.stack.schedule import DEMO_SCHEDULE, ScheduleNode, load_schedule
from lotsen.runtime.executor import SimExecutor


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sim", help="run the simulated boat open loop and write the trajectory (CSV)")
    p.add_argument("--duration", type=Number(0.01, 3600.0, "s"), default=60.0,
                   help="simulated seconds (default 60, at most an hour)")
    p.add_argument("--schedule", help="input schedule YAML (segments of set-points); default: a demo manoeuvre")
    p.add_argument("--config", help="launch config YAML (sim and vessel sections are used)")
    p.add_argument("--seed", type=SEED, help="random seed (overrides the config)")
    p.add_argument("--out", default="trajectory.csv", help="trajectory CSV (default trajectory.csv)")
    p.add_argument("--rate", type=Number(0.1, 100.0, "Hz"), default=20.0,
                   help="trajectory rows per second (default 20; at most the simulator's 100)")
    p.add_argument("--headless", action="store_true", help="no user interface (the only mode of this command)")
    p.set_defaults(func=run)


COLUMNS = ("t", "north", "east", "psi", "u", "v", "r", "alpha1", "alpha2", "n1", "n2", "nt")


def run(args: argparse.Namespace) -> int:
    config = load_stack_config(args.config)
    inputs = (args.config, args.schedule, *config_files(config))
    check_output(args.out, inputs, ConfigError, "trajectory")
    if args.seed is not None:
        from dataclasses import replace

        config = replace(config, seed=args.seed)
    schedule = load_schedule(args.schedule) if args.schedule else DEMO_SCHEDULE
    stack = build_stack(config, realtime=False, parts=())
    stack.add(ScheduleNode(schedule))
    sim = stack.simulator
    assert sim is not None and isinstance(stack.executor, SimExecutor)
    rows: list[tuple[float, ...]] = []

    def record() -> None:
        x, a = sim.x, sim.actuators.state
        rows.append((sim.t, *x, *a))

    stack.executor.add_timer(1.0 / args.rate, record, "trajectory")
    wall = time.perf_counter()
    stack.executor.run_until(args.duration)
    wall = time.perf_counter() - wall
    out = Path(args.out)
    with atomic_output(out, inputs, ConfigError, "trajectory") as tmp, tmp.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([f"{v:.6g}" if i else f"{v:.3f}" for i, v in enumerate(r)])
    x = sim.x
    counts = stack.bus.stats.published
    print(f"simulated {args.duration:.1f} s in {wall:.2f} s wall ({args.duration / wall:.0f}x real time) -> {out}")
    print(f"final: N = {x[0]:.2f} m, E = {x[1]:.2f} m, heading = {math.degrees(x[2]) % 360:.1f} deg, "
          f"u = {x[3]:.2f} m/s, v = {x[4]:.3f} m/s, r = {math.degrees(x[5]):.1f} deg/s")
    print("messages: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())), file=sys.stderr)
    return 0
