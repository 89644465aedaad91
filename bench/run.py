#!/usr/bin/env python3
"""Benchmark harness: runs every bench/bench_*.py (or those named) and writes, per benchmark,
bench/results/<name>.json and a readable bench/results/<name>.md table, plus bench/results/README.md
as an index. Each benchmark module defines `run(quick: bool = False) -> list[dict]` (one dict a row).

Usage: python bench/run.py [--quick] [NAME ...]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import platform
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"


def markdown_table(rows: list[dict]) -> str:
    if not rows:
        return "(no rows)\n"
    cols: list[str] = []
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)

    def fmt(v: object) -> str:
        if isinstance(v, float):
            return f"{v:.4g}"
        if isinstance(v, bool):
            return "yes" if v else "NO"
        return "" if v is None else str(v)

    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(r.get(c)) for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def load(path: Path):  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module
    spec.loader.exec_module(module)
    return module


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="shorter runs (smoke test of the benchmarks)")
    ap.add_argument("names", nargs="*", help="benchmark names (e.g. sim control); default all")
    args = ap.parse_args()
    sys.path.insert(0, str(HERE.parent))
    RESULTS.mkdir(parents=True, exist_ok=True)
    files = sorted(HERE.glob("bench_*.py"))
    if args.names:
        files = [f for f in files if f.stem.removeprefix("bench_") in args.names]
    machine = {"python": platform.python_version(), "machine": platform.machine(),
               "processor": platform.processor() or platform.machine(), "date": time.strftime("%Y-%m-%d %H:%M")}
    failed = 0
    for f in files:
        name = f.stem.removeprefix("bench_")
        print(f"== {name}", flush=True)
        t0 = time.perf_counter()
        try:
            module = load(f)
            rows = module.run(quick=args.quick)
            error = None
        except Exception:  # a broken benchmark is reported, the others still run
            rows, error = [], traceback.format_exc()
            failed += 1
        elapsed = time.perf_counter() - t0
        doc = (module.__doc__ or "").strip() if error is None else ""
        result = {"benchmark": name, "quick": args.quick, "elapsed_s": round(elapsed, 1), "machine": machine,
                  "rows": rows, "error": error}
        (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=2, default=str) + "\n")
        table = markdown_table(rows) if error is None else f"```\n{error}\n```\n"
        (RESULTS / f"{name}.md").write_text(f"# {name}\n\n{doc}\n\n{table}\n(run took {elapsed:.1f} s)\n")
        print(table, flush=True)
    (RESULTS / "README.md").write_text(index_page())
    return 1 if failed else 0


def index_page() -> str:
    """bench/results/README.md from every result present, so running one benchmark updates its
    entry and keeps the others (each with the machine and date it was measured on)."""
    lines = ["# Benchmark results", "", "Written by `make bench` (bench/run.py); each entry says when and where "
             "it was measured.", ""]
    for path in sorted(RESULTS.glob("*.json")):
        try:
            result = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        name = result.get("benchmark", path.stem)
        m = result.get("machine", {})
        md = RESULTS / f"{name}.md"
        parts = md.read_text().split("\n\n") if md.exists() else []
        doc_lines = parts[1].strip().splitlines() if len(parts) > 1 else []
        doc = doc_lines[0] if doc_lines and not doc_lines[0].startswith("|") else ""
        table = markdown_table(result.get("rows", [])) if not result.get("error") else "(failed: see the .md)\n"
        lines += [f"## {name}", "", doc, "", f"Measured {m.get('date', '?')} on {m.get('machine', '?')}, Python "
                  f"{m.get('python', '?')}{' (quick mode)' if result.get('quick') else ''}.", "", table]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
