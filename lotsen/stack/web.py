"""`add_web(stack)`: attach the operator interface to a running stack.

Part "web" of `lotsen.stack.launch.PARTS`, or the main of the web process. The server never enters
node code: it reads the bus through a queue and publishes through
``executor.call_soon_threadsafe``, so every publication happens on the executor's thread.
"""

from __future__ import annotations

import os
import socket
from typing import TYPE_CHECKING, Any

from lotsen.errors import ConfigError
from lotsen.stack.config import StackConfig
from lotsen.stack.stack import Stack
from lotsen.web.options import WebOptions
from lotsen.web.tls import Certificate, ensure_certificate, fingerprint

if TYPE_CHECKING:
    from lotsen.web.server import WebServer


def pilot_credential_file(config: StackConfig) -> str:
    """The file of the boat's pilot credential (lotsen.web.pairing): `extra.web.credential_file`,
    else one per boat in $LOTSEN_CONFIG_DIR/pairing: the simulated boat by its name, the hardware
    as the one boat of this computer."""
    from lotsen.stack.identity import run_identities
    from lotsen.web.pairing import credential_path

    if config.extra.web.credential_file:
        return os.path.expanduser(config.extra.web.credential_file)
    boat = run_identities(config)[0] if config.mode == "sim" else "boat"
    return str(credential_path(boat))


def paired_config(config: StackConfig) -> tuple[StackConfig, list[str]]:
    """`config` with the boat's pilot credential when web.pilot_token is not set: the credential
    file (made now if there is none) named in `extra.web.credential_file` for the web process (it
    re-reads it), and its value in web.pilot_token for the core (ROS 2 commands). Returns the
    config and what was found, for the console (unchanged without a page, or with a token)."""
    from dataclasses import replace

    from lotsen.web.pairing import PilotCredential

    if not config.web.enabled or config.web.pilot_token:
        if config.web.pilot_token and config.extra.web.credential_file:
            raise ConfigError("web.pilot_token and extra.web.credential_file are both set: the page takes one "
                              "credential; remove one of them")
        return config, []
    path = pilot_credential_file(config)
    cred, created = PilotCredential.load_or_create(path)
    extra = replace(config.extra, web=replace(config.extra.web, credential_file=path))
    return replace(config, extra=extra, web=replace(config.web, pilot_token=cred.current())), \
        ["new" if created else "kept", path]


