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


def _fmt(v: object) -> str:
    if isinstance(v, bool):
        return "yes" if v else "NO"
    if isinstance(v, float):
        return f"{v:.4g}"
    return "" if v is None else str(v)


def markdown_table(rows: list[dict], skip: tuple[str, ...] = ()) -> str:
    """One table of `rows`: the columns any row has (in first-seen order), without `skip` and
    without columns that are empty in every row."""
    if not rows:
        return "(no rows)\n"
    cols: list[str] = []
    for r in rows:
        for k in r:
            if k not in cols and k not in skip and any(_fmt(x.get(k)) != "" for x in rows):
                cols.append(k)
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(_fmt(r.get(c)).replace("|", "/") for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def grouped(rows: list[dict]) -> list[tuple[str, list[dict]]]:
    """Rows by the question they answer (their `table` key), in first-seen order."""
    groups: dict[str, list[dict]] = {}
    for r in rows:
        groups.setdefault(str(r.get("table", "results")), []).append(r)
    return list(groups.items())


def verdict(rows: list[dict]) -> str:
    """'pass' when every judged row passed, 'FAIL (k of n)' otherwise, 'info' without verdicts. A
    peer's row (`role: peer`, e.g. the design it is compared with) and an ablation's (`role: ablation`,
    the product with one part switched off to show what that part contributes) are shown, not judged."""
    judged = [r["pass"] for r in rows if isinstance(r.get("pass"), bool) and r.get("role") not in ("peer", "ablation")]
    if not judged:
        return "info"
    failed = judged.count(False)
    return "pass" if not failed else f"FAIL ({failed} of {len(judged)})"


def targets(rows: list[dict]) -> str:
    seen: list[str] = []
    for r in rows:
        t = r.get("target")
        if t and not str(t).startswith("(info") and str(t) not in seen:
            seen.append(str(t))
    return "; ".join(seen)


def tables_markdown(rows: list[dict]) -> str:
    """One small table per question: its title, its target(s), its verdict, then the rows."""
    out = []
    for title, group in grouped(rows):
        t = targets(group)
        out.append(f"### {title}\n\n" + (f"Target: {t}. " if t else "") + f"Verdict: **{verdict(group)}**.\n\n"
                   # a target shared by every row is in the title already
                   + markdown_table(group, skip=("table",) + (("target",) if len({str(r.get("target")) for r in group}) == 1 else ())))
    return "\n".join(out)


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
    ap.add_argument("--render", action="store_true", help="only rewrite the .md tables from the stored .json")
    ap.add_argument("--baseline", metavar="PATH", help="a checkout to pair with where a benchmark compares "
                    "(bench_footprint: e.g. a worktree of main, `git worktree add ../base main`)")
    ap.add_argument("names", nargs="*", help="benchmark names (e.g. sim control); default all")
    args = ap.parse_args()
    if args.render:
        return render_only()
    if args.baseline:
        import os

        os.environ["LOTSEN_BENCH_BASELINE"] = str(Path(args.baseline).resolve())
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
        (RESULTS / f"{name}.md").write_text(result_markdown(result, doc))
        print(tables_markdown(rows) if error is None else error, flush=True)
    (RESULTS / "README.md").write_text(index_page())
    return 1 if failed else 0


def result_markdown(result: dict, doc: str) -> str:
    m = result.get("machine", {})
    body = tables_markdown(result.get("rows", [])) if not result.get("error") else f"```\n{result['error']}\n```\n"
    return (f"# {result.get('benchmark')}\n\n{doc}\n\nMeasured {m.get('date', '?')} on {m.get('machine', '?')}, "
            f"Python {m.get('python', '?')}{' (quick mode)' if result.get('quick') else ''}; the run took "
            f"{result.get('elapsed_s', '?')} s.\n\n{body}")


def stored_results() -> list[tuple[Path, dict]]:
    """The benchmarks' stored results (bench/results/*.json written by `main`); other JSON there
    (tools/test_under_load.py's under_load.json) has no "benchmark" key and is not one of them."""
    out = []
    for path in sorted(RESULTS.glob("*.json")):
        try:
            result = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(result, dict) and "benchmark" in result:
            out.append((path, result))
    return out


def index_page() -> str:
    """bench/results/README.md from every result present (running one benchmark updates its entry
    and keeps the others): a summary of every question and its verdict on top, then the tables."""
    summary = ["| benchmark | question | target | verdict | measured |", "|---|---|---|---|---|"]
    sections = []
    for _, result in stored_results():
        name = result["benchmark"]
        m = result.get("machine", {})
        when = f"{m.get('date', '?')}{' (quick)' if result.get('quick') else ''}"
        if result.get("error"):
            summary.append(f"| {name} | (the benchmark failed: see {name}.md) |  | FAIL | {when} |")
            continue
        for title, group in grouped(result.get("rows", [])):
            summary.append(f"| [{name}]({name}.md) | {title} | {targets(group).replace('|', '/')} | "
                           f"{verdict(group)} | {when} |")
        sections.append(f"## {name}\n\nMeasured {when} on {m.get('machine', '?')}, Python {m.get('python', '?')}."
                        f" Details and method: [{name}.md]({name}.md).\n\n" + tables_markdown(result.get("rows", [])))
    head = ["# Benchmark results", "", "Written by `make bench` (bench/run.py). One table per question, with its "
            "target, the peer measured in the same run where there is one, and its verdict (rows marked `peer` or "
            "`ablation`, the product with one part switched off, are shown but not judged).", "", "## Summary", ""]
    return "\n".join(head + summary) + "\n\n" + "\n".join(sections)


def render_only() -> int:
    """Rewrite every .md and the index from the stored .json (no benchmark runs)."""
    for _, result in stored_results():
        name = result["benchmark"]
        bench = HERE / f"bench_{name}.py"
        doc = ""
        if bench.exists():
            import ast

            doc = (ast.get_docstring(ast.parse(bench.read_text())) or "").strip()
        (RESULTS / f"{name}.md").write_text(result_markdown(result, doc))
    (RESULTS / "README.md").write_text(index_page())
    return 0


if __name__ == "__main__":
    sys.exit(main())
