"""`lotsen run`: the whole stack, on the simulated boat (default) or the hardware, at wall-clock pace.

The control core runs in its own process; the web server (with its planner worker), the
recorder and the Foxglove server run in others (lotsen.stack.processes). `--one-process` runs
everything in this process instead (debugging only: a busy web server then shares the control
loop's interpreter).
"""

from __future__ import annotations

import argparse
import signal
import threading
from dataclasses import replace
from pathlib import Path
from typing import Any

from lotsen.cli.mission import waves_flag
from lotsen.errors import ConfigError
from lotsen.physics.config import address_flag as physics_address
from lotsen.runtime.config import BoatSection
from lotsen.settings import PORT, RUN_DURATION, SEED
from lotsen.runtime.lifetime import RunLock
from lotsen.stack.config import StackConfig, load_stack_config
from lotsen.stack.identity import run_identities

# Only what the run lock needs is imported above (the typed config: the sections' dataclasses):
# a second run on the same boat is refused before the launcher's heavy modules (numba, scipy,
# osqp, FastAPI, ...) are loaded. Those are imported in the functions below, after the lock is taken.


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the full stack (simulated boat by default)")
    p.add_argument("config", nargs="?", help="launch config YAML (default: built-in defaults)")
    p.add_argument("--sim", action="store_true", help="simulated boat (the default)")
    p.add_argument("--hardware", action="store_true", help="real drivers (on the boat)")
    p.add_argument("--emulated", action="store_true", help="with --hardware: emulated devices speaking the real protocols")
    p.add_argument("--host", help="web bind address (default from config: 127.0.0.1)")
    p.add_argument("--port", type=PORT, help="web port (default from config: 8080)")
    p.add_argument("--duration", type=RUN_DURATION,
                   help="stop after this many seconds (default: run until Ctrl-C; at most a week)")
    p.add_argument("--seed", type=SEED, help="random seed of the simulation")
    p.add_argument("--foxglove", nargs="?", type=PORT, const=8765, metavar="PORT",
                   help="also stream every topic to Foxglove (WebSocket, default port 8765)")
    p.add_argument("--tls", action="store_true",
                   help="serve the operator page over HTTPS with a self-signed certificate (its fingerprint is printed)")
    p.add_argument("--boat", metavar="BOAT.json|ideal",
                   help="with the simulated boat: its coefficients (a params JSON as `lotsen identify --out` writes "
                        "it, over the config's sim.boat), or 'ideal' for a boat equal to the model in use")
    p.add_argument("--params", metavar="PARAMS.json",
                   help="the model the estimator and the controllers use (over the config's vessel.parameters_file)")
    p.add_argument("--mavlink", action="append", metavar="URL",
                   help="a MAVLink 2 endpoint for ground stations (QGroundControl, Mission Planner, MAVProxy, Cockpit): "
                        "udpout:HOST:PORT (as ArduPilot SITL sends to 14550), udpin:HOST:PORT, tcpin:HOST:PORT, or a "
                        "serial device /dev/ttyUSB0[,57600]; repeatable; added to extra.mavlink.endpoints "
                        "(docs/mavlink.md)")
    p.add_argument("--waves", metavar="HS,TP,FROM_DEG[,S]", type=waves_flag,
                   help="the simulated boat in a wind sea: significant height (m), peak period (s), the direction "
                        "it comes FROM (deg), optionally the spreading exponent (default 10; 0 long-crested); "
                        "sim.environment.waves in the config")
    p.add_argument("--physics", metavar="udp:HOST:PORT", type=physics_address,
                   help="an external physics instead of the simulated boat (ArduPilot SITL's JSON protocol, "
                        "docs/physics.md; over the config's extra.physics.address)")
    p.add_argument("--one-process", action="store_true", help="everything in this process (debugging only)")
    p.set_defaults(func=run)


