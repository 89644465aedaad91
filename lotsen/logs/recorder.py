"""MCAP recorder: every topic of a run, one JSON-schema channel per (topic, message type), plus
Foxglove well-known views (`foxglove_views`).

The control loop only pays for a deque append: the bus callback puts (receipt time, message) in
a bounded queue (drop-oldest, counted), and a writer thread encodes, writes and flushes. Every
`flush_period_s` (0.5 s) the writer closes the MCAP chunk in progress and flushes (and by default
fsyncs) the file, so a killed process or a power cut loses at most about the last second; such a
file has no summary/footer and `LogReader` still reads it. Files: `<dir>/<date>_<time>_runNNN.mcap`.
Messages received from another process (`on_envelopes`, the recorder process of `lotsen run`) are
written as they came: the envelope's JSON payload is the channel's data (the bytes `encode_json`
makes of the message), and it is decoded only for a Foxglove view.

Times: MCAP `log_time` is the receipt time on the runtime's clock mapped to Unix epoch
nanoseconds (epoch at start + clock seconds), `publish_time` the message's `stamp_s` mapped the
same way (log_time when the stamp is not finite), so Foxglove shows wall time and sim runs stay
in simulated-time order.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import re
import threading
import time
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Callable, Literal

from lotsen.errors import ConfigError
from lotsen.logs import foxglove_views
from lotsen.messages import RecorderStatus
from lotsen.runtime.bus import BoundedQueue, Bus
from lotsen.transport import codec
from lotsen.settings import value_range as _r

LOG_FORMAT_VERSION = "1"
PROFILE = ""  # no MCAP profile: JSON and protobuf channels
_RUN_RE = re.compile(r"_run(\d+)(?:\.recovered)?\.mcap$")  # recovered runs keep their number


@dataclass(frozen=True)
class RecorderConfig:
    """Recorder settings (`extra.logs` in the launch config). The ranges are checked by
    `from_mapping` (the error names the key) and again here for direct construction."""

    directory: str = "logs"
    # ~10 s of the sim stack's ~1.5 k msg/s before drop-oldest; 0 would silently record nothing
    queue_maxlen: int = field(default=20000, metadata=_r(1, 10_000_000))
    # chunk closed and file flushed this often (a crash loses <= ~2 flush periods)
    flush_period_s: float = field(default=0.5, metadata=_r(0.01, 60.0))
    fsync: bool = True  # survive a power cut too, not only a killed process
    compression: Literal["zstd", "lz4", "none"] = "zstd"
    # upper bound; chunks are normally closed by the flush period
    chunk_size: int = field(default=4 * 1024 * 1024, metadata=_r(1024, 1 << 30))
    foxglove_views: bool = True
    topics: tuple[str, ...] | None = None  # None: every topic
    geo_origin: tuple[float, float, float] | None = None  # lat, lon, h of the NED origin (map view of the estimate)

    def __post_init__(self) -> None:
        where = "recorder"
        if not isinstance(self.directory, (str, os.PathLike)) or not str(self.directory).strip():
            raise ConfigError(f"{where}.directory: expected a directory name, got {self.directory!r}")
        for f in fields(self):
            rng = f.metadata.get("range")
            v = getattr(self, f.name)
            if rng is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and rng[0] <= v <= rng[1]):
                raise ConfigError(f"{where}.{f.name}: {v!r} outside the allowed range [{rng[0]}, {rng[1]}]")
        if self.compression not in ("zstd", "lz4", "none"):
            raise ConfigError(f"{where}.compression: {self.compression!r} is not one of zstd, lz4, none")
        if self.geo_origin is not None:
            lat, lon, h = self.geo_origin
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and math.isfinite(h)):
                raise ConfigError(f"{where}.geo_origin: latitude {lat!r} / longitude {lon!r} / height {h!r} "
                                  "out of range ([-90, 90], [-180, 180], finite)")


@dataclass
class RecorderStats:
    path: str = ""
    received: int = 0
    written: int = 0
    views_written: int = 0
    dropped: int = 0
    encode_errors: int = 0
    flushes: int = 0
    bytes: int = 0
    last_error: str = ""
    per_topic: dict[str, int] = field(default_factory=dict)
    # a write failure (the disk full or failing): recording stops at the first one, and the file
    # keeps what the last good flush put on disk (`kept_bytes`, messages up to `kept_until_s`)
    failed: str = ""
    kept_bytes: int = 0
    kept_until_s: float = math.nan  # runtime clock seconds of the last message flushed to disk

    def kept(self) -> str:
        """What is safe on disk after a failure, in the operator's words."""
        until = f" up to {self.kept_until_s:.1f} s of the run" if math.isfinite(self.kept_until_s) else ""
        return (f"{Path(self.path).name}{until} ({self.kept_bytes / 1e3:.0f} kB on disk, readable; "
                f"`lotsen recover` indexes it)")


