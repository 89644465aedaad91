"""`lotsen physics-server [CONFIG.yaml] [--host 127.0.0.1] [--port 9002] [--boat BOAT.json|ideal]
[--params PARAMS.json] [--seed N] [--current SPEED,DIR_DEG] [--wind SPEED,DIR_DEG] [--duration S]`

lotsen's own simulated boat served as a physics over ArduPilot SITL's JSON protocol
(`lotsen.physics.server`, docs/physics.md): the reference a `--physics udp:HOST:PORT` run is
checked against. The boat is the config's `sim.boat` (or `--boat`), its water and wind the
config's `sim.environment` (or `--current` / `--wind`), its step `sim.dt_s`, its gusts seeded by
`--seed` (as the built-in run's), its channel map the config's `extra.physics.servos`.
Runs until Ctrl-C / SIGTERM, or for `--duration` seconds of wall-clock time.
"""

from __future__ import annotations

import argparse
import signal
import threading
from dataclasses import replace
from typing import Any

from lotsen.cli.mission import waves_flag
from lotsen.errors import ConfigError
from lotsen.settings import PORT, RUN_DURATION, SEED


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "physics-server", help="serve the simulated boat as an ArduPilot SITL JSON physics (the reference for --physics)",
        description="Serve lotsen's simulated boat over ArduPilot SITL's JSON protocol: servo packets in, the "
                    "boat's state back, one frame per step (docs/physics.md).")
    p.add_argument("config", nargs="?", help="launch config YAML: sim.boat, sim.environment, sim.dt_s, extra.physics.servos")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=PORT, default=9002, help="UDP port (default 9002, ArduPilot's; 0: a free one, printed)")
    p.add_argument("--boat", metavar="BOAT.json|ideal",
                   help="the boat's coefficients (a params JSON; the lake boat's unmodelled effects stay), or 'ideal' "
                        "(the boat equals --params)")
    p.add_argument("--params", metavar="PARAMS.json", help="with --boat ideal: the model the boat equals")
    p.add_argument("--seed", type=SEED, help="seed of the boat's gusts and waves (default: the config's)")
    p.add_argument("--current", metavar="SPEED,DIR_DEG", help="current speed (m/s) and direction it flows TO (deg)")
    p.add_argument("--wind", metavar="SPEED,DIR_DEG", help="wind speed (m/s) and direction it comes FROM (deg)")
    p.add_argument("--waves", metavar="HS,TP,FROM_DEG[,S]", type=waves_flag,
                   help="a wind sea: significant height (m), peak period (s), the direction it comes FROM (deg), "
                        "optionally the spreading exponent (default 10; 0 long-crested)")
    p.add_argument("--duration", type=RUN_DURATION, help="stop after this many seconds (default: until Ctrl-C)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lotsen.cli.mission import parse_speed_dir
    from lotsen.cli.run import with_model_and_boat
    from lotsen.physics.server import PhysicsServer
    from lotsen.sim.plant import BoatPlant
    from lotsen.stack.config import load_stack_config
    from lotsen.stack.stack import sim_config, simulated_boat

    config = with_model_and_boat(load_stack_config(args.config), args.params, args.boat)
    if args.seed is not None:
        config = replace(config, seed=args.seed)
    sc = sim_config(config)
    env = sc.environment
    if args.current is not None or args.wind is not None:
        cur = parse_speed_dir(args.current, "current") if args.current else (env.current_speed_mps, env.current_to_deg)
        wind = parse_speed_dir(args.wind, "wind") if args.wind else (env.wind_speed_mps, env.wind_from_deg)
        env = replace(env, current_speed_mps=cur[0], current_to_deg=cur[1], wind_speed_mps=wind[0],
                      wind_from_deg=wind[1])
    if args.waves is not None:
        env = replace(env, waves=args.waves.waves())
    boat = simulated_boat(config)

    def make_plant() -> BoatPlant:
        return BoatPlant(boat, dt_s=sc.dt_s, seed=sc.seed, environment=env, wind=sc.wind,
                         x0=config.sim.initial_state)

    try:
        server = PhysicsServer(make_plant, config.extra.physics.servos, args.host, args.port)
    except OSError as exc:
        raise ConfigError(f"cannot listen on udp:{args.host}:{args.port}: {exc.strerror or exc}") from None
    stop = threading.Event()
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stop.set())
        signal.signal(signal.SIGINT, lambda *_: stop.set())
    if args.duration is not None:
        timer = threading.Timer(args.duration, stop.set)
        timer.daemon = True
        timer.start()
    host, port = server.address
    print(f"physics server: {boat.describe()}; current {env.current_speed_mps:g} m/s to {env.current_to_deg:g} deg, "
          f"wind {env.wind_speed_mps:g} m/s from {env.wind_from_deg:g} deg; "
          f"{'waves ' + env.waves.describe() if env.wavy else 'calm water'}; seed {sc.seed}; step {sc.dt_s:g} s; "
          f"listening on udp:{host}:{port}", flush=True)
    try:
        server.serve(stop)
    finally:
        server.close()
    print(f"physics server stopped: {server.status()}", flush=True)
    return 0
