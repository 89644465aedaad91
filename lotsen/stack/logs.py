"""Attach the recorder and the Foxglove live server to a `lotsen.stack.launch.Stack`.

Wiring (by the lead, in lotsen/runtime/nodes/parts.py or launch):

    from lotsen.stack.logs import add_recorder, add_foxglove_server
    register_part("logs", add_recorder)                      # records when config.logging.enabled
    # `lotsen run --foxglove [PORT]`:  add_foxglove_server(stack, "127.0.0.1", port)

Settings beyond `logging: {enabled, directory}` are `extra.logs` (keys of `RecorderConfig`, e.g.
`{flush_period_s: 0.5, fsync: true, compression: zstd}`), typed with the rest of the config
(`lotsen.stack.config.ExtraConfig.logs`).
"""

from __future__ import annotations

import dataclasses
import json
import sys
from typing import Any, Callable

from lotsen.errors import LotsenError
from lotsen.logs.live import FoxgloveLive
from lotsen.logs.recorder import McapRecorder, RecorderConfig, ensure_log_directory
from lotsen.logs.recover import recover_directory
from lotsen.messages import OperatorCommand, Topic
from lotsen.planning import GeoOrigin
from lotsen.stack.config import StackConfig
from lotsen.runtime.executor import Node, NodeContext


class LoggingControlNode(Node):
    """Logging on/off from the operator (OperatorCommand logging_on / logging_off), a warning on
    the `log` topic when the recorder has to drop messages (disk too slow), and the recorder's
    status once a second (RecorderStatus on logs/status: free space, a write failure and what it
    kept), which the supervisor's storage check and the page read. A write failure is said once on
    the `log` topic and on the console."""

    name = "logging"

    def __init__(self, recorder: McapRecorder, check_period_s: float = 2.0, status_period_s: float = 1.0,
                 console: Callable[[str], None] | None = None) -> None:
        self.recorder = recorder
        self.check_period_s = check_period_s
        self.status_period_s = status_period_s
        self.console = console or (lambda line: print(line, file=sys.stderr, flush=True))
        self._reported_drops = 0
        self._reported_failure = ""

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        ctx.add_timer(self.check_period_s, self._check)
        ctx.add_timer(self.status_period_s, self._status)

    def _status(self) -> None:
        st = self.recorder.status(self.ctx.now())
        self.ctx.publish(Topic.RECORDER, st)
        if st.error and st.error != self._reported_failure:
            self._reported_failure = st.error
            text = f"recording stopped: {st.error}; kept: {st.kept}"
            self.ctx.log("error", text, kept=st.kept)
            self.console(f"lotsen recorder: error: {text}")

    def _on_operator(self, cmd: OperatorCommand) -> None:
        if cmd.action == "logging_on" and self._failed():  # a file that failed: a new one
            self.recorder.stop()
        if cmd.action == "logging_on" and not self.recorder.recording:
            try:
                path = self.recorder.start()
            except (LotsenError, OSError) as exc:  # a full or read-only disk: said, not a crash
                self.ctx.log("error", f"logging on failed: {exc}")
                return
            self.ctx.log("info", f"logging on: {path}", path=str(path))
        elif cmd.action == "logging_off" and self.recorder.recording:
            stats = self.recorder.stop()
            # the log event is published after the file is closed: it is not in that file
            self.ctx.log("info", f"logging off: {stats.path} ({stats.written} messages, {stats.dropped} dropped)",
                         path=stats.path, written=stats.written, dropped=stats.dropped)

    def _failed(self) -> bool:
        s = self.recorder.stats
        return s is not None and bool(s.failed)

    def _check(self) -> None:
        s = self.recorder.stats
        if s is None:
            return
        if s.dropped > self._reported_drops:
            self.ctx.log("warning", f"recorder dropped {s.dropped - self._reported_drops} messages (disk too slow?)",
                         dropped_total=s.dropped)
            self._reported_drops = s.dropped

    def stop(self) -> None:
        self.recorder.close()


def recorder_config(config: StackConfig, origin: GeoOrigin | None = None) -> RecorderConfig:
    """`extra.logs` (else the defaults in `logging.directory`), with the stack's one local-frame
    origin for the map views (none on a boat without a configured `origin`: no map views)."""
    rc = config.extra.logs or RecorderConfig(directory=config.logging.directory)
    geo = (origin.lat_deg, origin.lon_deg, origin.height_m) if origin is not None else None
    return dataclasses.replace(rc, geo_origin=geo)


def _redacted(config: dict) -> dict:
    """The launch config for the log's metadata, without the pilot token (never in logs)."""
    web = dict(config.get("web", {}))
    if web.get("pilot_token"):
        web["pilot_token"] = "<redacted>"
    return {**config, "web": web}


def add_recorder(stack: Any, config: RecorderConfig | None = None, start: bool | None = None) -> McapRecorder:
    """Record every topic of `stack` to MCAP. Starts a file now if `start` (default:
    `config.logging.enabled`); logging_on / logging_off operator actions switch it at run time."""
    rc = config or recorder_config(stack.config, stack.origin)
    clock = stack.executor.clock
    meta = {"mode": stack.config.mode, "seed": str(stack.config.seed),
            "launch_config": json.dumps(_redacted(dataclasses.asdict(stack.config)), default=str)}
    if stack.config.mode == "sim":  # which boat the log is of: identify names it in its report
        from lotsen.stack.stack import boat_description

        meta["boat"] = boat_description(stack.config)
    rec = McapRecorder(rc, clock=clock.now, epoch_at_clock_zero=getattr(clock, "epoch_at_start", None), metadata=meta)
    rec.attach(stack.bus)
    stack.add(LoggingControlNode(rec))
    stack.services["recorder"] = rec
    stack.services.setdefault("on_shutdown", []).append(rec.close)
    if stack.config.logging.enabled if start is None else start:
        # a folder that cannot exist (under a file, no permission) is the configuration's error, said at
        # once; a disk that is full or fails when the file is written is a failure the run survives
        ensure_log_directory(rec.config.directory)
        try:
            path = rec.start()
            stack.services.setdefault("banner", []).append(f"logging: recording to {path}")
        except LotsenError as exc:  # a full or read-only disk: the run goes on, the status says why
            stack.services.setdefault("banner", []).append(f"logging: cannot record: {exc}")
    else:
        stack.services.setdefault("banner", []).append("logging: off (operator action logging_on starts a file)")
    return rec


def add_foxglove_server(stack: Any, host: str = "127.0.0.1", port: int = 8765) -> FoxgloveLive:
    """A Foxglove WebSocket server streaming the stack's topics live (port 0: any free port)."""
    o = stack.origin
    geo = (o.lat_deg, o.lon_deg, o.height_m) if o is not None else None
    live = FoxgloveLive(stack.bus, host=host, port=port, geo_origin=geo)
    stack.services["foxglove"] = live
    stack.services.setdefault("on_shutdown", []).append(live.stop)
    stack.services.setdefault("banner", []).append(f"foxglove: live at {live.url} (Foxglove > Open connection)")
    return live


def recover_unclosed_logs(config: StackConfig) -> list[str]:
    """At the start of a run: recover the log directory's files a killed run left unclosed
    (lotsen.logs.recover), and say what was done, one line per file. With logging enabled, a
    log directory that cannot be created or written is a ConfigError naming it, here in the
    launching process, not a traceback in the recorder's process."""
    if not config.logging.directory:
        return []
    directory = recorder_config(config).directory
    if config.logging.enabled:
        ensure_log_directory(directory)
    return [f"logging: recovered an unclosed log: {s.summary_line()}" for s in recover_directory(directory)]
