"""Clocks. Nodes read time only from here, so the same code runs on simulated and wall time."""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    def now(self) -> float:
        """Seconds since the start of the run."""
        ...


class SimClock:
    """Simulated time, advanced only by the executor: deterministic and as fast as the CPU allows."""

    def __init__(self, t0: float = 0.0) -> None:
        self._t = t0

    def now(self) -> float:
        return self._t

    def set(self, t: float) -> None:
        self._t = t


class WallClock:
    """Monotonic wall time since start (immune to NTP jumps); `epoch()` for file names and logs."""

    def __init__(self) -> None:
        self._t0 = time.monotonic()
        self.epoch_at_start = time.time()

    def now(self) -> float:
        return time.monotonic() - self._t0

    def epoch(self) -> float:
        return self.epoch_at_start + self.now()
