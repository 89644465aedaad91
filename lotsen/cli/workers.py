"""The worker processes of the numerical commands (`identify --jobs`; `experiment design` runs on one core).

The algorithms never start a process (lotsen.sysid.parallel): the command starts the workers and hands in
a `map` that runs on the command's own process and its `jobs` - 1 workers (`_SharedMap`). Workers
are forked from the command after it has read its files and built the compiled kernels, so each starts
with numpy, scipy, CasADi and the kernels in place (a spawned worker imports them again: 0.8 s of CPU
each here, 3-4 s on a Raspberry Pi 4, measured in bench/bench_identify.py) and with the one BLAS thread
the command set before numpy's import (lotsen.cli.main.single_threaded_blas). Forking is safe there:
these commands run no thread of their own, and numba (whose threading layers do not survive a fork) is
not in use in them. Where fork is missing (macOS, Windows) they are spawned. Workers ignore Ctrl-C: the
command stops them.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
from contextlib import contextmanager
from typing import Any, Callable, Iterable, Iterator, Sequence, TypeVar

from lotsen.settings import Number
from lotsen.sysid.parallel import SERIAL, Map

T = TypeVar("T")

#: `--jobs`: processes that compute, the command's own and `jobs` - 1 workers (1: the command alone)
JOBS = Number(1, 64, "processes", integer=True)


def default_jobs() -> int:
    """The cores this process may run on: the default of --jobs."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def add_jobs_flag(parser: object, what: str) -> None:
    """`--jobs N` on a command's parser (argparse), validated like every number (lotsen.settings)."""
    parser.add_argument("--jobs", type=JOBS, default=None,  # type: ignore[attr-defined]
                        help=f"processes computing {what}: this one and N - 1 workers (default: the number of "
                             f"cores, here {default_jobs()}; 1: this one alone). The answer is the same with any "
                             "number")


#: glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3


def keep_freed_memory() -> bool:
    """Let this process (and the workers forked from it) keep the memory it frees for its next arrays.

    The estimators allocate and free arrays of 1-30 MB thousands of times (the equation error's
    regressors of a 10-min lake record: ~2000 solves). glibc hands such blocks back to the kernel (a
    freed top of the heap above the trim threshold, or a block above the mmap threshold, which it moves
    with each free) and takes them again page by page: measured on the lake record 2500, 1.0 million
    page faults and 2.2 s of system CPU on 10.7 s of user CPU (main's code 50 thousand, 0.3 s: it kept
    one more array alive, by chance). With blocks up to 32 MB from the heap and the heap kept: 20
    thousand, 0.1 s. Numbers are unchanged; the process's resident memory stays at its peak until it
    ends (a command, not the boat's long-running stack). Elsewhere than glibc: nothing (False)."""
    import ctypes
    import ctypes.util

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        return bool(libc.mallopt(_M_MMAP_THRESHOLD, 32 * 1024 * 1024)) and bool(
            libc.mallopt(_M_TRIM_THRESHOLD, 1024 * 1024 * 1024))
    except (OSError, AttributeError):  # musl and others: no mallopt
        return False


def _ignore_interrupt() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def worker_pool(jobs: int | None, warm: Callable[[], None] | None = None) -> Iterator[Map]:
    """The map to hand the algorithms: the built-in one for a single job, else `jobs` processes that
    compute, this one and `jobs` - 1 workers (None: `default_jobs()`; `_SharedMap`); `warm` runs here
    first (e.g. building the kernels), so that the workers inherit its result instead of each doing it
    again."""
    jobs = default_jobs() if jobs is None else int(jobs)
    if jobs <= 1:
        yield SERIAL
        return
    if warm is not None:
        warm()
    ctx = multiprocessing.get_context("fork" if _can_fork() else "spawn")
    workers: list[tuple[Any, Any]] = []
    try:
        for _ in range(jobs - 1):
            mine, theirs = ctx.Pipe()
            # the command's ends (this worker's and the earlier ones') closed in the worker: each worker
            # then reads the end of its pipe when the command closes its end, and returns
            ours = [conn for _, conn in workers] + [mine]
            proc = ctx.Process(target=_serve, args=(theirs, ours), daemon=True)
            proc.start()
            theirs.close()  # the worker's end: a worker that dies closes the pipe (EOFError here, no hang)
            workers.append((proc, mine))
        yield _SharedMap([conn for _, conn in workers], jobs)
    except BaseException:
        for proc, _ in workers:  # interrupted or failed: a worker may still be computing, stopped now
            proc.terminate()
        raise
    finally:
        for _, conn in workers:
            conn.close()
        for proc, _ in workers:
            proc.join(2.0)
            if proc.is_alive():
                proc.terminate()
                proc.join()


def _serve(conn: Any, commands_ends: list[Any]) -> None:
    """A worker: (function, items) in, (True, [function(x) for x in items]) or (False, exception) out,
    until the command closes the pipe."""
    _ignore_interrupt()
    for end in commands_ends:
        end.close()
    while True:
        try:
            function, items = conn.recv()
        except (EOFError, OSError):
            return
        try:
            answer: tuple[bool, Any] = (True, [function(x) for x in items])
        except BaseException as exc:  # noqa: BLE001 - raised in the command, as the built-in map would
            answer = (False, exc)
        try:
            conn.send(answer)
        except (BrokenPipeError, EOFError, OSError):
            return
        except Exception as exc:  # noqa: BLE001 - an answer that does not pickle: said in words
            conn.send((False, RuntimeError(f"a worker's answer could not be sent back: {exc}")))


