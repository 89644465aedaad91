"""Pilot authentication, the single pilot seat, token strength and per-address guessing limits.

Rules (docs/web.md, "Access rules"):
- Anyone who can reach the server may watch. Control needs the pilot token, sent in the
  WebSocket's `auth` message (never in a URL, never logged), compared in constant time.
- One pilot at a time. A second `auth` is refused while the seat is held by a connection that
  was heard within `link_timeout_s`.
- The pilot leaves the seat by `release` or by closing the socket. A pilot that is still
  connected but silent for longer than `link_timeout_s` (a frozen tab, a half-open Wi-Fi link)
  can be replaced by `auth` with `takeover: true`; the old connection is told it lost the seat.
- Guessing: each address (an IPv4 address, an IPv6 /64) may send `AUTH_BURST` wrong tokens at once
  and then one every `1 / AUTH_RATE_PER_S` seconds, across all its connections; while its budget is
  spent a wrong token is answered `rate_limited` and closes its connection at once (each further
  guess costs a new WebSocket handshake). The right token is checked first and is never
  throttled, also when another client behind the same address (a phone hotspot, a NAT) spent the
  budget. A connection is closed after `MAX_AUTH_FAILURES` wrong tokens. The real protection is
  the credential's strength: >= 128 bits (`check_token_strength`), which no online guessing at any
  rate gets near; the budget keeps a guesser's noise out of the logs and the CPU.
- The credential may be replaced while the server runs (`lotsen pair --new`, lotsen.web.pairing):
  `PilotSeat` reads it through a callable, and a pilot seated with the old one loses the seat.
"""

from __future__ import annotations

import hmac
import ipaddress
import math
import string
from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable

from lotsen.errors import ConfigError
from lotsen.web.ratelimit import TokenBucket

MAX_AUTH_FAILURES = 5
AUTH_BURST = 5.0
AUTH_RATE_PER_S = 0.5
MAX_TRACKED_ADDRESSES = 4096
MIN_TOKEN_BITS = 128.0
MIN_TOKEN_DISTINCT = 8
MAX_TOKEN_CHARS = 256

#: character classes for the entropy bound: a token drawing on a class may use any of its members
_CLASSES = ((set(string.ascii_lowercase), 26), (set(string.ascii_uppercase), 26), (set(string.digits), 10),
            (set("-_"), 2), (set(string.punctuation) - set("-_") | {" "}, 31))


class AuthError(Exception):
    def __init__(self, code: str, message: str) -> None:
        super().__init__(message)
        self.code = code


def token_matches(given: str, expected: str) -> bool:
    """Constant-time comparison (hmac.compare_digest on bytes: no early exit, any length)."""
    return hmac.compare_digest(given.encode("utf-8"), expected.encode("utf-8"))


_HEX = (set("0123456789abcdef"), set("0123456789ABCDEF"))
_URLSAFE = set(string.ascii_letters + string.digits + "-_")


def token_strength_bits(token: str) -> float:
    """Upper bound of a token's entropy: length x log2(alphabet). The alphabet is that of the
    usual generators when the token fits it (hex: 16, URL-safe base64: 64, so that
    `secrets.token_hex(16)` and `secrets.token_urlsafe(16)` both count 128 bits), else the sum of
    the character classes the token uses (a-z, A-Z, 0-9, '-_', other ASCII punctuation and space;
    any non-ASCII character adds 1000). It is an upper bound: 'aaaa...' or a dictionary word
    scores as random text, hence the extra rule of `MIN_TOKEN_DISTINCT` distinct characters."""
    if not token:
        return 0.0
    chars = set(token)
    if any(chars <= h for h in _HEX):
        alphabet = 16
    elif chars <= _URLSAFE:
        alphabet = 64
    else:
        alphabet = sum(size for members, size in _CLASSES if chars & members)
        if any(ord(c) > 127 for c in chars):
            alphabet += 1000
    return len(token) * math.log2(max(alphabet, 2))


def check_token_strength(token: str, where: str = "web.pilot_token") -> None:
    """Refuse a weak configured token at start (ConfigError): >= 128 bits by `token_strength_bits`,
    >= 8 distinct characters, <= 256 characters, no leading/trailing space (the page trims)."""
    if token != token.strip():
        raise ConfigError(f"{where}: must not start or end with white space")
    if len(token) > MAX_TOKEN_CHARS:
        raise ConfigError(f"{where}: {len(token)} characters, at most {MAX_TOKEN_CHARS}")
    bits = token_strength_bits(token)
    if bits < MIN_TOKEN_BITS or len(set(token)) < MIN_TOKEN_DISTINCT:
        raise ConfigError(
            f"{where}: too weak ({len(token)} characters, at most {bits:.0f} bits, {len(set(token))} distinct "
            f"characters; needs >= {MIN_TOKEN_BITS:.0f} bits and >= {MIN_TOKEN_DISTINCT} distinct characters, "
            "e.g. 22 random URL-safe characters: python -c 'import secrets; print(secrets.token_urlsafe(16))'; "
            "or leave it unset for a new random token each run)")


