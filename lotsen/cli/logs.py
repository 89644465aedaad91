"""`lotsen replay`, `lotsen export`, `lotsen record`: MCAP logs of runs (docs/logs.md)."""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from pathlib import Path

from lotsen.errors import DataError, LotsenError
from lotsen.settings import PORT, RUN_DURATION, Number

def _add_zenoh_args(p: argparse.ArgumentParser, default_vessel: str) -> None:
    g = p.add_argument_group("Zenoh (multi-process / multi-machine)")
    g.add_argument("--vessel", default=default_vessel, help=f"our name in keys lotsen/<vessel>/<topic> (default {default_vessel})")
    g.add_argument("--listen", action="append", default=[], metavar="ENDPOINT", help="e.g. tcp/127.0.0.1:7447 (repeatable)")
    g.add_argument("--connect", action="append", default=[], metavar="ENDPOINT", help="e.g. tcp/192.168.4.1:7447 (repeatable)")
    g.add_argument("--mode", choices=("peer", "client", "router"), default="peer")
    g.add_argument("--multicast-scouting", action="store_true", help="allow multicast discovery (off by default)")
    g.add_argument("--json", action="store_true", help="encode everything as JSON (default: ROS 2 CDR where a type fits)")


def _bridge_config(args: argparse.Namespace, publish: tuple[str, ...], subscribe: tuple[str, ...]):
    from lotsen.transport.zenoh_bridge import BridgeConfig

    return BridgeConfig(vessel=args.vessel, mode=args.mode, listen=tuple(args.listen), connect=tuple(args.connect),
                        publish=publish, subscribe=subscribe, multicast_scouting=args.multicast_scouting,
                        encoding="json" if args.json else "auto")


def _topics(values: list[str] | None) -> list[str] | None:
    if not values:
        return None
    return [t for v in values for t in v.split(",") if t]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="re-publish a log on the bus (and to Foxglove / Zenoh)")
    p.add_argument("log", help="RUN.mcap")
    p.add_argument("--speed", type=Number(0.01, 1000.0), default=1.0, help="replay speed factor (default 1.0)")
    p.add_argument("--topics", nargs="+", help="only these topics (default: all recorded lotsen topics)")
    p.add_argument("--exclude", nargs="+", default=[], help="topics not to replay")
    p.add_argument("--restamp", action="store_true", help="shift stamp_s to the replay clock")
    p.add_argument("--fast", action="store_true", help="simulated time: as fast as possible (with --record)")
    p.add_argument("--foxglove", type=PORT, nargs="?", const=8765, metavar="PORT", help="serve live to Foxglove (default port 8765)")
    p.add_argument("--record", metavar="DIR", help="record what is replayed (e.g. with re-run nodes) to DIR")
    _add_zenoh_args(p, "replay")
    p.set_defaults(func=replay)

    e = sub.add_parser("export", help="write the topics of a log as tables (CSV), and sysid.csv")
    e.add_argument("log", help="RUN.mcap")
    e.add_argument("--topics", nargs="+", help="topics to export (default: all)")
    e.add_argument("--out", help="output directory")
    e.add_argument("--format", choices=("csv", "parquet"), default="csv", help="parquet needs pyarrow (not installed)")
    e.add_argument("--sysid", choices=("auto", "raw", "estimate", "truth", "none"), default="auto",
                   help="outputs of DIR/sysid.csv (asynchronous form, docs/sysid.md): raw (GNSS position, IMU yaw "
                        "rate, heading of the estimate), state/estimate, sim/truth, auto (raw if the log has GNSS, "
                        "IMU and an estimate, else estimate, else truth), none")
    e.add_argument("--sysid-inputs", choices=("auto", "achieved", "command"), default="auto",
                   help="inputs of sysid.csv: achieved actuators/state, ship_command, auto (achieved if present)")
    e.add_argument("--info", action="store_true", help="only print what the log holds")
    e.add_argument("--ros2", metavar="BAG_DIR", help="write a ROS 2 bag (rosbag2 + MCAP, ros2msg/cdr) that "
                   "`ros2 bag info/play` accept, instead of the tables")
    e.add_argument("--namespace", default="", help="with --ros2: ROS namespace of every topic (e.g. /boat)")
    e.add_argument("--depth-cell", type=Number(0.05, 100.0, "m"), metavar="M",
                   help="cell of the depth map written when the log has soundings (default: the survey's line "
                        "spacing, else 1 m)")
    e.set_defaults(func=export)

    r = sub.add_parser("record", help="record topics received over Zenoh to MCAP (shore side)")
    r.add_argument("--out", default="logs", help="directory of the MCAP files (default logs)")
    r.add_argument("--subscribe", nargs="+", default=["*/**"], help="key patterns under lotsen/ (default */**)")
    r.add_argument("--duration", type=RUN_DURATION, help="stop after this many seconds (default: until Ctrl-C)")
    _add_zenoh_args(r, "shore")
    r.set_defaults(func=record)


def _print_problems(reader_problems: list) -> None:
    for p in reader_problems:
        print(f"warning: {p}", file=sys.stderr)


