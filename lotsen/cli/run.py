"""`lotsen run`: the whole stack, on the simulated boat (default) or the hardware, at wall-clock pace."""

from __future__ import annotations

import argparse
import signal
import threading
from dataclasses import replace

from lotsen.runtime.config import load_config
from lotsen.runtime.launch import build_stack, summary


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the full stack (simulated boat by default)")
    p.add_argument("config", nargs="?", help="launch config YAML (default: built-in defaults)")
    p.add_argument("--sim", action="store_true", help="simulated boat (the default)")
    p.add_argument("--hardware", action="store_true", help="real drivers (on the boat)")
    p.add_argument("--emulated", action="store_true", help="with --hardware: emulated devices speaking the real protocols")
    p.add_argument("--host", help="web bind address (default from config: 127.0.0.1)")
    p.add_argument("--port", type=int, help="web port (default from config: 8080)")
    p.add_argument("--duration", type=float, help="stop after this many seconds (default: run until Ctrl-C)")
    p.add_argument("--seed", type=int, help="random seed of the simulation")
    p.add_argument("--foxglove", nargs="?", type=int, const=8765, metavar="PORT",
                   help="also stream every topic to Foxglove (WebSocket, default port 8765)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = load_config(args.config)
    if args.hardware:
        config = replace(config, mode="hardware", extra={**config.extra, "emulated": bool(args.emulated)})
    web = config.web
    if args.host is not None or args.port is not None:
        web = replace(web, host=args.host or web.host, port=args.port if args.port is not None else web.port)
    config = replace(config, web=web, seed=args.seed if args.seed is not None else config.seed)
    stack = build_stack(config, realtime=True)
    if args.foxglove is not None:
        from lotsen.logs.part import add_foxglove_server

        add_foxglove_server(stack, config.web.host, args.foxglove)
    print(f"lotsen: {config.mode} stack with nodes: {', '.join(stack.nodes)}", flush=True)
    for line in stack.services.get("banner", []):
        print(line, flush=True)
    stack.executor.add_timer(5.0, lambda: print(summary(stack), flush=True), "console")
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: stack.executor.stop())
    try:
        stack.executor.run(args.duration)
    except KeyboardInterrupt:
        pass
    finally:
        stack.executor.stop()
        for close in stack.services.get("on_shutdown", []):
            close()
    print(summary(stack))
    return 0