def address_key(host: str | None) -> str:
    """What counts as one address for the limits: an IPv4 address, an IPv6 /64 (one host gets a
    whole /64 on most networks), IPv4-mapped IPv6 as IPv4; anything unparsable as itself."""
    if not host:
        return "?"
    try:
        ip = ipaddress.ip_address(host.split("%")[0])
    except ValueError:
        return host[:64]
    if isinstance(ip, ipaddress.IPv6Address):
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        return str(ipaddress.ip_network(f"{ip}/64", strict=False))
    return str(ip)


class AuthGuard:
    """Wrong-token budget per address across connections (token bucket: `AUTH_BURST`, then
    `AUTH_RATE_PER_S`): `allow` before checking a token, `failed` after a wrong one. Bounded
    memory: the least recently used addresses are forgotten."""

    def __init__(self, clock: Callable[[], float], rate_per_s: float = AUTH_RATE_PER_S,
                 burst: float = AUTH_BURST) -> None:
        self._clock = clock
        self.rate, self.burst = rate_per_s, burst
        self._buckets: OrderedDict[str, TokenBucket] = OrderedDict()

    def _bucket(self, key: str) -> TokenBucket:
        b = self._buckets.get(key)
        if b is None:
            b = self._buckets[key] = TokenBucket(self.rate, self.burst, self._clock)
            while len(self._buckets) > MAX_TRACKED_ADDRESSES:
                self._buckets.popitem(last=False)
        self._buckets.move_to_end(key)
        return b

    def allow(self, key: str) -> bool:
        """May `key` try a token now (its wrong-token budget is not spent)?"""
        return self._bucket(key).available()

    def failed(self, key: str) -> None:
        """A wrong token from `key`: one attempt of its budget used."""
        self._bucket(key).take()

    def wait_s(self) -> float:
        return 1.0 / self.rate


@dataclass
class SeatChange:
    """Result of a claim: the previous holder when it was taken over (to be notified)."""

    previous: object | None = None


class PilotSeat:
    """Who the pilot is and when the pilot was last heard. Used from the server's event loop only."""

    def __init__(self, token: str | Callable[[], str], link_timeout_s: float, clock: Callable[[], float]) -> None:
        """`token`: the pilot credential, or a callable returning the one in force now (a paired
        boat's credential file, re-read when it changes)."""
        self._credential = token if callable(token) else (lambda: token)
        if not self._credential():
            raise ValueError("pilot token must not be empty")
        self._holder_token = ""
        self.link_timeout_s = link_timeout_s
        self._clock = clock
        self.holder: object | None = None
        self.last_heard_s = float("nan")
        self.ever_held = False

    def is_pilot(self, session: object) -> bool:
        return session is not None and session is self.holder

    def silent_s(self) -> float:
        return self._clock() - self.last_heard_s if self.holder is not None else float("inf")

    def stale(self) -> bool:
        """The pilot is silent beyond its limit: the seat's, or the holder's own `link_timeout_s`
        (a ground station heartbeats at 1 Hz: lotsen.web.mavlink)."""
        limit = getattr(self.holder, "link_timeout_s", None) or self.link_timeout_s
        return self.holder is not None and self.silent_s() > limit

    def token_ok(self, token: str) -> bool:
        """Is `token` the pilot credential in force now (constant-time comparison)?"""
        current = self._credential()
        return bool(current) and token_matches(token, current)

    def current_token(self) -> str:
        """The credential in force (for the pilot's pairing QR code only)."""
        return self._credential()

    def holder_revoked(self) -> bool:
        """The seat is held with a credential that has since been replaced (`lotsen pair --new`)."""
        return self.holder is not None and not self.token_ok(self._holder_token)

    def claim(self, session: object, token: str, takeover: bool = False) -> SeatChange:
        if not self.token_ok(token):
            raise AuthError("bad_token", "auth: wrong pilot token")
        if self.holder is session:
            self.heard(session)
            return SeatChange()
        previous = None
        if self.holder is not None:
            if not self.stale():
                raise AuthError("pilot_busy", "auth: another pilot is connected; ask them to release "
                                "the controls (a silent pilot can be taken over after "
                                f"{self.link_timeout_s:g} s with the Take over button)")
            if not takeover:
                raise AuthError("pilot_busy", f"auth: the pilot has been silent for {self.silent_s():.1f} s; "
                                "press Take over to take the controls")
            previous = self.holder
        self.holder = session
        self._holder_token = token
        self.ever_held = True
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
