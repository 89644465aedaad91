"""The pilot's seat is always reachable (issue 15, item 2): admission that never closes the
pilot, per-address connection limits, token strength checked at start, optional TLS."""

from __future__ import annotations

import json
import secrets
import ssl
import urllib.request
from contextlib import ExitStack
from dataclasses import dataclass

import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from lotsen.errors import ConfigError
from lotsen.runtime.config import LaunchConfig, WebSection
from lotsen.web.admission import choose_evictions
from lotsen.web.auth import address_key, check_token_strength, token_strength_bits
from lotsen.web.options import WebOptions
from lotsen.web.tls import ensure_certificate, fingerprint

from .conftest import TOKEN, recv_until, start_stack, stop_stack


# -- token strength -----------------------------------------------------------------------------
@pytest.mark.parametrize("token", ["x", "test-pilot-token", "correct horse battery", "a" * 40,
                                   "abababababababababababababababab", " " + TOKEN])
def test_a_weak_configured_token_is_refused_at_start(token):
    with pytest.raises(ConfigError, match="web.pilot_token"):
        WebOptions.from_config(LaunchConfig(web=WebSection(pilot_token=token)))


def test_random_tokens_pass_the_strength_rule():
    for _ in range(50):
        for t in (secrets.token_urlsafe(16), secrets.token_hex(16)):  # 128 random bits each
            check_token_strength(t)
            assert token_strength_bits(t) >= 128
    o = WebOptions.from_config(LaunchConfig(web=WebSection(pilot_token=TOKEN)))
    assert o.pilot_token == TOKEN and not o.token_generated


# -- admission (pure) -----------------------------------------------------------------------------
@dataclass
class Occ:
    address: str
    seq: int
    pilot: bool = False

    @property
    def is_pilot(self) -> bool:
        return self.pilot


def test_per_address_limit_closes_the_oldest_viewer_of_that_address_only():
    occ = [Occ("a", 1), Occ("b", 2), Occ("a", 3), Occ("a", 4)]
    out = choose_evictions(occ, "a", max_viewers=16, max_per_address=3)
    assert [o.seq for o, _ in out] == [1] and "your address" in out[0][1]
    assert choose_evictions(occ, "c", max_viewers=16, max_per_address=3) == []


def test_when_full_the_busiest_address_gives_way_and_the_pilot_never_does():
    occ = [Occ("p", 0, pilot=True)] + [Occ("a", i) for i in range(1, 4)] + [Occ("b", 4), Occ("c", 5)]
    out = choose_evictions(occ, "d", max_viewers=5, max_per_address=4)
    assert [o.seq for o, _ in out] == [1] and "full" in out[0][1]
    # whatever the flood, the pilot is never chosen
    flood = [Occ("p", 0, pilot=True)] + [Occ(f"x{i}", i + 1) for i in range(100)]
    for addr in ("x0", "new", "p"):
        assert all(not o.is_pilot for o, _ in choose_evictions(flood, addr, max_viewers=16, max_per_address=1))


def test_addresses_count_ipv6_by_64_and_mapped_ipv4_as_ipv4():
    assert address_key("2001:db8::1") == address_key("2001:db8::ffff:2") == "2001:db8::/64"
    assert address_key("::ffff:192.0.2.1") == "192.0.2.1"
    assert address_key(None) == "?"


# -- over real sockets ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def small():
    rs = start_stack(extra_web={"max_viewers": 4, "max_per_address": 2})
    yield rs
    stop_stack(rs)


def _open(rs, source: str, stack: ExitStack):
    """A connection from `source` (any 127.0.0.x reaches the loopback server), closed with `stack`."""
    ws = stack.enter_context(connect(rs.ws_url, source_address=(source, 0), open_timeout=5))
    recv_until(ws, lambda m: m["type"] == "hello")
    return ws


def _alive(ws) -> bool:
    try:
        ws.send(json.dumps({"type": "ping", "id": 99}))
        recv_until(ws, lambda m: m.get("id") == 99, timeout=2)
        return True
    except (ConnectionClosed, AssertionError, TimeoutError):
        return False


def test_a_flood_of_strangers_never_locks_the_pilot_out(small):
    """Strangers at many addresses fill every slot; the pilot still connects, takes the seat and
    keeps it while the flood goes on (issue 15: 17 tokenless sockets locked the pilot out)."""
    with ExitStack() as es:
        strangers = [_open(small, f"127.0.0.{10 + i}", es) for i in range(6)]  # more than max_viewers
        pilot = _open(small, "127.0.0.1", es)
        pilot.send(json.dumps({"type": "auth", "token": TOKEN, "id": 1}))
        assert recv_until(pilot, lambda m: m.get("id") == 1)["type"] == "auth_ok"
        strangers += [_open(small, f"127.0.0.{30 + i}", es) for i in range(8)]
        pilot.send(json.dumps({"type": "command", "action": "estop", "id": 2}))
        assert recv_until(pilot, lambda m: m.get("id") == 2)["type"] == "ack"  # the e-stop reaches the boat
        hub = small.stack.services["web"].hub
        assert len(hub.clients) <= 4 + 1 and hub.evictions >= 10
        assert sum(_alive(s) for s in strangers) <= 4


def test_one_address_keeps_at_most_max_per_address_viewers(small):
    with ExitStack() as es:
        socks = [_open(small, "127.0.0.77", es) for _ in range(4)]
        reason = recv_until(socks[0], lambda m: m["type"] == "evicted")["reason"]
        assert "too many connections from your address" in reason
        alive = [_alive(s) for s in socks]
        assert alive == [False, False, True, True]  # the oldest gave way, with a reason


# -- TLS --------------------------------------------------------------------------------------------
def test_tls_serves_the_page_and_the_socket_with_the_printed_fingerprint(tmp_path):
    rs = start_stack(extra_web={"tls_dir": str(tmp_path)}, tls=True)
    try:
        url = rs.stack.services["web"].url
        assert url.startswith("https://127.0.0.1:")
        fp = fingerprint(tmp_path / "lotsen-cert.pem")
        assert any(fp in line for line in rs.stack.services["banner"])
        ctx = ssl.create_default_context(cafile=str(tmp_path / "lotsen-cert.pem"))  # pinned: verified
        with urllib.request.urlopen(url, context=ctx, timeout=5) as r:
            assert "EMERGENCY STOP" in r.read().decode()
        with connect(f"wss://127.0.0.1:{rs.port}/ws", ssl=ctx) as ws:
            ws.send(json.dumps({"type": "auth", "token": TOKEN, "id": 1}))
            assert recv_until(ws, lambda m: m.get("id") == 1)["type"] == "auth_ok"
        with pytest.raises(Exception):  # plain HTTP on the TLS port gets nothing
            urllib.request.urlopen(f"http://127.0.0.1:{rs.port}/", timeout=3).read()
    finally:
        stop_stack(rs)
    # made once: a second start reuses the pair (the browser's exception stays valid)
    assert ensure_certificate(tmp_path).fingerprint_sha256 == fp
    assert (tmp_path / "lotsen-key.pem").stat().st_mode & 0o077 == 0
