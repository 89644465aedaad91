"""What `lotsen run --sim` costs the boat's computer: memory, locked memory, idle CPU, start-up.

`lotsen run --sim` (config/sim.yaml, web page on a free port, no browser) is started as the
operator starts it, from another directory. Per process (launcher, core, recorder, web and any
child they start): resident memory (RSS; shared library pages count in every process that maps
them), proportional memory (PSS: shared pages split between the processes, so the PSS column
adds up to what the run really occupies), locked memory (VmLck, /proc/PID/status) and the CPU
used while the boat sits idle for 20 s (10 s quick), in % of one core of this machine, and then
while it follows the config's route in AUTO for as long (armed and put in AUTO through the page's
WebSocket, as the operator does; that page stays connected).
Locked: pages pinned in RAM (smaps Locked); VmLck: the address space under mlock, faulted in or
not (with MCL_ONFAULT a locked but never touched page costs nothing). Working set: the pages
the process touched during the idle window (Referenced after clear_refs).
Start-up: seconds from the command to the web page answering (HTTP 200 on /) and to the core's
control loop running (its banner; the watchdog starts then); "cold" with an empty compiled-kernel
cache (NUMBA_CACHE_DIR), "warm" with the cache the cold start left. Watchdog events: "control
loop silent" lines in the run's console. Repeated warm starts: 10 in a row, then 20 with two CPU
burners (`while True: pass`, one per core of this machine) running, each up to the page and the
control loop and 2 s of running; every start must come up with no watchdog event.
Targets (issue: what a Raspberry Pi carries): total PSS <= 400 MB, core <= 200 MB, locked
<= 256 MB, idle CPU <= 12 %, AUTO CPU <= 15 %, warm start page <= 3 s and control <= 5 s, no
watchdog event.
Paired with one core busy (issue 49): this checkout and a baseline checkout (`bench/run.py
--baseline PATH`, `make bench BASELINE=PATH`, e.g. a worktree of main; without one, this checkout
alone) alternate in the same minutes beside one `while True: pass`: warm starts (page time, then
idle CPU per process over 15 s from 5 s after all processes are up; medians of 4 starts each) and
viewer floods (tests/stack/test_live.py's: 20 strangers flooding `plan` requests for 20 s while the
pilot flies the short route's first turn; the largest ship_command gap of 2 runs each, from the
run's log). Ratio = this / baseline. Bars: idle CPU <= 12 % of one core, page <= 3 s, gap <= 150 ms.
On a machine shared with other work the absolute figures move with that work; the ratios hold.
"""

from __future__ import annotations

import math
import os
import re
import secrets
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

from lotsen.runtime.lifetime import process_cpu_seconds
from lotsen.stack.processes import free_port
from lotsen.stack.soak import PilotSocket, _Clock, derive_run_config

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "config" / "sim.yaml"
PAGE = os.sysconf("SC_PAGE_SIZE")


def _proc_kb(pid: int, name: str, key: str) -> float:
    """One "Key: value kB" line of /proc/PID/<name>: status (VmRSS, VmLck) or smaps_rollup (Pss,
    Locked = pinned resident pages, Referenced); nan when the process is gone."""
    try:
        for line in Path(f"/proc/{pid}/{name}").read_text().splitlines():
            if line.startswith(key + ":"):
                return float(line.split()[1])
    except OSError:
        pass
    return float("nan")


def _clear_referenced(pid: int) -> None:
    try:
        Path(f"/proc/{pid}/clear_refs").write_text("1")
    except OSError:
        pass


def _cpu_s(pid: int) -> float:
    cpu = process_cpu_seconds(pid)
    return math.nan if cpu is None else cpu


def _children(pid: int) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                    out.append(int(d.name))
            except (OSError, IndexError, ValueError):
                pass
    return out


def _tree(root: int, roles: dict[int, str]) -> dict[int, str]:
    """Every process of the run with a name: the roles the run printed, others by command."""
    named = {root: "launcher"}
    todo = [root]
    while todo:
        p = todo.pop()
        for c in _children(p):
            if c not in named:
                try:
                    cmd = Path(f"/proc/{c}/cmdline").read_bytes().replace(b"\0", b" ").decode()[:60]
                except OSError:
                    cmd = "?"
                named[c] = roles.get(c) or ("multiprocessing helper" if "multiprocessing" in cmd else cmd)
                todo.append(c)
    return named


