"""Clocks. Nodes read time only from here, so the same code runs on simulated and wall time.

Two kinds of time:
- the run's clock (`now()`): simulated seconds, or monotonic wall seconds since the run's start.
  Every message is stamped with it. Processes of one run share it: the launcher passes its
  start (`WallClock.t0_monotonic`) to the others, and CLOCK_MONOTONIC is the same for every
  process of the machine.
- the work clock (`work()`): how long computations take (controller overrun monitor). On the
  boat the CPU's own time (perf_counter); in simulation it advances only when a node `charge`s
  it, so a simulated run never depends on how busy the machine running it is.
"""

from __future__ import annotations

import os
import time
from typing import Protocol

#: environment variable carrying the run's monotonic start to the processes of one run
CLOCK_ENV = "LOTSEN_CLOCK_T0"


class Clock(Protocol):
    def now(self) -> float:
        """Seconds since the start of the run."""
        ...

    def work(self) -> float:
        """A stopwatch for computation time (seconds, arbitrary origin)."""
        ...


class SimClock:
    """Simulated time, advanced only by the executor: deterministic and as fast as the CPU allows."""

    def __init__(self, t0: float = 0.0) -> None:
        self._t = t0
        self._work = 0.0

    def now(self) -> float:
        return self._t

    def set(self, t: float) -> None:
        self._t = t

    def work(self) -> float:
        return self._work

    def charge(self, seconds: float) -> None:
        """Declare simulated computation time (e.g. a fault scenario's slow controller)."""
        self._work += max(0.0, seconds)


class WallClock:
    """Monotonic wall time since the run's start (immune to NTP jumps); `epoch()` for file names.

    `t0_monotonic`: the run's start on CLOCK_MONOTONIC; default: the value in LOTSEN_CLOCK_T0 if a
    launcher set it (so every process of a run stamps on one time base), else now."""

    def __init__(self, t0_monotonic: float | None = None) -> None:
        if t0_monotonic is None:
            env = os.environ.get(CLOCK_ENV)
            t0_monotonic = float(env) if env else time.monotonic()
        self.t0_monotonic = t0_monotonic
        self.epoch_at_start = time.time() - (time.monotonic() - t0_monotonic)

    def now(self) -> float:
        return time.monotonic() - self.t0_monotonic

    def epoch(self) -> float:
        return self.epoch_at_start + self.now()

    def work(self) -> float:
        return time.perf_counter()
