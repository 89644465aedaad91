"""Fuzz every command (issue 42): the suite's harness (tests/fuzz) run longer, with several draws.

Each case is one `lotsen` command line on hostile input: a flag given NaN, 1e308, a denormal, text,
a missing, empty, oversized or special file, an output that is an input (or a link to one); or one
of the project's own inputs (routes, experiments, config, parameter files, schedule, calibration,
identification and magnetometer CSVs, an MCAP and a UBX capture) mutated in its numbers or bytes.
Every case runs in-process (forked from a warm server) with a 60 s limit; the expensive commands
(`run`, `mission`, `check`, `record`) run their accepted cases here too, which the suite skips.
Counted per command: cases, refusals, tracebacks, hangs (still running at 60 s), invalid input
accepted with exit 0, inputs changed, refusals of certainly invalid input slower than 5 s (the
issue's bar), and the slowest such refusal.
"""

from __future__ import annotations

import random
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
for p in (str(REPO), str(REPO / "tests" / "fuzz")):
    if p not in sys.path:
        sys.path.insert(0, p)

import fuzz_cases as fc  # noqa: E402  (after the path set-up above)
from fuzz_runner import measure  # noqa: E402

CASE_TIMEOUT_S = 60.0
REFUSAL_LIMIT_S = 5.0
TARGET = "0 tracebacks, 0 hangs, 0 invalid accepted, 0 inputs changed, refusals < 5 s"
#: mutated inputs per command and draw (the expensive ones fewer: an accepted mission is ~25 s)
FILE_CASES = {("mission",): 6, ("run",): 6}


def run(quick: bool = False) -> list[dict]:
    from lotsen.cli.main import build_parser

    draws = (1, 2) if quick else (1, 2, 3, 4, 5)
    per_flag = 1 if quick else 2
    per_command = 10 if quick else 30
    stats: dict[str, dict] = {}
    problems: list[str] = []
    t_start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="lotsen-fuzz-") as tmp:
        work = Path(tmp)
        with fc.session(work) as (runner, seeds):
            for draw in draws:
                rng = random.Random(draw)
                cases = fc.flag_cases(build_parser(), rng, per_flag)
                for cmd in fc.COMMANDS:
                    n = FILE_CASES.get(cmd.path, per_command // (3 if not cmd.cheap else 1))
                    cases += fc.file_cases(seeds, rng, n, (cmd,))
                for i, case in enumerate(cases):
                    folder = work / f"d{draw}c{i:05d}"
                    fc.prepare(case, folder, seeds)
                    outcome = measure(runner, case.argv, folder, CASE_TIMEOUT_S, case.inputs)
                    found = fc.judge(case, outcome, REFUSAL_LIMIT_S)
                    s = stats.setdefault(" ".join(case.command), {
                        "cases": 0, "refused": 0, "tracebacks": 0, "hangs": 0, "accepted_invalid": 0,
                        "inputs_changed": 0, "slow_refusals": 0, "silent_refusals": 0, "max_refusal_s": 0.0,
                        "wall_s": 0.0})
                    s["cases"] += 1
                    s["wall_s"] += outcome.seconds
                    refused = outcome.code not in (0, None)
                    s["refused"] += refused
                    s["tracebacks"] += outcome.traceback
                    s["hangs"] += outcome.hang
                    s["accepted_invalid"] += any("accepted" in f for f in found)
                    s["inputs_changed"] += bool(outcome.changed_inputs)
                    s["slow_refusals"] += any("refused after" in f for f in found)
                    s["silent_refusals"] += any("without a message" in f for f in found)
                    if refused and case.must_refuse:
                        s["max_refusal_s"] = max(s["max_refusal_s"], outcome.seconds)
                    if found:
                        problems.append(f"[draw {draw}] {case.label()}: {'; '.join(found)} -- {outcome.describe()}")
                    shutil.rmtree(folder, ignore_errors=True)
    rows = []
    for command, s in sorted(stats.items()):
        bad = s["tracebacks"] + s["hangs"] + s["accepted_invalid"] + s["inputs_changed"] + s["slow_refusals"] + \
            s["silent_refusals"]
        rows.append({"table": "every command on hostile input", "command": command, **s,
                     "max_refusal_s": round(s["max_refusal_s"], 2), "wall_s": round(s["wall_s"], 1),
                     "target": TARGET, "pass": bad == 0})
    total = {k: sum(s[k] for s in stats.values()) for k in ("cases", "refused", "tracebacks", "hangs",
                                                             "accepted_invalid", "inputs_changed", "slow_refusals",
                                                             "silent_refusals")}
    rows.append({"table": "every command on hostile input", "command": "all", **total,
                 "max_refusal_s": round(max((s["max_refusal_s"] for s in stats.values()), default=0.0), 2),
                 "wall_s": round(time.monotonic() - t_start, 1), "target": TARGET,
                 "pass": all(r["pass"] for r in rows)})
    for text in problems[:40]:
        rows.append({"table": "cases that went wrong (first 40)", "case": text[:400]})
    return rows


if __name__ == "__main__":
    import json

    print(json.dumps(run(quick="--quick" in sys.argv), indent=1))