class Run:
    """One `lotsen run --sim` with its console collected and its start-up timed; `code`: the
    checkout whose lotsen runs (its directory on PYTHONPATH), this one by default."""

    def __init__(self, work: Path, numba_cache: Path, code: Path | None = None) -> None:
        self.port = free_port()
        self.token = secrets.token_urlsafe(16)
        config = derive_run_config(CONFIG, work, self.port, self.token)
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "NUMBA_CACHE_DIR": str(numba_cache)}
        if code is not None:
            env["PYTHONPATH"] = str(code)
        self.output: list[str] = []
        self.t0 = time.monotonic()
        self.proc = subprocess.Popen([sys.executable, "-m", "lotsen", "run", str(config), "--sim"], cwd=work,
                                     env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     stdin=subprocess.DEVNULL)
        self.control_s = float("nan")
        self.all_up_s = float("nan")
        self.roles: dict[int, str] = {}
        self._up = threading.Event()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line.rstrip())
            if line.startswith("core:") and self.control_s != self.control_s:
                self.control_s = time.monotonic() - self.t0
            if line.startswith("processes:"):
                self.all_up_s = time.monotonic() - self.t0
                self.roles = {int(pid): role for role, pid in (kv.split("=") for kv in line.split()[1:])}
                self._up.set()
        self._up.set()

    def wait_page(self, timeout_s: float = 120.0) -> float:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end and self.proc.poll() is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{self.port}/", timeout=1.0) as r:
                    if r.status == 200:
                        return time.monotonic() - self.t0
            except OSError:
                pass
            time.sleep(0.05)
        raise RuntimeError("the page did not answer:\n" + "\n".join(self.output[-30:]))

    def wait_up(self, timeout_s: float = 120.0) -> None:
        if not self._up.wait(timeout_s) or not self.roles:
            raise RuntimeError("lotsen run did not start:\n" + "\n".join(self.output[-30:]))

    def watchdog_events(self) -> int:
        return sum("control loop silent" in line for line in self.output)

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)


def _cpu_window(procs: dict[int, str], seconds: float) -> dict[int, float]:
    """% of one core each process used over the next `seconds`."""
    cpu0 = {p: _cpu_s(p) for p in procs}
    t0 = time.monotonic()
    time.sleep(seconds)
    wall = time.monotonic() - t0
    return {p: 100.0 * (_cpu_s(p) - cpu0[p]) / wall for p in procs}


def _go_auto(run: Run) -> tuple[PilotSocket, str]:
    """Arm and AUTO on the config's route through the page's WebSocket; the mode reached."""
    pilot = PilotSocket(f"ws://127.0.0.1:{run.port}/ws", _Clock())
    if pilot.request({"type": "auth", "token": run.token}).get("type") != "auth_ok":
        return pilot, "auth refused"
    sup = lambda f: f.get("sup") or {}  # noqa: E731
    pilot.wait_for(lambda f: "link_lost" not in sup(f).get("failsafes", ["link_lost"]), 15)
    pilot.request({"type": "command", "action": "arm"})
    pilot.wait_for(lambda f: sup(f).get("armed") is True, 10)
    pilot.request({"type": "command", "action": "auto"})
    frame = pilot.wait_for(lambda f: sup(f).get("mode") == "AUTO", 10)
    mode = sup(frame or pilot.latest).get("mode", "?")
    return pilot, mode if mode == "AUTO" else f"{mode} ({[a.get('text') for a in pilot.alerts[-2:]]})"


def _start(work: Path, cache: Path, label: str) -> tuple[Run, dict]:
    run = Run(work, cache)
    page_s = run.wait_page()
    run.wait_up()
    row = {"table": "start-up", "case": label, "page_s": round(page_s, 2), "control_ready_s": round(run.control_s, 2),
           "all_processes_s": round(run.all_up_s, 2)}
    return run, row


def _burners(n: int) -> list[subprocess.Popen]:
    """`n` processes that keep one core each busy (the "CPU burners" of the start-up check)."""
    return [subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)
            for _ in range(n)]


