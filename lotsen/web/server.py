"""uvicorn in a background thread, bound to the configured address (loopback by default),
optionally with TLS (`ssl_certfile`/`ssl_keyfile`, see lotsen.web.tls)."""

from __future__ import annotations

import threading
import time

import uvicorn

from lotsen.errors import ConfigError
from lotsen.web.hub import Hub
from lotsen.web.routes import create_app


class WebServer:
    def __init__(self, hub: Hub, host: str, port: int, *, ssl_certfile: str | None = None,
                 ssl_keyfile: str | None = None) -> None:
        self.hub = hub
        self.host = host
        self.tls = ssl_certfile is not None
        config = uvicorn.Config(create_app(hub), host=host, port=port, log_level="warning", access_log=False,
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