def launch_config(args: argparse.Namespace, lock: RunLock | None = None) -> tuple[StackConfig, list[str]]:
    """The config with the command line's overrides and, unless web.pilot_token is set, the boat's
    pilot credential (lotsen.web.pairing: made once, kept on the boat, the same for every run and
    every restart). Returns (config, pairing): pairing is ["new" | "kept", credential file] when
    the boat's credential is used, else [].
    With `lock`: the boat is locked for this run (`RunRefused` when another run has it) before
    the config is validated, so a second run is refused before anything else happens."""
    if getattr(args, "sim", False) and args.hardware:
        raise ConfigError("--sim and --hardware: choose one (the simulated boat is the default)")
    if getattr(args, "emulated", False) and not args.hardware:
        raise ConfigError("--emulated is for --hardware (the drivers' emulated twins)")
    config = load_stack_config(args.config)  # every section typed and checked (lotsen.stack.config)
    if args.hardware:
        config = replace(config, mode="hardware", extra=replace(config.extra, emulated=bool(args.emulated)))
    web = config.web
    if args.host is not None and not args.host.strip():
        raise ConfigError("--host: empty; give the web server's bind address (e.g. 127.0.0.1 or 0.0.0.0)")
    if args.host is not None or args.port is not None:
        web = replace(web, host=args.host or web.host, port=args.port if args.port is not None else web.port)
    config = replace(config, web=web, seed=args.seed if args.seed is not None else config.seed)
    config = with_mavlink(config, getattr(args, "mavlink", None))
    config = with_model_and_boat(config, getattr(args, "params", None), getattr(args, "boat", None))
    config = with_physics(config, getattr(args, "physics", None))
    config = with_waves(config, getattr(args, "waves", None))
    if lock is not None:
        lock.identities = run_identities(config)
        lock.acquire(web=f"http://{config.web.host}:{config.web.port}/ (starting)" if config.web.enabled else "")
    from lotsen.stack.processes import validate
    from lotsen.stack.web import paired_config

    config, pairing = paired_config(config)
    validate(config, tls=bool(getattr(args, "tls", False)))
    return config, pairing


def with_waves(config: StackConfig, waves: Any) -> StackConfig:
    """`--waves HS,TP,FROM_DEG[,S]` (a `WavesConfig`) as the simulated boat's `sim.environment.waves`;
    an external physics or the boat itself owns its sea."""
    if waves is None:
        return config
    if config.mode != "sim" or config.extra.physics.address:
        raise ConfigError("--waves: only the simulated boat's sea can be set (an external physics and the lake "
                          "have their own)")
    env = replace(config.sim.environment, waves=waves)
    return replace(config, sim=replace(config.sim, environment=env))


def with_mavlink(config: StackConfig, urls: list[str] | None) -> StackConfig:
    """`--mavlink URL ...` added to `extra.mavlink.endpoints` (checked there: a bad URL is a
    ConfigError naming it); the endpoint lives in the web process, so it needs the web server."""
    if urls:
        mav = config.extra.mavlink
        config = replace(config, extra=replace(config.extra, mavlink=replace(
            mav, endpoints=mav.endpoints + tuple(u for u in urls if u not in mav.endpoints))))
    if config.extra.mavlink.endpoints and not config.web.enabled:
        raise ConfigError("--mavlink / extra.mavlink.endpoints: the MAVLink endpoint runs in the web process; "
                          "set web.enabled: true")
    return config


def with_model_and_boat(config: StackConfig, params: str | None, boat: str | None) -> StackConfig:
    """`--params FILE` sets the model in use; `--boat FILE|ideal` the simulated boat (its file's
    coefficients replace the config's `sim.boat.parameters`; its unmodelled effects stay; its name says
    which file, as `lotsen mission --boat` names it, so every report and log names the boat file)."""
    if params:
        config = replace(config, vessel=replace(config.vessel, parameters_file=str(Path(params).resolve())))
    if boat == "ideal":
        config = replace(config, sim=replace(config.sim, boat=BoatSection(ideal=True)))
    elif boat:
        from lotsen.sim import DEFAULT_BOAT
        from lotsen.model import load_parameter_file

        named = f"{config.sim.boat.name or DEFAULT_BOAT.name} with {load_parameter_file(boat).describe()}"
        config = replace(config, sim=replace(config.sim, boat=replace(
            config.sim.boat, ideal=False, parameters=None, parameters_file=str(Path(boat).resolve()), name=named)))
    return config