def repeated_start_rows(work: Path, cache: Path, starts: int, burners: int) -> list[dict]:
    """`starts` consecutive warm starts of `lotsen run --sim` with `burners` CPU burners running:
    each waits for the page and the control loop, lets the loop run 2 s, stops; the watchdog's
    "control loop silent" lines of every start are counted."""
    hogs = _burners(burners)
    page, control, events, failed = [], [], 0, []
    try:
        for i in range(starts):
            d = work / f"start-{burners}-{i}"
            d.mkdir()
            run = Run(d, cache)
            try:
                page_s = run.wait_page()
                run.wait_up()
                time.sleep(2.0)
            except RuntimeError as exc:
                failed.append(str(exc).splitlines()[0])
                continue
            finally:
                run.stop()
                events += run.watchdog_events()
            page.append(page_s)
            control.append(run.control_s)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    return [{"table": "repeated warm starts", "burners": burners, "starts": starts, "started": len(page),
             "watchdog_events": events, "page_s_median": round(statistics.median(page), 2) if page else None,
             "page_s_max": round(max(page), 2) if page else None,
             "control_ready_s_max": round(max(control), 2) if control else None,
             "failures": "; ".join(failed)[:200], "target": "every start up, 0 watchdog events",
             "pass": bool(len(page) == starts and events == 0)}]


def arm64_check_rows() -> list[dict]:
    """The last `make pi-check`'s result (bench/results/pi-check.md, its own date): the arm64 build
    of the Pi's OS, emulated, is too slow to run inside this bench."""
    path = Path(__file__).resolve().parent / "results" / "pi-check.md"
    text = path.read_text() if path.is_file() else ""
    run_line = re.search(r"Run (\d{4}-\d\d-\d\d \d\d:\d\d); result: \*\*(\w+)\*\*", text)
    python = re.search(r"\| Python in the image \| ([^|]+) \|", text)
    return [{"table": "arm64 check (make pi-check)", "run": run_line.group(1) if run_line else "never",
             "result": run_line.group(2) if run_line else "no result", "image": "Debian bookworm arm64 (qemu)",
             "python": python.group(1).strip() if python else "?", "details": "pi-check.md",
             "target": "make pi-check passes", "pass": bool(run_line and run_line.group(2) == "pass")}]


#: the checkout to pair this one with (`bench/run.py --baseline PATH`, e.g. a worktree of main)
BASELINE_ENV = "LOTSEN_BENCH_BASELINE"
#: one viewer flood (tests/stack/test_live.py's case): 20 strangers flooding `plan` requests for
#: 20 s while the pilot's page arms and flies the short route's first turn; the helm's figures
#: from the run's log, printed as JSON by the checkout under test
FLOOD = """
import json, sys, tempfile
from pathlib import Path
from lotsen.stack.soak import FIRST_TURN_ROUTE, LivePlan, run_live
with tempfile.TemporaryDirectory(prefix="lotsen-bench-flood-") as work:
    r = run_live(LivePlan(config=Path(sys.argv[1]), idle_s=5.0, route=FIRST_TURN_ROUTE, flood_viewers=20,
                          flood_s=20.0), work)
print("FLOOD " + json.dumps({"ok": r.ok, "figures": r.figures, "failures": r.failures}, default=str))
"""


def _flood(code: Path, cache: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(code), "NUMBA_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-c", FLOOD, str(CONFIG)], env=env, capture_output=True, text=True,
                         timeout=600, cwd=code)
    line = next((ln for ln in out.stdout.splitlines() if ln.startswith("FLOOD ")), None)
    if line is None:
        return {"ok": False, "figures": {}, "failures": [(out.stdout + out.stderr)[-300:]]}
    import json

    return json.loads(line[len("FLOOD "):])


def _ratio(after: float | None, before: float | None) -> float | None:
    if after is None or before is None or before != before or after != after or before == 0:
        return None
    return round(after / before, 2)