def check_web_host(host: str) -> None:
    """ConfigError unless `host` names an address of this machine the web server can bind (a
    trial bind on a free port), checked before any process starts."""
    try:
        infos = socket.getaddrinfo(host or None, 0, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except (socket.gaierror, UnicodeError, ValueError) as exc:
        raise ConfigError(f"web.host: {host!r} is not a host name or address ({getattr(exc, 'strerror', None) or exc}); "
                          "use 127.0.0.1 (this computer only) or 0.0.0.0 (every network)") from None
    problems = []
    for family, kind, proto, _, address in infos:
        try:
            with socket.socket(family, kind, proto) as s:
                s.bind(address)
            return
        except OSError as exc:
            problems.append(f"{address[0]}: {exc.strerror or exc}")
    raise ConfigError(f"web.host: {host!r} is not an address of this machine ({'; '.join(problems)}); "
                      "use 127.0.0.1 (this computer only) or 0.0.0.0 (every network)")


def tls_certificate(options: WebOptions, tls: bool) -> Certificate | None:
    """The certificate to serve: the configured pair (extra.web.tls_certfile/keyfile, TLS on
    without the flag), else with `tls` (`lotsen run --tls`) a self-signed one in `tls_dir`,
    created once for this machine's names; None = plain HTTP."""
    if options.tls_certfile and options.tls_keyfile:
        for f in (options.tls_certfile, options.tls_keyfile):
            if not os.path.isfile(f):
                raise ConfigError(f"extra.web: TLS file {f} does not exist")
        return Certificate(options.tls_certfile, options.tls_keyfile, fingerprint(options.tls_certfile))
    if not tls:
        return None
    hosts = ["localhost", "127.0.0.1", "::1", socket.gethostname()]
    if options.host not in ("0.0.0.0", "::", "") and options.host not in hosts:
        hosts.append(options.host)
    return ensure_certificate(options.tls_dir or "~/.config/lotsen/tls", tuple(hosts))


def add_web(stack: Stack, run_blocking: Any = None, tls: bool = False) -> WebServer | None:
    """The web server on `stack`'s bus. `run_blocking`: how planning requests run (the planner
    worker process in `lotsen run`; a thread of this process by default). `tls`: serve HTTPS with
    a self-signed certificate (`tls_certificate`; its fingerprint goes to the banner)."""
    # the server here, not at the top: the launcher checks the host and the certificate with
    # this module and must not carry FastAPI for the whole run
    from lotsen.web.hub import Hub
    from lotsen.web.server import WebServer
    from lotsen.web.settings import Settings

    config = stack.config
    if not config.web.enabled:
        return None
    options = WebOptions.from_config(config, config.extra.web, config.extra.failsafes.link_timeout_s)
    bus, executor = stack.bus, stack.executor

    def publish(topic: str, msg: Any) -> None:
        executor.call_soon_threadsafe(lambda: bus.publish(topic, msg))

    cert = tls_certificate(options, tls)
    hub = Hub(bus, executor.clock.now, publish, options, origin=stack.origin)
    hub.handler.planner_config = config.extra.planner  # the run's one PlannerConfig
    fs = config.extra.failsafes
    hub.handler.settings = Settings(hub.handler.planner_config, fs, controller={
        "controller": config.nodes.controller, "control_rate_hz": config.nodes.control_rate_hz,
        "command_deadline_s": config.nodes.command_deadline_s, "fallback_controller": fs.fallback_controller,
        "settings": "the defaults of lotsen.control (docs/control.md); the launch config has no section for them"})
    if run_blocking is not None:
        hub.handler.run_blocking = run_blocking
    add_prediction(hub, config)
    server = WebServer(hub, options.host, options.port, ssl_certfile=cert.certfile if cert else None,
                       ssl_keyfile=cert.keyfile if cert else None, allowed_hosts=options.allowed_hosts)
    server.start()
    stack.services["web"] = server
    banner = stack.services.setdefault("banner", [])
    banner.append(f"operator interface: {server.url}")
    if cert is not None:
        banner.append(f"TLS certificate {cert.certfile}: SHA-256 fingerprint {cert.fingerprint_sha256} "
                      "(compare it with the browser's certificate viewer on first connection)")
    if options.token_generated:
        banner.append(f"pilot token (this run only; set web.pilot_token to fix it): {options.pilot_token}")
    if options.host not in ("127.0.0.1", "localhost", "::1"):
        banner.append(f"warning: the operator interface is reachable from the network ({options.host})")
    stack.services.setdefault("on_shutdown", []).append(server.stop)
    if config.extra.mavlink.endpoints:
        add_mavlink(stack, hub, options.pilot_token)
    return server


def add_prediction(hub: Any, config: StackConfig) -> None:
    """The page's Predict: the run's model in use and controller, the current and the sea the
    estimator knows now (the latest state/estimate and fusion/sea_state the page receives)."""
    from lotsen.messages import SeaState, Topic, VesselState
    from lotsen.stack.page_prediction import EstimatedConditions, PagePredictor, estimated_conditions
    from lotsen.stack.stack import model_info, vessel_model

    model = vessel_model(config)
    hub.handler.predict = PagePredictor(model.params, model.geometry, model_info(config, model).source,
                                        config.nodes.controller, config.extra.planner)

    def estimated_current() -> EstimatedConditions:  # the handler's name for it: what Predict is given
        state, sea = hub.state.latest.get(Topic.STATE), hub.state.latest.get(Topic.SEA_STATE)
        return estimated_conditions(state.current_ne_mps if isinstance(state, VesselState) else None,
                                    sea if isinstance(sea, SeaState) else None)

    hub.handler.estimated_current = estimated_current


def add_mavlink(stack: Stack, hub: Any, pilot_token: str) -> Any:
    """The MAVLink endpoint (`extra.mavlink`, `lotsen run --mavlink URL`) on the web server's hub:
    the same bus, pilot seat, control handler and planner as the page; signing with the page's
    pilot token (one credential)."""
    from lotsen.web.mavlink.endpoint import MavlinkEndpoint

    config = stack.config
    fs = config.extra.failsafes
    endpoint = MavlinkEndpoint(hub, config.extra.mavlink, pilot_token, stack.origin, stack.model.params.to_dict(),
                               fs, config.nodes.controller, config.nodes.control_rate_hz,
                               config.nodes.command_deadline_s)
    assert hub.loop is not None, "the web server starts (and its hub gets its event loop) before the endpoint"
    endpoint.start(hub.loop)
    stack.services["mavlink"] = endpoint
    stack.services.setdefault("banner", []).extend(endpoint.banner())
    stack.services.setdefault("on_shutdown", []).append(endpoint.stop)
    return endpoint
