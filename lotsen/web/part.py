"""`add_web(stack)`: attach the operator interface to a running stack.

Registered by the launch code with ``register_part("web", add_web)``. The server never enters
node code: it reads the bus through a queue and publishes through
``executor.call_soon_threadsafe``, so every publication happens on the executor's thread.
"""

from __future__ import annotations

from typing import Any

from lotsen.planning import GeoOrigin
from lotsen.runtime.launch import Stack
from lotsen.web.hub import Hub
from lotsen.web.options import WebOptions
from lotsen.web.server import WebServer


def geo_origin(stack: Stack) -> GeoOrigin | None:
    """The local frame's geographic origin: `extra.origin`, else the simulated receiver's."""
    extra = stack.config.extra.get("origin")
    if isinstance(extra, dict) and "lat_deg" in extra and "lon_deg" in extra:
        return GeoOrigin(float(extra["lat_deg"]), float(extra["lon_deg"]), float(extra.get("height_m", 0.0)))
    if stack.simulator is not None:
        g = stack.simulator.config.gnss
        return GeoOrigin(g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m)
    return None


def add_web(stack: Stack) -> WebServer | None:
    config = stack.config
    if not config.web.enabled:
        return None
    options = WebOptions.from_config(config)
    bus, executor = stack.bus, stack.executor

    def publish(topic: str, msg: Any) -> None:
        executor.call_soon_threadsafe(lambda: bus.publish(topic, msg))

    hub = Hub(bus, executor.clock.now, publish, options, origin=geo_origin(stack))
    server = WebServer(hub, options.host, options.port)
    server.start()
    stack.services["web"] = server
    banner = stack.services.setdefault("banner", [])
    banner.append(f"operator interface: {server.url}")
    if options.token_generated:
        banner.append(f"pilot token (this run only; set web.pilot_token to fix it): {options.pilot_token}")
    else:
        banner.append("pilot token: from the config (web.pilot_token)")
    if options.host not in ("127.0.0.1", "localhost", "::1"):
        banner.append(f"warning: the operator interface is reachable from the network ({options.host})")
    stack.services.setdefault("on_shutdown", []).append(server.stop)
    return server
