"""Executors run nodes' timers. `SimExecutor` jumps from timer to timer on simulated time;
`RealtimeExecutor` runs the same timers at wall-clock pace in one thread, and accepts work from
other threads (web handlers) through `call_soon_threadsafe`, so node code is never re-entered
concurrently."""

from __future__ import annotations

import heapq
import itertools
import math
import os
import queue
import threading
from dataclasses import dataclass
from typing import Any, Callable

from lotsen.messages import LogEvent
from lotsen.runtime.bus import Bus
from lotsen.runtime.clock import Clock, SimClock, WallClock


@dataclass
class Timer:
    period_s: float
    callback: Callable[[], None]
    name: str
    next_t: float
    overruns: int = 0
    cancelled: bool = False

    def cancel(self) -> None:
        self.cancelled = True


class NodeContext:
    """What a node may touch: the bus, the clock, timers and the log."""

    def __init__(self, executor: "Executor", node_name: str) -> None:
        self.executor = executor
        self.bus: Bus = executor.bus
        self.clock: Clock = executor.clock
        self.node_name = node_name

    def now(self) -> float:
        return self.clock.now()

    def work(self) -> float:
        """The work clock (seconds): CPU time on the boat, charged time in simulation."""
        return self.clock.work()

    def add_timer(self, period_s: float, callback: Callable[[], None], phase_s: float = 0.0) -> Timer:
        return self.executor.add_timer(period_s, callback, f"{self.node_name}", phase_s)

    def publish(self, topic: str, msg: Any) -> None:
        self.bus.publish(topic, msg)

    def subscribe(self, topic: str, callback: Callable[[Any], None]) -> Callable[[], None]:
        return self.bus.subscribe(topic, callback)

    def log(self, level: str, text: str, **data: Any) -> None:
        self.bus.publish("log", LogEvent(stamp_s=self.clock.now(), level=level, source=self.node_name,
                                         text=text, data=data))

    def run_in_background(self, work: Callable[[], Any], done: Callable[[Any, BaseException | None], None]) -> None:
        """`work()` away from the node's timers, then `done(result, error)` back on the node's thread
        (error: what `work` raised, else None). For work too long for one control period (checking a
        survey's 78 000-point path); `work` must touch nothing the node changes meanwhile."""
        self.executor.run_in_background(work, done)


class Node:
    """Base class of runtime nodes: override `start` (subscribe, add timers) and maybe `stop`."""

    name = "node"

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx

    def stop(self) -> None:
        pass


class Executor:
    def __init__(self, bus: Bus | None = None, clock: Clock | None = None) -> None:
        self.bus = bus or Bus()
        self.clock: Clock = clock or SimClock()
        self._heap: list[tuple[float, int, Timer]] = []
        self._seq = itertools.count()
        self.nodes: list[Node] = []
        self.timer_errors = 0
        # one count for every callback this executor runs (subscribers, timers, external calls),
        # on its clock: reports of repeats are reproducible on simulated time
        self.errors = self.bus.stats.errors
        self.errors.clock = self.clock.now

    def add_node(self, node: Node) -> Node:
        self.nodes.append(node)
        node.start(NodeContext(self, node.name))
        return node

    def add_timer(self, period_s: float, callback: Callable[[], None], name: str = "", phase_s: float = 0.0) -> Timer:
        if not period_s > 0:
            raise ValueError(f"timer {name}: period must be > 0, got {period_s}")
        timer = Timer(period_s, callback, name, self._first_due(self.clock.now() + phase_s))
        heapq.heappush(self._heap, (timer.next_t, next(self._seq), timer))
        return timer

    def _first_due(self, t: float) -> float:
        """When a timer asked for at `t` first runs (the real-time loop puts it on its grid)."""
        return t

    def _run_timer(self, timer: Timer) -> None:
        try:
            timer.callback()
        except Exception as exc:  # a failing node must not stop the others; it is reported
            self.timer_errors += 1
            self._report(f"timer {timer.name or getattr(timer.callback, '__qualname__', '?')}", exc, timer.name)

    def run_in_background(self, work: Callable[[], Any], done: Callable[[Any, BaseException | None], None]) -> None:
        """Here (simulated time, and any executor without a thread of its own): at once, on this
        thread, so a simulated run stays deterministic and takes no simulated time for it."""
        try:
            result, error = work(), None
        except Exception as exc:  # noqa: BLE001 - handed to `done`, which decides
            result, error = None, exc
        done(result, error)

    def _report(self, where: str, exc: Exception, source: str) -> None:
        text = self.errors.record(where, "", exc)
        if text is not None:
            self.bus.publish("log", LogEvent(stamp_s=self.clock.now(), level="error", source=source or "executor",
                                             text=text, data={"callback_errors": self.errors.total}))

    def health(self) -> dict[str, int]:
        """Counts for health reports: callbacks that raised (all kinds), timers that raised, and
        timer periods skipped because the loop was late."""
        return {"callback_errors": self.errors.total, "timer_errors": self.timer_errors,
                "timer_overruns": sum(t.overruns for _, _, t in self._heap)}

    def _reschedule(self, timer: Timer, now: float) -> None:
        timer.next_t += timer.period_s
        if timer.next_t < now:  # behind schedule: skip missed periods rather than bursting
            missed = int((now - timer.next_t) / timer.period_s) + 1
            timer.overruns += missed
            timer.next_t += missed * timer.period_s
        heapq.heappush(self._heap, (timer.next_t, next(self._seq), timer))

    def shutdown(self) -> None:
        for node in reversed(self.nodes):
            try:
                node.stop()
            except Exception:  # noqa: BLE001 - shutting down: keep stopping the rest
                pass


