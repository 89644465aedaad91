"""In-process publish/subscribe bus.

Delivery is synchronous and in subscription order, so a simulated run is deterministic. A
subscriber that raises is isolated: the error is counted and reported on the `log` topic (once per
distinct error, then repeats at most every 10 s: `CallbackErrors`), and the other subscribers
still get the message (a bad message never takes a node down). Threads (web
server, drivers) read through `BoundedQueue`s, which drop the oldest message when full, so a slow
consumer never blocks the control loop.
"""

from __future__ import annotations

import threading
from collections import defaultdict, deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from lotsen.runtime.callback_errors import CallbackErrors

Callback = Callable[[Any], None]
AnyCallback = Callable[[str, Any], None]


class BoundedQueue:
    """Thread-safe FIFO of (topic, message) with drop-oldest overflow."""

    def __init__(self, maxlen: int = 256) -> None:
        self._q: deque[tuple[str, Any]] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self._ready = threading.Condition(self._lock)
        self.dropped = 0

    def put(self, topic: str, msg: Any) -> None:
        with self._lock:
            if len(self._q) == self._q.maxlen:
                self.dropped += 1
            self._q.append((topic, msg))
            self._ready.notify()

    def put_many(self, items: list[tuple[str, Any]]) -> None:
        """`put` of each (topic, message), with one lock and one wake-up for the lot."""
        if not items:
            return
        with self._lock:
            room = self._q.maxlen - len(self._q) if self._q.maxlen is not None else len(items)
            self.dropped += max(0, len(items) - room)
            self._q.extend(items)
            self._ready.notify()

    def get_all(self) -> list[tuple[str, Any]]:
        with self._lock:
            items = list(self._q)
            self._q.clear()
            return items

    def get(self, timeout: float | None = None) -> tuple[str, Any] | None:
        with self._lock:
            if not self._q and not self._ready.wait_for(lambda: bool(self._q), timeout):
                return None
            return self._q.popleft()

    def __len__(self) -> int:
        with self._lock:
            return len(self._q)


@dataclass
class BusStats:
    published: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    errors: CallbackErrors = field(default_factory=CallbackErrors)

    @property
    def callback_errors(self) -> int:
        return self.errors.total

    @property
    def last_error(self) -> str:
        return self.errors.last_error


class Bus:
    def __init__(self) -> None:
        self._subs: dict[str, list[Callback]] = defaultdict(list)
        self._all: list[AnyCallback] = []
        self._queues: list[tuple[frozenset[str] | None, BoundedQueue]] = []
        self.stats = BusStats()
        self._reporting = False
        self.latest: dict[str, Any] = {}  # last message per topic: status views, late joiners

    def subscribe(self, topic: str, callback: Callback) -> Callable[[], None]:
        self._subs[topic].append(callback)
        return lambda: self._subs[topic].remove(callback)

    def subscribed_topics(self) -> frozenset[str]:
        """The topics that have a subscriber of their own (`subscribe`, `queue` with topics)."""
        queued = {t for topics, _ in self._queues if topics is not None for t in topics}
        return frozenset(t for t, cbs in self._subs.items() if cbs) | queued

    def subscribe_all(self, callback: AnyCallback) -> Callable[[], None]:
        """Every message of every topic (recorders, bridges)."""
        self._all.append(callback)
        return lambda: self._all.remove(callback)

    def queue(self, topics: Iterable[str] | None = None, maxlen: int = 256) -> BoundedQueue:
        """A queue receiving `topics` (all if None) for another thread."""
        q = BoundedQueue(maxlen)
        self._queues.append((frozenset(topics) if topics is not None else None, q))
        return q

    def remove_queue(self, q: BoundedQueue) -> None:
        self._queues = [(t, qq) for t, qq in self._queues if qq is not q]

    def publish(self, topic: str, msg: Any) -> None:
        self.stats.published[topic] += 1
        self.latest[topic] = msg
        for cb in tuple(self._subs.get(topic, ())):
            self._call(cb, topic, msg, single=True)
        for acb in tuple(self._all):
            self._call(acb, topic, msg, single=False)
        for topics, q in self._queues:
            if topics is None or topic in topics:
                q.put(topic, msg)

    def _call(self, cb: Any, topic: str, msg: Any, single: bool) -> None:
        try:
            if single:
                cb(msg)
            else:
                cb(topic, msg)
        except Exception as exc:  # isolate subscribers: count, report, carry on
            text = self.stats.errors.record(f"subscriber {getattr(cb, '__qualname__', cb)}", topic, exc)
            if text is not None and not self._reporting and topic != "log":
                self._reporting = True
                try:
                    from lotsen.messages import LogEvent

                    stamp = getattr(msg, "stamp_s", float("nan"))
                    self.publish("log", LogEvent(stamp_s=stamp, level="error", source="bus", text=text))
                finally:
                    self._reporting = False
