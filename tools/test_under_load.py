"""The default test suite, N times in a row, on a busy machine: two CPU burners (`while True: pass`,
one per core of a 2-core machine) run for the whole time. Writes bench/results/under_load.{md,json}.

    .venv/bin/python tools/test_under_load.py [--runs 10] [--burners 2] [--live]

Each run is the first step of `make test` (everything on simulated time: `pytest -n 2 --dist
loadfile -m "not live"`); with --live also its wall-clock steps (the live tests two at a time, then
the `alone` ones on their own, each with the one retry `make test` allows). A run counts as green only when pytest exits 0. The suite is meant to
be deterministic: a red run under load is a bug to fix, not noise.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import subprocess
import sys
import time
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
SUMMARY = re.compile(r"(\d+) (passed|failed|error|errors|skipped|deselected|xfailed|xpassed)")


def _pytest(args: list[str], cache: bool = False) -> tuple[int, dict[str, int], float, str]:
    t0 = time.monotonic()
    plugins = [] if cache else ["-p", "no:cacheprovider"]  # --last-failed needs the cache
    p = subprocess.run([sys.executable, "-m", "pytest", "-q", *plugins, *args], cwd=ROOT,
                       capture_output=True, text=True)
    counts: dict[str, int] = {}
    tail = p.stdout.strip().splitlines()[-1] if p.stdout.strip() else ""
    for n, what in SUMMARY.findall(tail):
        counts[what] = int(n)
    failed = [ln for ln in p.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))]
    return p.returncode, counts, time.monotonic() - t0, "; ".join(failed[:5])


def write_results(rows: list[dict], meta: dict) -> None:
    """bench/results/under_load.{json,md}, rewritten after every run (a stopped series keeps what ran)."""
    green = sum(1 for r in rows if r["pass"])
    meta = {**meta, "green": green, "of": len(rows)}
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "under_load.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    cols = ["run", "step", "exit", "passed", "failed", "skipped", "deselected", "wall_s", "failed_tests"]
    done = "" if len(rows) >= meta["runs"] * meta["steps"] else f" (stopped after {len(rows)} of {meta['runs']} planned)"
    md = ["# under load", "",
          f"The default test suite run {meta['runs']} times in a row with {meta['burners']} CPU burners "
          "(`while True: pass`) running the whole time (`tools/test_under_load.py`).", "",
          f"Measured {meta['date']} on {meta['machine']}, Python {meta['python']}, commit {meta['commit']}: "
          f"**{green} of {len(rows)} green**{done}.", "",
          "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(str(r.get(c, "")) for c in cols) + " |" for r in rows]
    (RESULTS / "under_load.md").write_text("\n".join(md) + "\n")


def makefile_selection(name: str) -> str:
    """The Makefile's `NAME := <pytest -m expression>`: the selections `make test` runs, read where they
    are written so that this tool cannot drift from them."""
    for line in (ROOT / "Makefile").read_text().splitlines():
        m = re.fullmatch(rf"{name}\s*:=\s*(.+?)\s*", line)
        if m:
            return m.group(1)
    raise SystemExit(f"test_under_load: the Makefile defines no {name}")


# the wall-clock steps of `make test`: two at a time, then the `alone` ones on their own
LIVE_STEPS = [("live, two at a time (wall clock, one retry)", ["-n", "2", "--dist", "loadfile"],
               makefile_selection("LIVE_PAIRED")),
              ("live, alone (wall clock, one retry)", [], makefile_selection("LIVE_ALONE"))]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--burners", type=int, default=2)
    ap.add_argument("--live", action="store_true", help="also the wall-clock step of make test")
    args = ap.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    meta = {"date": datetime.now().strftime("%Y-%m-%d %H:%M"), "machine": f"{platform.machine()}, {os.cpu_count()} CPUs",
            "python": platform.python_version(), "commit": commit or "?", "burners": args.burners, "runs": args.runs,
            "steps": 1 + len(LIVE_STEPS) if args.live else 1}
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.burners)]
    rows: list[dict] = []
    try:
        for k in range(1, args.runs + 1):
            rc, counts, wall, failed = _pytest(["-n", "2", "--dist", "loadfile", "-m", "not live"])
            row = {"run": k, "step": "simulated time (-m 'not live', -n 2)", "exit": rc, **counts,
                   "wall_s": round(wall, 1), "failed_tests": failed, "pass": rc == 0}
            rows.append(row)
            print(json.dumps(row), flush=True)
            write_results(rows, meta)
            if args.live:
                for step, workers, marker in LIVE_STEPS:
                    rc, counts, wall, failed = _pytest([*workers, "-m", marker], cache=True)
                    if rc != 0:  # make test's one retry of a live step, on its own
                        rc, counts, wall2, failed = _pytest(["-m", marker, "--last-failed"], cache=True)
                        wall += wall2
                    row = {"run": k, "step": step, "exit": rc, **counts,
                           "wall_s": round(wall, 1), "failed_tests": failed, "pass": rc == 0}
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                    write_results(rows, meta)
    finally:
        for b in burners:
            b.kill()
    return 0 if rows and all(r["pass"] for r in rows) and len(rows) == args.runs * meta["steps"] else 1


if __name__ == "__main__":
    sys.exit(main())
