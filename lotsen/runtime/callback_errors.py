"""Errors raised by callbacks the runtime calls (bus subscribers, timers, calls from other
threads): counted, and logged once per distinct error, then at most once per `period_s` with
the number of repeats, so a callback failing at 50 Hz neither hides nor floods the log.

A distinct error is one callback failing with one exception type on one topic (the message text
may differ from call to call, e.g. a value in it). `total` is what health reports show (the
console summary of a run; `Executor.health`)."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable


@dataclass
class _Seen:
    count: int = 0
    reported: int = 0
    last_report_s: float = 0.0


@dataclass
class CallbackErrors:
    period_s: float = 10.0
    clock: Callable[[], float] = time.monotonic  # the executor's clock (simulated time: reproducible logs)
    total: int = 0
    last_error: str = ""
    _seen: dict[tuple[str, str, str], _Seen] = field(default_factory=dict)

    def record(self, where: str, topic: str, exc: BaseException) -> str | None:
        """Count one error; the text to log now, or None (a repeat within `period_s`)."""
        self.total += 1
        text = f"{where}{' on ' + topic if topic else ''} failed: {exc!r}"
        self.last_error = text
        key = (where, topic, type(exc).__name__)
        seen = self._seen.get(key)
        now = self.clock()
        if seen is None:
            self._seen[key] = _Seen(count=1, reported=1, last_report_s=now)
            return text
        seen.count += 1
        if now - seen.last_report_s < self.period_s:
            return None
        repeats = seen.count - seen.reported
        seen.reported, seen.last_report_s = seen.count, now
        return f"{text} (again: {repeats} times since the last report, {seen.count} in all)"

    @property
    def distinct(self) -> int:
        return len(self._seen)

    def summary(self) -> str:
        """'' without errors, else e.g. "callback errors: 37 (2 distinct; last: ...)"."""
        if not self.total:
            return ""
        return f"callback errors: {self.total} ({self.distinct} distinct; last: {self.last_error})"