def paired_rows(work: Path, baseline: Path | None, reps: int, idle_s: float, floods: int) -> list[dict]:
    """This checkout against `baseline` (None: this one alone) with one core kept busy the whole
    time (a `while True: pass` beside the run), alternating the two in the same minutes so both
    see the same machine: `reps` warm starts each (page time, then idle CPU per process over
    `idle_s`), and `floods` viewer floods each (the helm's largest ship_command gap). Figures:
    median over the starts for CPU and page, the largest gap over the floods."""
    codes = {"this": ROOT} if baseline is None else {"baseline": baseline, "this": ROOT}
    caches = {name: work / f"numba-{name}" for name in codes}
    for name, code in codes.items():  # the kernel caches: every measured start is warm
        d = work / f"paired-cold-{name}"
        d.mkdir()
        run = Run(d, caches[name], code)
        try:
            run.wait_page()
            run.wait_up()
        finally:
            run.stop()
    hog = _burners(1)
    cpu: dict[str, dict[str, list[float]]] = {n: {} for n in codes}
    page: dict[str, list[float]] = {n: [] for n in codes}
    gaps: dict[str, list[float]] = {n: [] for n in codes}
    hz: dict[str, list[float]] = {n: [] for n in codes}
    failures: dict[str, list[str]] = {n: [] for n in codes}
    try:
        order = list(codes)
        for i in range(reps):
            for name in (order if i % 2 == 0 else order[::-1]):
                d = work / f"paired-{name}-{i}"
                d.mkdir()
                run = Run(d, caches[name], codes[name])
                try:
                    page[name].append(run.wait_page())
                    run.wait_up()
                    time.sleep(5.0)  # past the planner worker's start, slow on a loaded machine
                    procs = _tree(run.proc.pid, run.roles)
                    used = _cpu_window(procs, idle_s)
                finally:
                    run.stop()
                per: dict[str, float] = {}
                for pid, role in procs.items():
                    per[role] = per.get(role, 0.0) + used[pid]  # the two multiprocessing helpers: one row
                per["whole run"] = sum(used.values())
                for role, value in per.items():
                    cpu[name].setdefault(role, []).append(value)
        for i in range(floods):
            for name in (order if i % 2 == 0 else order[::-1]):
                r = _flood(codes[name], caches[name])
                f = r.get("figures", {})
                if f.get("ship_command_max_gap_ms") is not None:
                    gaps[name].append(float(f["ship_command_max_gap_ms"]))
                    hz[name].append(float(f.get("ship_command_hz", float("nan"))))
                if not r.get("ok"):
                    failures[name].append("; ".join(map(str, r.get("failures", [])))[:150])
    finally:
        for h in hog:
            h.kill()
            h.wait()

    def med(xs: list[float]) -> float | None:
        return round(statistics.median(xs), 1) if xs else None

    rows: list[dict] = []
    base = "baseline" if baseline is not None else None
    table = "paired with one core busy: idle CPU per process, page, helm under a viewer flood"
    roles = [r for r in cpu["this"] if r != "whole run"] + ["whole run"]
    for role in roles:
        row = {"table": table, "figure": f"idle CPU % of one core: {role}"}
        if base:
            row["baseline"] = med(cpu[base].get(role, []))
        row["this"] = med(cpu["this"].get(role, []))
        if base:
            row["ratio"] = _ratio(row["this"], row["baseline"])
        if role == "whole run":
            row["target"] = "<= 12"
            row["pass"] = bool(row["this"] is not None and row["this"] <= 12.0)
        rows.append(row)
    for label, values, target, ok, digits in (
            ("page answers after start, s (median)", page, "<= 3", lambda v: v <= 3.0, 2),
            ("page answers after start, s (slowest)", page, "", None, 2),
            ("helm: largest ship_command gap under 20 flooding viewers, ms (worst run)", gaps, "<= 150",
             lambda v: v <= 150.0, 0),
            ("helm: ship_command rate under the flood, Hz (lowest run)", hz, ">= 9.5", lambda v: v >= 9.5, 2)):
        pick = max if "slowest" in label or "worst" in label else (min if "lowest" in label else statistics.median)
        row = {"table": table, "figure": label}
        for name in codes:
            row[name] = round(pick(values[name]), digits) if values[name] else None
        if base:
            row = {k: row[k] for k in ("table", "figure", "baseline", "this")}
            row["ratio"] = _ratio(row["this"], row["baseline"])
        if target:
            row["target"] = target
            row["pass"] = bool(row["this"] is not None and ok(row["this"]))
        rows.append(row)
    rows.append({"table": table, "figure": "runs", "baseline": f"{reps} starts, {floods} floods; {baseline}"
                 if base else None, "this": f"{reps} starts, {floods} floods; {ROOT}",
                 "failures": "; ".join(f"{n}: {x}" for n in codes for x in failures[n])[:300]})
    return rows


