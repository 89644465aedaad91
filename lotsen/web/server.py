"""uvicorn in a background thread, bound to the configured address (loopback by default),
optionally with TLS (`ssl_certfile`/`ssl_keyfile`, see lotsen.web.tls), behind `HostGuard`."""

from __future__ import annotations

import functools
import ipaddress
import socket
import threading
import time
from typing import Any, Awaitable, Callable

import uvicorn

from lotsen.errors import ConfigError
from lotsen.web.hub import Hub
from lotsen.web.routes import create_app


@functools.lru_cache(maxsize=256)
def _is_local_address(text: str) -> bool:
    """An IP literal that is one of this machine's addresses (a trial bind on a free port)."""
    try:
        ip = ipaddress.ip_address(text)
    except ValueError:
        return False
    if ip.is_loopback or ip.is_unspecified:
        return ip.is_loopback
    try:
        with socket.socket(socket.AF_INET6 if ip.version == 6 else socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind((text, 0))
        return True
    except OSError:
        return False


#: header limits (uvicorn's httptools parser takes headers of any size): one header line, all of them
MAX_HEADER_BYTES = 8 * 1024
MAX_HEADERS_BYTES = 32 * 1024
MAX_HEADER_COUNT = 100
#: headers that must come once: two Host headers let a check read one and a proxy or the app the other
SINGLE_HEADERS = frozenset({b"host", b"origin", b"content-length", b"transfer-encoding", b"upgrade",
                            b"sec-websocket-key", b"sec-websocket-version", b"authorization", b"cookie"})


def header_problem(headers: Any) -> tuple[int, str] | None:
    """(status, reason) when the request's headers are refused: a duplicate of a header that must
    come once (400), too many or too large (431 Request Header Fields Too Large); None when fine."""
    seen: set[bytes] = set()
    total = 0
    for count, (k, v) in enumerate(headers, 1):
        size = len(k) + len(v) + 4
        total += size
        if size > MAX_HEADER_BYTES:
            return 431, f"header {k[:40].decode('latin-1')!r} is {size} bytes (at most {MAX_HEADER_BYTES})"
        if total > MAX_HEADERS_BYTES or count > MAX_HEADER_COUNT:
            return 431, f"headers too large (at most {MAX_HEADERS_BYTES} bytes in {MAX_HEADER_COUNT} headers)"
        if k in SINGLE_HEADERS:
            if k in seen:
                return 400, f"header {k.decode('latin-1')!r} given twice"
            seen.add(k)
    return None


class HostGuard:
    """Refuses requests whose Host header names no one this server serves: DNS rebinding (a page
    of evil.example whose name then resolves to the boat) sends `Host: evil.example` with its own
    origin, so only the Host header tells it apart. Served: localhost (and *.localhost), this
    machine's names (host name, its .local and its full name), the configured bind host, and IP
    literals of this machine's addresses, and the configured `extra.web.allowed_hosts`. HTTP gets 421 Misdirected Request; a WebSocket
    handshake is refused before it is accepted (421 where the server can say so, else 403).
    It also refuses duplicated single headers (a second Host is never read past) and oversized
    headers (`header_problem`)."""

    def __init__(self, app: Callable[..., Awaitable[None]], bind_host: str,
                 allowed_hosts: tuple[str, ...] = ()) -> None:
        self.app = app
        names = {"localhost", socket.gethostname(), socket.gethostname() + ".local", socket.getfqdn(),
                 *allowed_hosts}
        if bind_host not in ("", "0.0.0.0", "::"):
            names.add(bind_host)
        self.names = {n.lower().rstrip(".") for n in names if n}

    def allows(self, host_header: str | None) -> bool:
        if not host_header:
            return False
        host = host_header.strip().lower()
        if host.startswith("["):  # [v6]:port
            host = host[1:host.find("]")] if "]" in host else ""
        elif host.count(":") == 1:
            host = host.split(":", 1)[0]
        host = host.rstrip(".")
        return host in self.names or host.endswith(".localhost") or _is_local_address(host)

    async def __call__(self, scope: dict, receive: Callable[..., Any], send: Callable[..., Any]) -> None:
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        problem = header_problem(scope.get("headers", ()))
        host = next((v.decode("latin-1") for k, v in scope.get("headers", ()) if k == b"host"), None)
        if problem is None and self.allows(host):
            return await self.app(scope, receive, send)
        status, why = problem or (421, f"this server does not serve the host {host!r}")
        text = {400: "Bad Request", 421: "Misdirected Request", 431: "Request Header Fields Too Large"}[status]
        body = f"{status} {text}: {why}\n".encode()[:300]
        headers = [(b"content-type", b"text/plain; charset=utf-8"), (b"content-length", str(len(body)).encode())]
        if scope["type"] == "http":
            await send({"type": "http.response.start", "status": status, "headers": headers})
            await send({"type": "http.response.body", "body": body})
        elif "websocket.http.response" in scope.get("extensions", {}):
            await send({"type": "websocket.http.response.start", "status": status, "headers": headers})
            await send({"type": "websocket.http.response.body", "body": body})
        else:
            await send({"type": "websocket.close", "code": 1008})


class WebServer:
    def __init__(self, hub: Hub, host: str, port: int, *, ssl_certfile: str | None = None,
                 ssl_keyfile: str | None = None, allowed_hosts: tuple[str, ...] = ()) -> None:
        self.hub = hub
        self.host = host
        self.tls = ssl_certfile is not None
        config = uvicorn.Config(HostGuard(create_app(hub), host, allowed_hosts), host=host, port=port, log_level="warning", access_log=False,
                                ws_max_size=1 << 20, ws_ping_interval=5.0, ws_ping_timeout=5.0,
                                lifespan="on", server_header=False, ssl_certfile=ssl_certfile,
                                ssl_keyfile=ssl_keyfile)
        self._server = uvicorn.Server(config)
        self._thread: threading.Thread | None = None
        self.port = port

    def start(self, timeout_s: float = 10.0) -> None:
        """Start serving; returns once the socket is bound (port 0 -> the chosen port in `.port`)."""
        self._thread = threading.Thread(target=self._server.run, name="web-server", daemon=True)
        self._thread.start()
        t_end = time.monotonic() + timeout_s
        while not self._server.started:
            if not self._thread.is_alive():
                raise ConfigError(f"web: cannot serve on {self.host}:{self.port} "
                                  "(address in use or not available; set web.port / web.host)")
            if time.monotonic() > t_end:
                raise ConfigError(f"web: server did not start within {timeout_s:g} s")
            time.sleep(0.01)
        sockets = [s for srv in self._server.servers for s in srv.sockets]
        if sockets:
            self.port = sockets[0].getsockname()[1]

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"{'https' if self.tls else 'http'}://{host}:{self.port}/"

    def stop(self, timeout_s: float = 5.0) -> None:
        self._server.should_exit = True
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)
