"""Pilot authentication and the single pilot seat.

Rules (docs/web.md, "Access"):
- Anyone who can reach the server may watch. Control needs the pilot token, sent in the
  WebSocket's `auth` message (never in a URL, never logged), compared in constant time.
- One pilot at a time. A second `auth` is refused while the seat is held by a connection that
  was heard within `link_timeout_s`.
- The pilot leaves the seat by `release` or by closing the socket. A pilot that is still
  connected but silent for longer than `link_timeout_s` (a frozen tab, a half-open Wi-Fi link)
  can be replaced by `auth` with `takeover: true`; the old connection is told it lost the seat.
- After `MAX_AUTH_FAILURES` wrong tokens the connection is closed (no online guessing).
"""

from __future__ import annotations

import hmac
from dataclasses import dataclass
from typing import Callable


MAX_AUTH_FAILURES = 5


class AuthError(Exception):
    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


def token_matches(given: str, expected: str) -> bool:
    """Constant-time comparison (hmac.compare_digest on bytes: no early exit, any length)."""
    return hmac.compare_digest(given.encode("utf-8"), expected.encode("utf-8"))


@dataclass
class SeatChange:
    """Result of a claim: the previous holder when it was taken over (to be notified)."""

    previous: object | None = None


class PilotSeat:
    """Who the pilot is and when the pilot was last heard. Used from the server's event loop only."""

    def __init__(self, token: str, link_timeout_s: float, clock: Callable[[], float]) -> None:
        if not token:
            raise ValueError("pilot token must not be empty")
        self._token = token
        self.link_timeout_s = link_timeout_s
        self._clock = clock
        self.holder: object | None = None
        self.last_heard_s = float("nan")

    def is_pilot(self, session: object) -> bool:
        return session is not None and session is self.holder

    def silent_s(self) -> float:
        return self._clock() - self.last_heard_s if self.holder is not None else float("inf")

    def stale(self) -> bool:
        return self.holder is not None and self.silent_s() > self.link_timeout_s

    def claim(self, session: object, token: str, takeover: bool = False) -> SeatChange:
        if not token_matches(token, self._token):
            raise AuthError("bad_token", "auth: wrong pilot token")
        if self.holder is session:
            self.heard(session)
            return SeatChange()
        previous = None
        if self.holder is not None:
            if not self.stale():
                raise AuthError("pilot_busy", "auth: another pilot is connected; ask them to release "
                                "the controls (a silent pilot can be taken over after "
                                f"{self.link_timeout_s:g} s with takeover)")
            if not takeover:
                raise AuthError("pilot_busy", f"auth: the pilot has been silent for {self.silent_s():.1f} s; "
                                "send takeover: true to take over")
            previous = self.holder
        self.holder = session
        self.heard(session)
        return SeatChange(previous=previous)

    def heard(self, session: object) -> None:
        if session is self.holder:
            self.last_heard_s = self._clock()

    def release(self, session: object) -> bool:
        if self.holder is session and session is not None:
            self.holder = None
            return True
        return False