def next_log_path(directory: str | os.PathLike, when: float | None = None) -> Path:
    """`<directory>/YYYY-MM-DD_HH-MM-SS_runNNN.mcap`, NNN one above the highest run in the directory."""
    d = Path(directory)
    runs = [int(m.group(1)) for p in d.glob("*_run*.mcap") if (m := _RUN_RE.search(p.name))] if d.is_dir() else []
    stamp = _dt.datetime.fromtimestamp(time.time() if when is None else when).strftime("%Y-%m-%d_%H-%M-%S")
    return d / f"{stamp}_run{max(runs, default=0) + 1:03d}.mcap"


#: how long the writer thread lets messages gather before it writes them: a wake-up of the writer
#: costs more than writing a message, and the file is flushed only every flush period anyway
#: (0.5 s by default: a message reaches the disk at most about WRITE_BATCH_S + flush_period_s late)
WRITE_BATCH_S = 0.2


class _Session:
    """One open file and its writer thread."""

    def __init__(self, path: Path, config: RecorderConfig, epoch0_ns: int, metadata: dict[str, str]) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = path
        self.config = config
        self.epoch0_ns = epoch0_ns
        self.queue = BoundedQueue(config.queue_maxlen)
        self.stats = RecorderStats(path=str(path))
        self._stop = threading.Event()
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
        if config.compression not in comp:
            raise ConfigError(f"logging: compression {config.compression!r} is not one of {', '.join(comp)}")
        self._file = _open_log_file(path)
        _lock_for_writing(self._file)
        self._writer = Writer(self._file, chunk_size=config.chunk_size, compression=comp[config.compression])
        from lotsen import __version__

        self._channels: dict[tuple[str, str], int] = {}
        self._schemas: dict[str, int] = {}
        self._last_t_s = math.nan
        self._views = foxglove_views.ViewMaker(config.geo_origin) if (
            config.foxglove_views and foxglove_views.available()) else None
        try:  # the header: a full disk already fails here; the run goes on, the failure is reported
            self._writer.start(profile=PROFILE, library=f"lotsen {__version__}")
            self._writer.add_metadata("lotsen", {"log_format_version": LOG_FORMAT_VERSION, "lotsen_version": __version__,
                                                 "start_epoch_ns": str(epoch0_ns), **metadata})
            self._writer.flush()
            self.stats.bytes = self.stats.kept_bytes = self._file.tell()
        except OSError as exc:
            self._fail("starting", exc)
        self._thread = threading.Thread(target=self._run, name=f"mcap-writer-{path.name}", daemon=True)
        self._thread.start()

    # -- writer thread
    def _schema_id(self, name: str, encoding: str, data: Callable[[], bytes]) -> int:
        sid = self._schemas.get(name)
        if sid is None:
            sid = self._schemas[name] = self._writer.register_schema(name, encoding, data())
        return sid

    def _channel_id(self, topic: str, schema: str, schema_encoding: str, schema_data: Callable[[], bytes],
                    message_encoding: str) -> int:
        key = (topic, schema)
        cid = self._channels.get(key)
        if cid is None:
            sid = self._schema_id(schema, schema_encoding, schema_data)
            cid = self._channels[key] = self._writer.register_channel(topic, message_encoding, sid)
        return cid

    def _write(self, topic: str, t_s: float, msg: Any) -> None:
        cls = type(msg)
        if cls.__name__ not in codec.MESSAGE_TYPES:
            self.stats.encode_errors += 1
            self.stats.last_error = f"{topic}: {cls.__name__} is not a lotsen message; not recorded"
            return
        stamp = getattr(msg, "stamp_s", math.nan)
        self._add(topic, t_s, cls, codec.encode_json(msg), stamp if isinstance(stamp, float) else math.nan,
                  lambda: msg)

    def _write_envelope(self, topic: str, t_s: float, env: codec.Envelope) -> None:
        """A message as it came over the wire: its JSON payload is the channel's data as it is
        (the same bytes `codec.encode_json` makes of the message); decoded only for a Foxglove
        view. A CDR payload is decoded and written as JSON."""
        if env.encoding != codec.ENC_JSON:
            self._write(topic, t_s, codec.decode_envelope(env))
            return
        cls = codec.message_class(env.type_name)
        payload = env.payload
        self._add(topic, t_s, cls, payload, codec.json_stamp_s(payload), lambda: codec.decode_json(cls, payload))

    def _add(self, topic: str, t_s: float, cls: type, data: bytes, stamp_s: float, message: Callable[[], Any]) -> None:
        """Write one message's JSON `data` on its channel, and its Foxglove views (`message()`
        gives the message itself, asked for only when the topic has a view)."""
        log_ns = self.epoch0_ns + int(round(t_s * 1e9))
        pub_ns = self.epoch0_ns + int(round(stamp_s * 1e9)) if math.isfinite(stamp_s) else log_ns
        cid = self._channel_id(topic, codec.schema_name(cls), "jsonschema",
                               lambda: json.dumps(codec.json_schema(cls)).encode(), "json")
        self._writer.add_message(cid, log_time=log_ns, data=data, publish_time=pub_ns)
        self.stats.written += 1
        self.stats.per_topic[topic] = self.stats.per_topic.get(topic, 0) + 1
        if self._views is not None and self._views.handles(topic):
            for v in self._views.views(topic, message(), log_ns):
                cid = self._channel_id(v.topic, v.schema_name, *_schema_args(v.schema_name), v.encoding)
                self._writer.add_message(cid, log_time=log_ns, data=v.data, publish_time=log_ns)
                self.stats.views_written += 1

    def _flush(self) -> None:
        self._writer.flush()
        if self.config.fsync:
            os.fsync(self._file.fileno())
        self.stats.flushes += 1
        self.stats.bytes = self.stats.kept_bytes = self._file.tell()
        self.stats.kept_until_s = self._last_t_s

    def _fail(self, what: str, exc: OSError) -> None:
        """A write failure (ENOSPC, EIO): record no more into this file (the writer's state is
        no longer the file's), say so once; what the last flush put on disk stays readable."""
        if not self.stats.failed:
            self.stats.failed = f"{what} {self.path}: {exc.strerror or exc}"
            self.stats.last_error = self.stats.failed

    def _run(self) -> None:
        last_flush = time.monotonic()
        dirty = False
        while True:
            stopping = self._stop.is_set()
            item = self.queue.get(timeout=WRITE_BATCH_S)
            if item is not None and not stopping:
                # a moment for the rest of the burst: one wake-up per WRITE_BATCH_S, not one per
                # message (300+ a second from the core, each a thread switch with the bus)
                self._stop.wait(WRITE_BATCH_S)
            batch = [item] if item is not None else []
            batch += self.queue.get_all()
            if self.stats.failed:  # the disk failed: nothing more goes into this file
                self.stats.dropped += len(batch)
                batch = []
            for topic, (t_s, msg) in batch:
                try:
                    if isinstance(msg, codec.Envelope):
                        self._write_envelope(topic, t_s, msg)
                    else:
                        self._write(topic, t_s, msg)
                    dirty = True
                    self._last_t_s = t_s
                except OSError as exc:  # the disk, not the message (a chunk filled up and was written)
                    self._fail("writing", exc)
                    break
                except Exception as exc:  # noqa: BLE001 - one bad message must not end the recording
                    self.stats.encode_errors += 1
                    self.stats.last_error = f"{topic}: {exc!r}"
            self.stats.dropped = max(self.stats.dropped, self.queue.dropped)
            now = time.monotonic()
            if dirty and not self.stats.failed and now - last_flush >= self.config.flush_period_s:
                try:
                    self._flush()
                except OSError as exc:
                    self._fail("flushing", exc)
                last_flush, dirty = now, False
            if stopping and not batch:
                break

    # -- control (any thread)
    def put(self, topic: str, t_s: float, msg: Any) -> None:
        self.stats.received += 1
        self.queue.put(topic, (t_s, msg))

    def put_many(self, t_s: float, items: list[tuple[str, Any]]) -> None:
        self.stats.received += len(items)
        self.queue.put_many([(topic, (t_s, msg)) for topic, msg in items])

    def close(self, timeout_s: float = 10.0) -> RecorderStats:
        self._stop.set()
        self._thread.join(timeout_s)
        self.stats.dropped = max(self.stats.dropped, self.queue.dropped)
        if self.stats.failed:  # a failed disk: leave the file as the last flush made it (recoverable)
            try:
                self._file.close()
            except OSError:
                pass
            return self.stats
        try:
            s = self.stats
            self._writer.add_metadata("lotsen_stats", {
                "received": str(s.received), "written": str(s.written), "dropped": str(s.dropped),
                "encode_errors": str(s.encode_errors), "last_error": s.last_error})
            self._writer.finish()  # summary + footer: an indexed file (field note 11)
            self._file.flush()
            if self.config.fsync:
                os.fsync(self._file.fileno())
            self.stats.bytes = self._file.tell()
        except OSError as exc:  # disk full or gone at shutdown: the file stays unclosed (`lotsen recover`)
            self.stats.last_error = f"closing {self.path}: {exc.strerror or exc}"
        finally:
            try:
                self._file.close()
            except OSError:
                pass
        return self.stats


