"""A minimal NTRIP client (rev 2, with rev 1 "ICY 200 OK" casters accepted) over a plain socket.

Why our own and not pygnssutils' GNSSNTRIPClient: that one owns its thread, its output and its
logging, and is configured through a GUI-oriented settings dict; what the boat needs is 60
lines: send a request, check the response header, de-chunk the body, hand the RTCM bytes to a
callback, send GGA for VRS casters, reconnect after a drop. The pure parts (request, response
header, chunked decoding, GGA) are separate functions so tests and fuzzing need no network.
"""

from __future__ import annotations

import base64
import math
import socket
import threading
from dataclasses import dataclass
from datetime import datetime, timezone
from typing import Callable

from lotsen.drivers.config import NtripSection


class NtripError(Exception):
    """The caster refused or answered something that is not an RTCM stream."""


def build_request(cfg: NtripSection, version: int = 2) -> bytes:
    """HTTP GET for the mountpoint (NTRIP rev 2 headers; Basic auth when a user is set)."""
    lines = [f"GET /{cfg.mountpoint} HTTP/1.1", f"Host: {cfg.host}:{cfg.port}",
             "User-Agent: NTRIP lotsen/1.0", "Connection: close"]
    if version == 2:
        lines.append("Ntrip-Version: Ntrip/2.0")
    if cfg.user:
        token = base64.b64encode(f"{cfg.user}:{cfg.password}".encode()).decode()
        lines.append(f"Authorization: Basic {token}")
    return ("\r\n".join(lines) + "\r\n\r\n").encode("ascii", "replace")


@dataclass
class NtripResponse:
    status: int
    chunked: bool
    header_length: int  # bytes of `data` that belong to the header
    is_sourcetable: bool = False


def parse_response_header(data: bytes) -> NtripResponse | None:
    """The caster's status line and headers. None: header not complete yet.
    Raises NtripError for anything other than a 200 stream (401, 404, SOURCETABLE, junk)."""
    end = data.find(b"\r\n\r\n")
    if end < 0:
        # rev-1 casters answer "ICY 200 OK\r\n" and then stream binary at once
        if data.startswith(b"ICY 200 OK\r\n"):
            return NtripResponse(200, False, len(b"ICY 200 OK\r\n"))
        if len(data) > 4096:
            raise NtripError("no end of the response header in the first 4 kB")
        return None
    head = data[:end].decode("latin-1")
    lines = head.split("\r\n")
    parts = lines[0].split(" ", 2)
    if parts[0] == "SOURCETABLE":
        raise NtripError("caster sent its source table: the mountpoint does not exist")
    if len(parts) < 2 or not (parts[0].startswith("HTTP/") or parts[0] == "ICY"):
        raise NtripError(f"not an NTRIP/HTTP response: {lines[0][:60]!r}")
    try:
        status = int(parts[1])
    except ValueError:
        raise NtripError(f"bad status line: {lines[0][:60]!r}") from None
    if status == 401:
        raise NtripError("401 unauthorized: check the NTRIP user and password")
    if status != 200:
        raise NtripError(f"caster answered {status} {parts[2] if len(parts) > 2 else ''}".strip())
    headers = {}
    for line in lines[1:]:
        k, sep, v = line.partition(":")
        if sep:
            headers[k.strip().lower()] = v.strip().lower()
    if headers.get("content-type", "") == "gnss/sourcetable":
        raise NtripError("caster sent its source table: the mountpoint does not exist")
    return NtripResponse(status, "chunked" in headers.get("transfer-encoding", ""), end + 4)


