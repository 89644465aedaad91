"""The planner worker: planning requests run in their own OS process with a time and a memory
budget, so no route, however hostile, can starve the web server or the control core.

One worker process serves one request at a time (requests queue up to `max_pending`; beyond
that they are refused at once: "busy"). The process runs with an address-space limit
(RLIMIT_AS = `memory_mb`); a request that runs out of memory is refused, and one that uses more
than `time_s` of CPU time is refused and its worker killed and replaced. The budget is CPU time,
not wall time, because the worker runs niced: on a machine the control core (or anything else)
keeps busy a legitimate plan gets a fraction of a core, and a wall-time budget refused it for the
machine's load, not the route's cost. A job that does not finish in `WALL_FACTOR` x its budget of
wall time (stuck, or a machine so busy it gets almost nothing) is stopped as well. Functions and
arguments cross the process boundary by pickling: module-level functions and plain data only.

    worker = PlannerWorker(PlanningBudget())
    result = await worker.run(plan_for_display, route_dict, planner_config)
"""

from __future__ import annotations

import asyncio
import multiprocessing as mp
import os
import threading
import time
from typing import Any, Callable

from lotsen.errors import LotsenError, PlanningError
from lotsen.planning.budget import PlanningBudget, check_budget
from lotsen.planning.io import route_from_dict
from lotsen.runtime.lifetime import die_with_parent, process_cpu_seconds


def _within_budget(args: tuple, budget: PlanningBudget) -> None:
    """Every job whose first argument is a route (plan, upload, export) is checked against the
    budget's size bounds before any planning work; a route that does not even parse is left to
    the job, which reports it with its location."""
    if args and isinstance(args[0], dict) and "nodes" in args[0]:
        try:
            route = route_from_dict(args[0])
        except LotsenError:
            return
        check_budget(route, budget)


def _serve(conn: Any, budget: PlanningBudget, parent_pid: int | None = None) -> None:
    """The worker's loop (in the child process); it ends with the process that started it (that
    process may have started it from a short-lived thread: no parent-death signal, the watcher)."""
    import resource

    if parent_pid is not None:
        die_with_parent(parent_pid, parent_death_signal=False)

    try:  # a background job: the web server that waits for it must stay responsive
        os.nice(10)
    except OSError:
        pass
    limit = int(budget.memory_mb * 1024 * 1024)
    try:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    except (ValueError, OSError):  # an OS without the limit: the time budget still applies
        pass
    conn.send(("ready", None))  # the time budget counts from here, not from the interpreter's start-up
    while True:
        try:
            job = conn.recv()
        except (EOFError, OSError):
            return
        if job is None:
            return
        fn, args = job
        try:
            _within_budget(args, budget)
            conn.send(("ok", fn(*args)))
        except MemoryError:
            conn.send(("memory", ""))
        except LotsenError as exc:
            conn.send(("lotsen", (type(exc).__name__, str(exc))))
        except Exception as exc:  # noqa: BLE001 - a planner bug is reported, the worker lives on
            conn.send(("error", f"{type(exc).__name__}: {exc}"[:500]))


#: a job is stopped after this many times its CPU budget in wall time, whatever CPU it got
WALL_FACTOR = 5.0
_POLL_S = 0.05