def run(quick: bool = False) -> list[dict]:
    idle_s = 10.0 if quick else 20.0
    rows: list[dict] = []
    baseline = os.environ.get(BASELINE_ENV)
    with tempfile.TemporaryDirectory(prefix="lotsen-bench-paired-") as tmp:
        rows += paired_rows(Path(tmp), Path(baseline).resolve() if baseline else None, 2 if quick else 4,
                            10.0 if quick else 15.0, 1 if quick else 2)
    with tempfile.TemporaryDirectory(prefix="lotsen-bench-footprint-") as tmp:
        cache = Path(tmp) / "numba-cache"
        cold, cold_row = _start(Path(tmp), cache, "cold (empty kernel cache)")
        cold.stop()
        cold_row["watchdog_events"] = cold.watchdog_events()
        warm_dir = Path(tmp) / "warm"
        warm_dir.mkdir()
        warm, warm_row = _start(warm_dir, cache, "warm (kernel cache present)")
        try:
            time.sleep(3.0)  # past the first console summary and the planner's warm-up
            procs = _tree(warm.proc.pid, warm.roles)
            for p in procs:
                _clear_referenced(p)  # what each process touches from now on: its working set
            idle_cpu = _cpu_window(procs, idle_s)
            mem_rows = []
            for pid, name in procs.items():
                cpu = idle_cpu[pid]
                mem_rows.append({"table": "memory and idle CPU per process", "process": name, "pid": pid,
                                 "rss_mb": round(_proc_kb(pid, "status", "VmRSS") / 1024, 1),
                                 "pss_mb": round(_proc_kb(pid, "smaps_rollup", "Pss") / 1024, 1),
                                 "working_set_mb": round(_proc_kb(pid, "smaps_rollup", "Referenced") / 1024, 1),
                                 "locked_mb": round(_proc_kb(pid, "smaps_rollup", "Locked") / 1024, 1),
                                 "vmlck_mb": round(_proc_kb(pid, "status", "VmLck") / 1024, 1),
                                 "cpu_idle_pct": round(cpu, 1)})
            pilot, mode = _go_auto(warm)
            try:
                procs = _tree(warm.proc.pid, warm.roles)  # the planner worker may have started
                auto_cpu = _cpu_window(procs, idle_s)
                still = (pilot.latest.get("sup") or {}).get("mode", "?")
            finally:
                pilot.close()
            for r in mem_rows:
                r["cpu_auto_pct"] = round(auto_cpu.get(r["pid"], float("nan")), 1)
            for pid, name in procs.items():
                if all(r["pid"] != pid for r in mem_rows):
                    mem_rows.append({"table": "memory and idle CPU per process", "process": name, "pid": pid,
                                     "cpu_auto_pct": round(auto_cpu[pid], 1)})
            auto_mode = mode if mode != "AUTO" else f"AUTO (at the end: {still})"
            warm_row["watchdog_events"] = warm.watchdog_events()
        finally:
            warm.stop()
        total = {k: round(sum(r[k] for r in mem_rows if r.get(k, float("nan")) == r.get(k, float("nan"))), 1)
                 for k in ("rss_mb", "pss_mb", "working_set_mb", "locked_mb", "vmlck_mb", "cpu_idle_pct",
                           "cpu_auto_pct")}
        core = next((r for r in mem_rows if r["process"] == "core"), {})
        target = ("total PSS <= 400 MB, core PSS <= 200 MB, locked <= 256 MB, idle CPU <= 12 %, "
                  "AUTO CPU <= 15 %")
        for r in mem_rows:
            r["target"] = target
        mem_rows.append({"table": "memory and idle CPU per process", "process": "whole run", **total,
                         "mode": auto_mode, "target": target,
                         "pass": bool(total["pss_mb"] <= 400 and core.get("pss_mb", 1e9) <= 200
                                      and total["locked_mb"] <= 256 and total["cpu_idle_pct"] <= 12
                                      and auto_mode.startswith("AUTO") and total["cpu_auto_pct"] <= 15)})
        cold_row["target"] = "(info: first start after install)"
        warm_row["target"] = "warm: page <= 3 s, control <= 5 s; no watchdog event"
        warm_row["pass"] = bool(warm_row["page_s"] <= 3.0 and warm_row["control_ready_s"] <= 5.0
                                and warm_row["watchdog_events"] == 0 and cold_row["watchdog_events"] == 0)
        rows += [cold_row, warm_row] + mem_rows
        for burners, starts in ((0, 3 if quick else 10), (2, 3 if quick else 20)):
            rows += repeated_start_rows(Path(tmp), cache, starts, burners)
    return rows + arm64_check_rows()