class SimExecutor(Executor):
    """Deterministic: timers fire in time order (ties in creation order) on simulated time."""

    def __init__(self, bus: Bus | None = None) -> None:
        super().__init__(bus, SimClock())
        self.sim_clock: SimClock = self.clock  # type: ignore[assignment]
        self._pending: list[Callable[[], None]] = []

    def call_soon_threadsafe(self, fn: Callable[[], None]) -> None:
        self._pending.append(fn)

    def run_until(self, t_end: float, stop: Callable[[], bool] | None = None) -> None:
        while self._heap and self._heap[0][0] <= t_end + 1e-12:
            t, _, timer = heapq.heappop(self._heap)
            if timer.cancelled:
                continue
            self.sim_clock.set(t)
            while self._pending:
                self._pending.pop(0)()
            self._run_timer(timer)
            self._reschedule(timer, t)
            if stop is not None and stop():
                return
        self.sim_clock.set(max(self.sim_clock.now(), t_end))

    def run_for(self, duration_s: float, stop: Callable[[], bool] | None = None) -> None:
        self.run_until(self.clock.now() + duration_s, stop)


class BackgroundThread:
    """One thread for a real-time loop's long jobs, one below the loop in the scheduler.

    A new thread inherits its creator's policy: made from a loop at real-time priority (the core:
    SCHED_FIFO) it would have the loop's priority, and a FIFO peer on the loop's CPU is not
    preempted: the loop would wait for every job to block. It takes SCHED_RR one level below
    instead (as the core's other threads, `apply_core_priority`): the loop preempts it whenever it
    does not hold the interpreter lock, and nothing outside the core preempts it while it does."""

    def __init__(self, post: Callable[[Callable[[], None]], None], name: str = "loop-background") -> None:
        self._post = post
        self._jobs: queue.SimpleQueue[tuple[Callable[[], Any], Callable[[Any, BaseException | None], None]] | None] = \
            queue.SimpleQueue()
        self._policy = _scheduling_of_this_thread()
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    def submit(self, work: Callable[[], Any], done: Callable[[Any, BaseException | None], None]) -> None:
        self._jobs.put((work, done))

    def close(self) -> None:
        self._jobs.put(None)

    def _serve(self) -> None:
        _below(self._policy)
        while (job := self._jobs.get()) is not None:
            work, done = job
            try:
                result, error = work(), None
            except Exception as exc:  # noqa: BLE001 - handed to `done` on the loop's thread
                result, error = None, exc
            self._post(lambda done=done, result=result, error=error: done(result, error))


