"""Replay a log on the bus at a chosen speed, so fusion or control can be re-run on recorded data.

`ReplayNode` is an ordinary runtime node: on `SimExecutor` it replays as fast as the CPU allows
(deterministically), on `RealtimeExecutor` at `speed` times wall pace. Messages are published on
their recorded topics in recording order, paced by their recorded receipt times (MCAP
log_time). With `restamp=True` each message's `stamp_s` is shifted by a constant so the first one
matches the replay clock at start (nodes that compare `stamp_s` with `ctx.now()` then see fresh
data); the spacing of stamps is kept as recorded.
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any, Iterable, Iterator

from lotsen.logs.reader import LogMessage, LogReader
from lotsen.runtime.executor import Node, NodeContext


class ReplayNode(Node):
    name = "replay"

    def __init__(self, path: str | os.PathLike, speed: float = 1.0, topics: Iterable[str] | None = None,
                 exclude: Iterable[str] = (), restamp: bool = False, period_s: float = 0.005,
                 loop: bool = False) -> None:
        if not (speed > 0 and math.isfinite(speed)):
            raise ValueError(f"replay speed must be > 0, got {speed}")
        self.reader = LogReader(path)
        self.speed = speed
        self.topics = frozenset(topics) if topics is not None else None
        self.exclude = frozenset(exclude)
        self.restamp = restamp
        self.period_s = period_s
        self.loop = loop
        self.published = 0
        self.finished = False
        self._it: Iterator[LogMessage] | None = None
        self._pending: LogMessage | None = None
        self._t0_log_ns = 0
        self._t0_clock = 0.0
        self._stamp_shift = 0.0

    def _open(self) -> None:
        self._it = self.reader.read(self.topics)
        self._pending = next(self._it, None)
        self._t0_clock = self.ctx.now()
        if self._pending is not None:
            self._t0_log_ns = self._pending.log_time_ns
            first_stamp = getattr(self._pending.message, "stamp_s", math.nan)
            self._stamp_shift = (self._t0_clock - first_stamp) if (self.restamp and math.isfinite(first_stamp)) else 0.0

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self._open()
        ctx.add_timer(self.period_s, self._tick)

    def _due(self, m: LogMessage) -> bool:
        return (m.log_time_ns - self._t0_log_ns) / 1e9 / self.speed <= self.ctx.now() - self._t0_clock + 1e-9

    def _tick(self) -> None:
        if self.finished:
            return
        while self._pending is not None and self._due(self._pending):
            m = self._pending
            if m.topic not in self.exclude:
                msg: Any = m.message
                if self._stamp_shift and hasattr(msg, "stamp_s"):
                    msg = dataclasses.replace(msg, stamp_s=msg.stamp_s + self._stamp_shift)
                self.ctx.publish(m.topic, msg)
                self.published += 1
            self._pending = next(self._it, None)  # type: ignore[arg-type]
        if self._pending is None:
            if self.loop:
                self._open()
            else:
                self.finished = True
                problems = "; ".join(str(p) for p in self.reader.problems)
                self.ctx.log("info" if not problems else "warning",
                             f"replay of {self.reader.path.name} finished: {self.published} messages"
                             + (f" ({problems})" if problems else ""))

    @property
    def duration_s(self) -> float:
        """Recorded duration (reads the file once)."""
        return self.reader.summary().duration_s