def ensure_log_directory(directory: str | os.PathLike) -> Path:
    """Create the log directory if needed and check that files can be made in it; a ConfigError
    naming it instead of an OSError (`lotsen run` calls this before any process starts)."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ConfigError(f"logging.directory {str(d)!r}: exists and is not a directory")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"logging.directory {str(d)!r}: cannot create the log directory: "
                          f"{exc.strerror or exc}") from None
    if not os.access(d, os.W_OK | os.X_OK):
        raise ConfigError(f"logging.directory {str(d)!r}: no permission to create files in it")
    return d


def _open_log_file(path: Path):  # noqa: ANN202 - a binary file object
    """Create the directory and the file; a ConfigError naming them instead of an OSError."""
    d = ensure_log_directory(path.parent)
    try:
        return open(path, "wb")
    except OSError as exc:
        raise ConfigError(f"logging.directory {str(d)!r}: cannot create log file {path.name}: "
                          f"{exc.strerror or exc}") from None


def _lock_for_writing(f: Any) -> None:
    """An advisory lock held while the file is written, so `recover_directory` leaves a file that
    another process is still recording alone (a killed writer's lock goes with it)."""
    try:
        import fcntl

        fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except (ImportError, OSError):  # no fcntl (Windows) or a file system without locks
        pass


def _schema_args(name: str) -> tuple[str, Callable[[], bytes]]:
    enc, data = foxglove_views.schema_of(name)
    return enc, lambda: data


class McapRecorder:
    """Records a bus to MCAP files. `attach(bus)` once; `start()` / `stop()` open and close files
    (logging on / off at run time); `close()` at shutdown. Thread-safe control."""

    def __init__(self, config: RecorderConfig = RecorderConfig(), clock: Callable[[], float] | None = None,
                 epoch_at_clock_zero: float | None = None, metadata: dict[str, str] | None = None) -> None:
        self.config = config
        self._clock = clock or time.monotonic
        if epoch_at_clock_zero is None:
            epoch_at_clock_zero = time.time() - self._clock()
        self._epoch0_ns = int(epoch_at_clock_zero * 1e9)
        self._metadata = dict(metadata or {})
        self._session: _Session | None = None
        self.start_error = ""  # the last start() that could not even create its file
        self._lock = threading.Lock()
        self._unsubscribe: Callable[[], None] | None = None
        self._topics = frozenset(config.topics) if config.topics is not None else None
        self.closed_files: list[RecorderStats] = []

    # bus side: called on the control thread for every message -> must stay cheap
    def on_message(self, topic: str, msg: Any) -> None:
        session = self._session
        if session is None or (self._topics is not None and topic not in self._topics):
            return
        session.put(topic, self._clock(), msg)

    def on_envelopes(self, items: list[tuple[str, codec.Envelope]]) -> None:
        """Messages as received from another process, (topic, envelope) each
        (`ZenohBridge.forward_encoded`): recorded without decoding them, with one receipt time
        and one queue operation for the lot (any thread)."""
        session = self._session
        if session is None:
            return
        if self._topics is not None:
            items = [item for item in items if item[0] in self._topics]
        session.put_many(self._clock(), items)

    def attach(self, bus: Bus) -> "McapRecorder":
        if self._unsubscribe is None:
            self._unsubscribe = bus.subscribe_all(self.on_message)
        return self

    def detach(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    @property
    def recording(self) -> bool:
        return self._session is not None

    @property
    def path(self) -> Path | None:
        s = self._session
        return s.path if s else None

    @property
    def stats(self) -> RecorderStats | None:
        s = self._session
        return s.stats if s else None

    def status(self, now_s: float) -> RecorderStatus:
        """Where the recorder writes and how that goes (`RecorderStatus`, for the storage check
        and the page): the free space of the log directory, a write failure and what it kept."""
        s = self._session
        last = s.stats if s is not None else (self.closed_files[-1] if self.closed_files else None)
        free = total = -1
        try:
            st = os.statvfs(self.config.directory)
            free, total = st.f_bavail * st.f_frsize, st.f_blocks * st.f_frsize
        except OSError:
            pass
        failed = last.failed if last is not None else ""
        if s is None and self.start_error:
            failed = self.start_error
        return RecorderStatus(stamp_s=now_s, directory=str(Path(self.config.directory).resolve()),
                              free_bytes=free, total_bytes=total, recording=s is not None and not failed,
                              file=s.path.name if s is not None else "",
                              written_bytes=s.stats.bytes if s is not None else 0,
                              error=failed, kept=last.kept() if failed and last is not None else
                              ("nothing (no file could be made)" if failed else ""))

    def start(self, path: str | os.PathLike | None = None) -> Path:
        """Open a new file (named by date and run unless `path`) and record into it. A directory
        or file that cannot be created is a ConfigError naming it."""
        with self._lock:
            if self._session is not None:
                return self._session.path
            try:
                p = Path(path) if path is not None else next_log_path(self.config.directory)
            except OSError as exc:  # an unreadable directory
                raise ConfigError(f"logging.directory {self.config.directory!r}: {exc.strerror or exc}") from None
            try:
                self._session = _Session(p, self.config, self._epoch0_ns, self._metadata)
            except ConfigError as exc:
                self.start_error = str(exc)
                raise
            self.start_error = ""
            return p

    def stop(self) -> RecorderStats | None:
        """Finish the current file (indexed, with summary); None if not recording."""
        with self._lock:
            s, self._session = self._session, None
        if s is None:
            return None
        stats = s.close()
        self.closed_files.append(stats)
        return stats

    def close(self) -> None:
        self.stop()
        self.detach()
