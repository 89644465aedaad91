import socket
import threading

import pytest
from hypothesis import given, settings, strategies as st

from lotsen.drivers.config import NtripSection
from lotsen.drivers.ntrip import (
    ChunkedDecoder, NtripClient, NtripError, build_request, gga_sentence, parse_response_header,
)
from lotsen.drivers.ubx import nmea_checksum_ok

CFG = NtripSection(enabled=True, host="caster.example", port=2101, mountpoint="MOUNT", user="u", password="p",
                   send_gga=False, reconnect_s=0.5)


def test_request_has_ntrip2_headers_and_basic_auth():
    req = build_request(CFG).decode()
    assert req.startswith("GET /MOUNT HTTP/1.1\r\n") and req.endswith("\r\n\r\n")
    assert "Ntrip-Version: Ntrip/2.0" in req and "Authorization: Basic dTpw" in req


@pytest.mark.parametrize("head, chunked", [
    (b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\nContent-Type: gnss/data\r\n\r\n", True),
    (b"HTTP/1.0 200 OK\r\n\r\n", False),
])
def test_response_200(head, chunked):
    r = parse_response_header(head + b"\xd3")
    assert r.status == 200 and r.chunked == chunked and r.header_length == len(head)


def test_rev1_icy_and_incomplete_header():
    assert parse_response_header(b"ICY 200 OK\r\n\xd3\x00").header_length == 12
    assert parse_response_header(b"HTTP/1.1 200 OK\r\nContent-") is None


@pytest.mark.parametrize("head, words", [
    (b"HTTP/1.1 401 Unauthorized\r\n\r\n", "401"),
    (b"SOURCETABLE 200 OK\r\n\r\n", "source table"),
    (b"HTTP/1.1 200 OK\r\nContent-Type: gnss/sourcetable\r\n\r\n", "source table"),
    (b"HTTP/1.1 404 Not Found\r\n\r\n", "404"),
    (b"garbage\r\n\r\n", "not an NTRIP"),
])
def test_response_refusals_are_clear_errors(head, words):
    with pytest.raises(NtripError, match=words):
        parse_response_header(head)


def test_chunked_decoding_in_any_split():
    body = b"5\r\nhello\r\n3;ext=1\r\nabc\r\n0\r\n\r\n"
    for size in (1, 2, 7, len(body)):
        d = ChunkedDecoder()
        out = b"".join(d.feed(body[i:i + size]) for i in range(0, len(body), size))
        assert out == b"helloabc" and d.finished


def test_gga_checksum():
    line = gga_sentence(57.6905, 11.976, 10.0).rstrip(b"\r\n")
    assert nmea_checksum_ok(line) and b",5741.43000,N,01158.56000,E," in line


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300))
def test_response_parser_fuzz(data):
    try:
        parse_response_header(data)
    except NtripError:
        pass


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200), st.integers(1, 20))
def test_chunked_decoder_fuzz(data, size):
    d = ChunkedDecoder()
    try:
        for i in range(0, len(data), size):
            d.feed(data[i:i + size])
    except NtripError:
        pass


def test_client_streams_dechunked_rtcm_from_a_local_fake_caster():
    """socketpair: no network. The fake caster answers rev 2 chunked and closes."""
    got = bytearray()
    done = threading.Event()
    server, client_sock = socket.socketpair()

    def caster():
        req = server.recv(4096)
        assert b"GET /MOUNT" in req
        server.sendall(b"HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n4\r\n\xd3\x00\x01\xaa\r\n")
        server.sendall(b"2\r\n\xbb\xcc\r\n0\r\n\r\n")
        server.close()

    threading.Thread(target=caster, daemon=True).start()
    client = NtripClient(CFG, on_rtcm=lambda b: (got.extend(b), done.set()),
                         connect=lambda host, port, timeout: client_sock)
    client.session()
    assert bytes(got) == b"\xd3\x00\x01\xaa\xbb\xcc" and client.bytes_received == 6