def _scheduling_of_this_thread() -> tuple[int, int] | None:
    try:
        return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    except (AttributeError, OSError):
        return None


def _below(policy: tuple[int, int] | None) -> None:
    """This thread one real-time level below `policy` (its creator's), or as it is when that was not real-time."""
    if policy is None or policy[0] not in (getattr(os, "SCHED_FIFO", -1), getattr(os, "SCHED_RR", -1)):
        return
    try:
        if policy[1] > 1:
            os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(policy[1] - 1))
        else:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (AttributeError, PermissionError, OSError):
        pass


#: the longest the real-time loop sleeps when no timer is due sooner (it wakes at once for calls)
IDLE_WAIT_S = 1.0
#: the real-time loop's timer grid (s): a timer's first run is put on the next grid point, so
#: timers whose periods are multiples of it fall due together and run in one wake-up (the core's
#: 100 Hz boat, 20 Hz fusion, 10 Hz supervisor and bridge: 100 wake-ups a second, not 150)
TIMER_GRID_S = 0.01


def on_grid(t: float, grid_s: float) -> float:
    """The first point of the grid k * grid_s at or after `t` (a hair of rounding allowed)."""
    k = math.ceil(t / grid_s - 1e-9)
    return k * grid_s


class RealtimeExecutor(Executor):
    """Wall-clock pace, one thread."""

    def __init__(self, bus: Bus | None = None, clock: WallClock | None = None) -> None:
        super().__init__(bus, clock or WallClock())
        self._calls: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._stop = threading.Event()
        self.grid_s = TIMER_GRID_S
        #: when the loop last finished a timer (clock seconds): a watchdog's proof of life
        self.beat_s = -math.inf
        self._background: BackgroundThread | None = None

    def call_soon_threadsafe(self, fn: Callable[[], None]) -> None:
        self._calls.put(fn)

    def run_in_background(self, work: Callable[[], Any], done: Callable[[Any, BaseException | None], None]) -> None:
        """`work()` on this executor's background thread (one, started on first use; jobs in
        order), `done(result, error)` then on the loop's thread, between timers."""
        if self._background is None:
            self._background = BackgroundThread(self.call_soon_threadsafe)
        self._background.submit(work, done)

    def _first_due(self, t: float) -> float:
        return on_grid(t, self.grid_s)

    def stop(self) -> None:
        self._stop.set()
        self._calls.put(lambda: None)
        if self._background is not None:
            self._background.close()

    @property
    def stopping(self) -> bool:
        """Told to stop: the loop is finishing (its nodes closing), so its silence is no stall."""
        return self._stop.is_set()

    def _call(self, fn: Callable[[], None]) -> None:
        try:
            fn()
        except Exception as exc:  # a web handler's call must not stop the loop; it is reported
            self._report(f"external call {getattr(fn, '__qualname__', '?')}", exc, "executor")

    def _drain_calls(self) -> None:
        while True:
            try:
                fn = self._calls.get_nowait()
            except queue.Empty:
                return
            self._call(fn)

    def run(self, duration_s: float | None = None) -> None:
        end = None if duration_s is None else self.clock.now() + duration_s
        while not self._stop.is_set():
            now = self.clock.now()
            if end is not None and now >= end:
                break
            self._drain_calls()
            t_next = self._heap[0][0] if self._heap else now + IDLE_WAIT_S
            if t_next > now:
                # sleep until the next timer (or the end), but wake for external calls: stop()
                # and call_soon_threadsafe put one, so no polling in between
                wait = min(t_next - now, IDLE_WAIT_S) if end is None else max(0.0, min(t_next, end) - now)
                try:
                    fn = self._calls.get(timeout=wait)
                except queue.Empty:
                    continue
                # run it now: putting it back would queue it behind calls that arrived later
                # (a route followed by "auto" would arrive as "auto", then the route)
                self._call(fn)
                continue
            _, _, timer = heapq.heappop(self._heap)
            if timer.cancelled:
                continue
            self._run_timer(timer)
            now = self.clock.now()
            self.beat_s = now
            self._reschedule(timer, now)
        self.shutdown()