class ChunkedDecoder:
    """HTTP/1.1 chunked transfer decoding, incremental. Bad chunk headers raise NtripError."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._remaining = 0  # bytes of chunk data still to come
        self._need_crlf = False
        self.finished = False

    def feed(self, data: bytes) -> bytes:
        self._buf += data
        out = bytearray()
        while self._buf and not self.finished:
            if self._remaining:
                take = self._buf[:self._remaining]
                out += take
                del self._buf[:len(take)]
                self._remaining -= len(take)
                if self._remaining == 0:
                    self._need_crlf = True
                continue
            if self._need_crlf:
                if len(self._buf) < 2:
                    break
                if self._buf[:2] != b"\r\n":
                    raise NtripError("chunked stream: missing CRLF after a chunk")
                del self._buf[:2]
                self._need_crlf = False
                continue
            lf = self._buf.find(b"\r\n")
            if lf < 0:
                if len(self._buf) > 64:
                    raise NtripError("chunked stream: chunk size line too long")
                break
            size_text = bytes(self._buf[:lf]).split(b";")[0].strip()
            try:
                size = int(size_text, 16)
            except ValueError:
                raise NtripError(f"chunked stream: bad chunk size {size_text[:16]!r}") from None
            if size < 0:
                raise NtripError("chunked stream: negative chunk size")
            del self._buf[:lf + 2]
            if size == 0:
                self.finished = True
                break
            self._remaining = size
        return bytes(out)


def gga_sentence(lat_deg: float, lon_deg: float, height_m: float, when: datetime | None = None,
                 num_sv: int = 12, quality: int = 1) -> bytes:
    """NMEA GGA for the caster (VRS needs the rover's approximate position)."""
    when = when or datetime(2000, 1, 1, tzinfo=timezone.utc)
    lat, lon = abs(lat_deg), abs(lon_deg)
    lat_s = f"{int(lat):02d}{(lat - int(lat)) * 60:08.5f}"
    lon_s = f"{int(lon):03d}{(lon - int(lon)) * 60:08.5f}"
    body = (f"GPGGA,{when:%H%M%S}.00,{lat_s},{'N' if lat_deg >= 0 else 'S'},{lon_s},"
            f"{'E' if lon_deg >= 0 else 'W'},{quality},{num_sv:02d},1.0,{height_m:.1f},M,0.0,M,,")
    x = 0
    for ch in body.encode():
        x ^= ch
    return f"${body}*{x:02X}\r\n".encode()


class NtripClient:
    """Connects, streams RTCM bytes to `on_rtcm(bytes)`, reconnects after `reconnect_s`.

    Runs in its own daemon thread (`start()` / `stop()`); `position()` returns the latest
    (lat, lon, height) or None, sent as GGA every gga_period_s when `send_gga`.
    """

    def __init__(self, cfg: NtripSection, on_rtcm: Callable[[bytes], None],
                 position: Callable[[], tuple[float, float, float] | None] = lambda: None,
                 on_status: Callable[[str], None] = lambda text: None,
                 connect: Callable[[str, int, float], socket.socket] | None = None) -> None:
        self.cfg = cfg
        self.on_rtcm = on_rtcm
        self.position = position
        self.on_status = on_status
        self._connect = connect or (lambda host, port, timeout: socket.create_connection((host, port), timeout))
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.bytes_received = 0
        self.connections = 0
        self.errors = 0
        self.last_error = ""

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="lotsen-ntrip", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.session()
            except (OSError, NtripError) as exc:
                self.errors += 1
                self.last_error = str(exc)
                self.on_status(f"ntrip: {exc}")
            self._stop.wait(self.cfg.reconnect_s)

    def session(self) -> None:
        """One connection: request, header, stream until the caster closes or stop()."""
        import time

        sock = self._connect(self.cfg.host, self.cfg.port, 10.0)
        try:
            sock.settimeout(1.0)
            sock.sendall(build_request(self.cfg))
            self.connections += 1
            head = b""
            resp = None
            while resp is None and not self._stop.is_set():
                chunk = sock.recv(4096)
                if not chunk:
                    raise NtripError("caster closed the connection before answering")
                head += chunk
                resp = parse_response_header(head)
            if resp is None:
                return
            self.on_status(f"ntrip: connected to {self.cfg.host}:{self.cfg.port}/{self.cfg.mountpoint}")
            dechunk = ChunkedDecoder() if resp.chunked else None
            body = head[resp.header_length:]
            next_gga = 0.0
            while not self._stop.is_set():
                if body:
                    data = dechunk.feed(body) if dechunk else body
                    if data:
                        self.bytes_received += len(data)
                        self.on_rtcm(data)
                    if dechunk is not None and dechunk.finished:
                        return
                if self.cfg.send_gga and time.monotonic() >= next_gga:
                    pos = self.position()
                    if pos is not None and all(math.isfinite(v) for v in pos):
                        sock.sendall(gga_sentence(*pos))
                        next_gga = time.monotonic() + self.cfg.gga_period_s
                try:
                    body = sock.recv(4096)
                except socket.timeout:
                    body = b""
                    continue
                if not body:
                    raise NtripError("caster closed the connection")
        finally:
            sock.close()