def export(args: argparse.Namespace) -> int:
    from lotsen.logs.export import check_format, export_topics, sysid_record
    from lotsen.sysid.data import save_csv
    from lotsen.logs.reader import LogReader

    reader = LogReader(args.log)
    if args.info:
        s = reader.summary()
        print(f"{s.path}: {s.messages} messages over {s.duration_s:.1f} s, "
              f"{'complete' if s.complete else 'INCOMPLETE (no footer)'}")
        for topic, n in sorted(s.per_topic.items()):
            print(f"  {topic:32s} {n:8d}")
        _print_problems(reader.problems)
        return 0
    if args.ros2:
        from lotsen.logs.ros2 import export_ros2

        result = export_ros2(args.log, args.ros2, namespace=args.namespace, topics=_topics(args.topics))
        print(f"ROS 2 bag {result.bag_dir}: {result.messages} messages on {len(result.topics)} topics"
              + (f", {result.errors} not convertible" if result.errors else ""))
        for topic, (ros_type, n) in sorted(result.topics.items()):
            print(f"  {topic:36s} {ros_type:40s} {n:8d}")
        return 0
    if not args.out:
        raise LotsenError("export: --out DIR is required (or --info, or --ros2 BAG_DIR)")
    check_format(args.format)
    problems: list = []
    files = export_topics(args.log, args.out, _topics(args.topics), args.format, problems)
    for topic, f in files.items():
        print(f"{topic} -> {f}")
    from lotsen.cli.depthmap import export_depth_map

    for line in export_depth_map(args.log, args.out, getattr(args, "depth_cell", None)):
        print(line)
    if args.sysid != "none":
        try:
            rec = sysid_record(args.log, outputs=args.sysid, inputs=args.sysid_inputs)
            save_csv(rec, Path(args.out) / "sysid.csv", (args.log,))
            print(f"sysid.csv: {len(rec.t)} rows, asynchronous ({rec.source}) -> {Path(args.out) / 'sysid.csv'}")
        except DataError as exc:
            if args.sysid != "auto":
                raise
            print(f"sysid.csv not written: {exc}", file=sys.stderr)
    _print_problems(problems)
    return 0


def _run_executor(executor, duration: float | None, stop_when=None) -> None:
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *_: executor.stop())
    if stop_when is not None:
        executor.add_timer(0.1, lambda: executor.stop() if stop_when() else None, "replay-end")
    try:
        executor.run(duration)
    except KeyboardInterrupt:
        pass
    finally:
        executor.stop()


def replay(args: argparse.Namespace) -> int:
    from lotsen.logs.replay import ReplayNode
    from lotsen.runtime import RealtimeExecutor, SimExecutor

    node = ReplayNode(args.log, speed=args.speed, topics=_topics(args.topics), exclude=_topics(args.exclude) or (),
                      restamp=args.restamp)
    executor = SimExecutor() if args.fast else RealtimeExecutor()
    closers = []
    if args.record:
        from lotsen.logs.recorder import McapRecorder, RecorderConfig

        rec = McapRecorder(RecorderConfig(directory=args.record), clock=executor.clock.now).attach(executor.bus)
        print(f"recording to {rec.start()}")
        closers.append(rec.close)
    if args.foxglove is not None:
        from lotsen.logs.live import FoxgloveLive

        live = FoxgloveLive(executor.bus, port=args.foxglove)
        print(f"foxglove: live at {live.url}")
        closers.append(live.stop)
    if args.listen or args.connect:
        from lotsen.transport.zenoh_bridge import ZenohBridge

        bridge = ZenohBridge(_bridge_config(args, publish=("*",), subscribe=()))
        executor.add_node(bridge)
        closers.append(bridge.close)
    executor.add_node(node)
    try:
        if args.fast:
            while not node.finished:
                executor.run_for(10.0)
        else:
            _run_executor(executor, None, lambda: node.finished)
    finally:
        for c in closers:
            c()
    print(f"replayed {node.published} messages from {args.log}")
    _print_problems(node.reader.problems)
    return 0


def record(args: argparse.Namespace) -> int:
    from lotsen.logs.recorder import McapRecorder, RecorderConfig
    from lotsen.runtime import RealtimeExecutor
    from lotsen.transport.zenoh_bridge import ZenohBridge

    if not (args.listen or args.connect):
        raise LotsenError("record: give --connect ENDPOINT (the boat) or --listen ENDPOINT")
    executor = RealtimeExecutor()
    bridge = ZenohBridge(_bridge_config(args, publish=(), subscribe=tuple(args.subscribe)))
    executor.add_node(bridge)
    rec = McapRecorder(RecorderConfig(directory=args.out), clock=executor.clock.now,
                       epoch_at_clock_zero=executor.clock.epoch_at_start,
                       metadata={"recorded_via": "zenoh", "subscribe": ",".join(args.subscribe)}).attach(executor.bus)
    path = rec.start()
    print(f"recording {', '.join(args.subscribe)} to {path}", flush=True)
    try:
        _run_executor(executor, args.duration)
    finally:
        bridge.close()
        stats = rec.stop()
        rec.detach()
    print(f"{path}: {stats.written} messages ({stats.dropped} dropped)", flush=True)
    return 0