class PlannerWorker:
    def __init__(self, budget: PlanningBudget = PlanningBudget(), max_pending: int = 8) -> None:
        self.budget = budget
        self.max_pending = max_pending
        self._ctx = mp.get_context("spawn")
        self.start_timeout_s = 60.0
        self._lock = threading.Lock()
        self._pending = 0
        self._proc: Any = None
        self._conn: Any = None
        self.stats = {"done": 0, "refused_busy": 0, "timeouts": 0, "out_of_memory": 0, "restarts": 0}

    def _start(self) -> None:
        parent, child = self._ctx.Pipe()
        env_before = os.environ.get("OPENBLAS_NUM_THREADS")
        os.environ["OPENBLAS_NUM_THREADS"] = "1"  # one BLAS thread: less address space, no CPU fight
        try:
            self._proc = self._ctx.Process(target=_serve, args=(child, self.budget, os.getpid()), daemon=True,
                                           name="lotsen-planner")
            self._proc.start()
        finally:
            if env_before is None:
                os.environ.pop("OPENBLAS_NUM_THREADS", None)
            else:
                os.environ["OPENBLAS_NUM_THREADS"] = env_before
        child.close()
        self._conn = parent
        if not parent.poll(self.start_timeout_s):
            self._kill()
            raise PlanningError(f"the planner worker did not start within {self.start_timeout_s:g} s")
        try:
            parent.recv()
        except (EOFError, OSError):
            self._kill()
            raise PlanningError("the planner worker ended while starting") from None

    def _kill(self) -> None:
        if self._proc is not None:
            self._proc.kill()
            self._proc.join(2.0)
        if self._conn is not None:
            self._conn.close()
        self._proc = self._conn = None
        self.stats["restarts"] += 1

    def warm(self) -> None:
        """Start the worker process now (its interpreter start-up is seconds on a Pi), so the
        operator's first plan does not pay for it."""
        with self._lock:
            if self._proc is None or not self._proc.is_alive():
                self._start()

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Run fn(*args) in the worker (blocking); PlanningError when over budget (CPU time, or
        `WALL_FACTOR` x that in wall time) or busy. A job that names its own budget (`fn.budget_key`,
        a field of PlanningBudget: `predict_time_s`) gets that."""
        key = getattr(fn, "budget_key", "time_s")
        limit = float(getattr(self.budget, key))
        with self._lock:
            if self._proc is None or not self._proc.is_alive():
                self._start()
            conn = self._conn
            pid = self._proc.pid
            cpu_0, wall_0 = process_cpu_seconds(pid), time.monotonic()
            conn.send((fn, args))
            while not conn.poll(_POLL_S):
                wall = time.monotonic() - wall_0
                cpu_now = process_cpu_seconds(pid)
                # no /proc: wall time stands in for CPU time (the stricter measure)
                cpu = wall if cpu_0 is None or cpu_now is None else cpu_now - cpu_0
                if cpu > limit:
                    why = f"{limit:g} s of CPU time and was stopped (extra.planning.{key}); simplify the route"
                elif wall > WALL_FACTOR * limit:
                    why = (f"{limit:g} s: {wall:.0f} s of wall time with {cpu:.1f} s of CPU (the machine is too "
                           f"busy, or the job is stuck) and was stopped (extra.planning.{key})")
                else:
                    continue
                self.stats["timeouts"] += 1
                self._kill()
                raise PlanningError(f"planning took longer than its budget of {why}")
            try:
                kind, value = conn.recv()
            except (EOFError, OSError):
                self._kill()
                raise PlanningError("the planner worker died while planning (out of memory?)") from None
        self.stats["done"] += 1
        if kind == "ok":
            return value
        if kind == "memory":
            self.stats["out_of_memory"] += 1
            raise PlanningError(f"planning needed more than its memory budget of {self.budget.memory_mb:g} MB "
                                "(extra.planning.memory_mb); simplify the route")
        if kind == "lotsen":
            raise PlanningError(value[1])
        raise PlanningError(f"planner failed: {value}")

    async def run(self, fn: Callable[..., Any], *args: Any) -> Any:
        """`call` from an event loop (the web server's `run_blocking`)."""
        if self._pending >= self.max_pending:
            self.stats["refused_busy"] += 1
            raise PlanningError(f"the planner is busy ({self._pending} requests waiting); try again in a moment")
        self._pending += 1
        try:
            return await asyncio.to_thread(self.call, fn, *args)
        finally:
            self._pending -= 1

    def close(self) -> None:
        with self._lock:
            if self._conn is not None:
                try:
                    self._conn.send(None)
                except OSError:
                    pass
            if self._proc is not None and self._proc.pid is not None:  # (a start that failed left no process)
                self._proc.join(1.0)
                if self._proc.is_alive():
                    self._proc.kill()
            self._proc = self._conn = None