def with_physics(config: StackConfig, address: str | None) -> StackConfig:
    """`--physics udp:HOST:PORT`: the external physics instead of the simulated boat (its
    `extra.physics` channel map and timeouts from the config). Only in simulation."""
    if address:
        physics = config.extra.physics
        config = replace(config, extra=replace(config.extra, physics=replace(physics, address=address)))
    if config.extra.physics.address and config.mode != "sim":
        raise ConfigError(f"extra.physics.address {config.extra.physics.address}: an external physics replaces the "
                          "simulated boat; it cannot fly with --hardware")
    return config


def run(args: argparse.Namespace) -> int:
    lock = RunLock([])  # one run per boat: held until this command ends (the kernel frees it if killed)
    try:
        return _run(args, lock)
    finally:
        lock.release()


def _run(args: argparse.Namespace, lock: RunLock) -> int:
    config, pairing = launch_config(args, lock)
    from lotsen.stack import processes
    from lotsen.stack.logs import recover_unclosed_logs
    from lotsen.stack.stack import boat_description, describe_parameters, physics_antenna_mismatch

    for line in recover_unclosed_logs(config):
        print(line, flush=True)
    if pairing:
        from lotsen.web.pairing import console_lines, page_base_url

        base = page_base_url(config.web.host, config.web.port, bool(args.tls))
        for line in console_lines(config.web.pilot_token, Path(pairing[1]), base, pairing[0] == "new"):
            print(line, flush=True)
    if args.one_process:
        return _run_one_process(config, args, lock)
    roles = ("core", "recorder") + (("web",) if config.web.enabled else ()) + \
        (("foxglove",) if args.foxglove is not None else ()) + (("ros2",) if config.extra.ros2 is not None else ())
    launcher = processes.Launcher(config, roles, role_kwargs={"web": {"tls": bool(args.tls)},
                                                              "foxglove": {"port": args.foxglove or 8765}},
                                  out=lambda line: print(line, flush=True), lock=lock)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: launcher.request_stop())
        signal.signal(signal.SIGINT, lambda *_: launcher.request_stop())
    if config.mode == "sim":
        print(f"simulated boat: {boat_description(config)}; model: "
              f"{describe_parameters(config.vessel.parameters_file)}", flush=True)
        mismatch = physics_antenna_mismatch(config)
        if mismatch:
            print(f"warning: {mismatch}", flush=True)
    print(f"lotsen: {config.mode} run, processes: {', '.join(roles)} (Zenoh on {launcher.endpoint})", flush=True)
    try:
        launcher.start()
        print("processes: " + " ".join(f"{role}={pid}" for role, pid in launcher.pids().items()), flush=True)
        return launcher.supervise(args.duration)
    finally:
        launcher.stop()


def _run_one_process(config: StackConfig, args: argparse.Namespace, lock: RunLock) -> int:
    # the whole stack only here: the launcher of the processes (the usual path) does not run it,
    # and a second run is refused (RunLock) before the control stack's libraries are loaded
    from lotsen.stack.launch import build_stack, summary
    from lotsen.stack.logs import add_foxglove_server
    from lotsen.stack.processes import freeze_heap

    stack = build_stack(config, realtime=True)
    if "web" in stack.services:
        lock.update(stack.services["web"].url)
    if args.foxglove is not None:
        add_foxglove_server(stack, config.web.host, args.foxglove)
    print(f"lotsen: {config.mode} stack in one process with nodes: {', '.join(stack.nodes)}", flush=True)
    for line in stack.services.get("banner", []):
        print(line, flush=True)
    stack.executor.add_timer(5.0, lambda: print(summary(stack), flush=True), "console")
    freeze_heap()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stack.executor.stop())
    try:
        stack.executor.run(args.duration)
    except KeyboardInterrupt:
        pass
    finally:
        stack.executor.stop()
        stack.shutdown()
    print(summary(stack))
    return 0