class _SharedMap:
    """`map(function, items)` on this process and the workers: the first ceil(len(items) / jobs) items
    here, the rest on the workers in contiguous shares, sent before this process starts on its own. This
    process would only wait while the workers compute: computing a share itself saves a worker (its
    memory, its copies of the held values and caches: the equation error's filtered regressors are this
    process's own) and the sending of that share's arguments and results. The split is by position, so a
    worker gets the same items (the same held shooting blocks) call after call. Each worker gets its
    share in one message on its own pipe and answers on it: no pool's threads between (they took the
    interpreter's lock from this process's share to pass each task on: ~1.5 ms a call, ~200 calls)."""

    def __init__(self, conns: list[Any], jobs: int) -> None:
        self.conns = conns
        self.jobs = jobs

    def __call__(self, function: Callable[[Any], Any], items: Iterable[Any]) -> list[Any]:
        items = list(items)
        mine = -(-len(items) // self.jobs)  # the larger share here: a worker's also waits for its pipe
        rest, k = items[mine:], len(self.conns)
        edges = [mine + (len(rest) * i) // k for i in range(k + 1)]
        sent = []
        try:
            for conn, a, b in zip(self.conns, edges[:-1], edges[1:]):
                if b > a:
                    conn.send((function, items[a:b]))
                    sent.append(conn)
            here = [function(x) for x in items[:mine]]
        finally:
            answers = [self._answer(conn) for conn in sent]  # no task of this call left on a worker
        out = here
        for ok, value in answers:
            if not ok:
                raise value
            out += value
        return out

    @staticmethod
    def _answer(conn: Any) -> tuple[bool, Any]:
        try:
            return conn.recv()
        except (EOFError, OSError):
            return False, RuntimeError("a worker process ended without an answer (killed, or out of memory?)")


def _can_fork() -> bool:
    """Whether worker processes can be forked here (not on macOS, where forking after numpy's and the
    system's threads have started is unsafe)."""
    return "fork" in multiprocessing.get_all_start_methods() and sys.platform != "darwin"


@contextmanager
def side_tasks(jobs: int | None, soon: Sequence[Callable[[], Any]],
               later: Sequence[Callable[[], Any]] = ()) -> Iterator[list[Callable[[], Any]]]:
    """Values that depend on the data alone and are needed only later (the prediction windows, the
    record's sea state), computed beside the computation; yields a getter for each, `soon` then `later`.
    With several jobs they run in order in a process forked now: `soon` at the priority of the computing
    processes (it takes one of their cores for a moment, and takes its work off the command's serial
    path), then `later` at a lower one (LATER_NICENESS: mostly in the gaps the computing processes leave,
    their serial stretches). A getter takes the answer if it has come, else computes the
    task here (a machine too busy to leave the side process any time is no slower than without it). With
    one job (or without fork) each is computed here when asked for. The same value either way; an
    exception is raised as if the task were called here."""
    tasks = [*soon, *later]
    jobs = default_jobs() if jobs is None else int(jobs)
    if jobs <= 1 or not _can_fork():
        yield [_once(task) for task in tasks]
        return
    ctx = multiprocessing.get_context("fork")
    pipes = [ctx.Pipe(duplex=False) for _ in tasks]  # one a task: a large answer waits for its reader alone
    proc = ctx.Process(target=_run_side, args=([send for _, send in pipes], tasks, len(soon)), daemon=True)
    proc.start()
    for _, send in pipes:
        send.close()  # the child's ends: a child that dies unheard closes them (EOFError, not a wait)

    def getter(i: int) -> Callable[[], Any]:
        local, receive, come = _once(tasks[i]), pipes[i][0], []

        def get() -> Any:
            try:
                if not come and receive.poll(0):  # come, or on its way: read; else not waited for
                    come.append(receive.recv())
            except (EOFError, OSError):
                pass
            if not come:
                return local()
            ok, value = come[0]
            if not ok:
                raise value
            return value

        return get

    try:
        yield [getter(i) for i in range(len(tasks))]
    finally:
        for receive, _ in pipes:
            receive.close()
        if proc.is_alive():
            proc.terminate()
        proc.join()


def _once(task: Callable[[], T]) -> Callable[[], T]:
    """The task computed at the first call, its value kept."""
    kept: list[T] = []

    def get() -> T:
        if not kept:
            kept.append(task())
        return kept[0]

    return get


def _run_side(sends: list[Any], tasks: list[Callable[[], Any]], soon: int) -> None:
    """In the side process: each task's answer (or exception) sent back on its own pipe as it is done, by
    a thread of its own (a large answer waits there until the command reads it, the next task goes on);
    the tasks from `soon` on at a lower priority; never raised here."""
    import threading

    _ignore_interrupt()
    senders = []
    for i, (task, send) in enumerate(zip(tasks, sends)):
        if i == soon:
            _lower_priority()
        try:
            answer: tuple[bool, Any] = (True, task())
        except BaseException as exc:  # noqa: BLE001 - handed to the command, which raises it
            answer = (False, exc)
        senders.append(threading.Thread(target=_send_answer, args=(send, answer), daemon=True))
        senders[-1].start()
    for t in senders:
        t.join()


#: the niceness of the side tasks wanted late: about a tenth of a core the computing processes want, so
#: they finish within a 10-min identification (SCHED_IDLE got none on a busy machine), and all of an idle one
LATER_NICENESS = 10


def _lower_priority() -> None:
    try:
        os.nice(LATER_NICENESS)
    except OSError:
        pass


def _send_answer(send: Any, answer: tuple[bool, Any]) -> None:
    try:
        send.send(answer)
    except Exception:  # noqa: BLE001 - the command has ended, or the answer does not pickle: it computes it
        pass
    finally:
        send.close()
