"""The worker processes of the numerical commands (`identify --jobs`; `experiment design` runs on one core).

The algorithms never start a process (lotsen.sysid.parallel): the command makes the pool and hands its
`map` in. Workers are forked from the command after it has read its files and built the compiled
kernels, so each starts with numpy, scipy, CasADi and the kernels in place (a spawned worker imports
them again: 0.8 s of CPU each here, 3-4 s on a Raspberry Pi 4, measured in bench/bench_identify.py) and
with the one BLAS thread the command set before numpy's import (lotsen.cli.main.single_threaded_blas).
Forking is safe there: these commands run no thread of their own, and numba (whose threading layers do
not survive a fork) is not in use in them. Where fork is missing (macOS, Windows) they are spawned.
Workers ignore Ctrl-C: the command stops them.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
from contextlib import contextmanager
from typing import Callable, Iterator

from lotsen.settings import Number
from lotsen.sysid.parallel import SERIAL, Map

#: `--jobs`: worker processes (1: none, the command computes alone)
JOBS = Number(1, 64, "workers", integer=True)


def default_jobs() -> int:
    """The cores this process may run on: the default of --jobs."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def add_jobs_flag(parser: object, what: str) -> None:
    """`--jobs N` on a command's parser (argparse), validated like every number (lotsen.settings)."""
    parser.add_argument("--jobs", type=JOBS, default=None,  # type: ignore[attr-defined]
                        help=f"worker processes for {what} (default: the number of cores, here {default_jobs()}; "
                             "1: none). The answer is the same with any number")


def _ignore_interrupt() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def worker_pool(jobs: int | None, warm: Callable[[], None] | None = None) -> Iterator[Map]:
    """The map to hand the algorithms: the built-in one for a single job, else a pool of `jobs`
    processes (None: `default_jobs()`); `warm` runs here first (e.g. building the kernels), so that the
    workers inherit its result instead of each doing it again."""
    jobs = default_jobs() if jobs is None else int(jobs)
    if jobs <= 1:
        yield SERIAL
        return
    if warm is not None:
        warm()
    method = "fork" if "fork" in multiprocessing.get_all_start_methods() and sys.platform != "darwin" else "spawn"
    pool = multiprocessing.get_context(method).Pool(jobs, initializer=_ignore_interrupt)
    try:
        yield pool.map
        pool.close()
    finally:
        pool.terminate()
        pool.join()
