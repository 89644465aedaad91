"""Token buckets: per-connection limits on control messages."""

from __future__ import annotations

from typing import Callable


class TokenBucket:
    """`rate_per_s` tokens per second, at most `burst` stored; `take()` is False when empty."""

    def __init__(self, rate_per_s: float, burst: float, clock: Callable[[], float]) -> None:
        self.rate = rate_per_s
        self.burst = burst
        self._clock = clock
        self._tokens = burst
        self._t = clock()

    def _refill(self) -> None:
        now = self._clock()
        self._tokens = min(self.burst, self._tokens + (now - self._t) * self.rate)
        self._t = now

    def available(self, n: float = 1.0) -> bool:
        """Whether `take(n)` would succeed now (nothing is taken)."""
        self._refill()
        return self._tokens >= n

    def take(self, n: float = 1.0) -> bool:
        self._refill()
        if self._tokens >= n:
            self._tokens -= n
            return True
        return False


#: message kind -> (rate per second, burst). Manual driving is sent at 10 Hz while keys are held.
DEFAULT_LIMITS: dict[str, tuple[float, float]] = {
    "manual": (30.0, 30.0),
    "ping": (20.0, 20.0),
    "other": (5.0, 10.0),
}


class RateLimiter:
    def __init__(self, clock: Callable[[], float], limits: dict[str, tuple[float, float]] | None = None) -> None:
        self._buckets = {k: TokenBucket(r, b, clock) for k, (r, b) in (limits or DEFAULT_LIMITS).items()}

    def allow(self, kind: str) -> bool:
        bucket = self._buckets.get(kind) or self._buckets["other"]
        return bucket.take()
