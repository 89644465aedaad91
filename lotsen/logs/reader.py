"""Read lotsen MCAP logs back into `lotsen.messages` types.

`LogReader` walks the file record by record (it does not need the summary or footer), so a file
from a killed process reads up to its last complete chunk. Problems are `LogFileError`s (a
`DataError`) naming the file and the byte offset:

* `TruncatedLogError` - the file ends inside a record or has no footer (a crash or a full disk):
  everything before the offset is read; by default this is only reported (`reader.problems`).
* `CorruptLogError` - bad magic, a record with an impossible length, or a chunk whose CRC or
  decompression fails: a damaged chunk is skipped (reported) when the record framing is intact;
  otherwise reading stops there. `strict=True` raises at the first problem, after yielding what
  came before it.
"""

from __future__ import annotations

import io
import json
import os
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator

from lotsen.errors import DataError
from lotsen.files import MAX_LOG_BYTES, check_input_file
from lotsen.transport import codec

MAGIC = b"\x89MCAP0\r\n"
_MAX_RECORD = 1 << 31  # a record longer than 2 GiB is corruption in a lotsen log


class LogFileError(DataError):
    def __init__(self, path: str | os.PathLike, offset: int, reason: str) -> None:
        self.path, self.offset, self.reason = str(path), offset, reason
        super().__init__(f"{path}: {reason} at byte offset {offset}")


class TruncatedLogError(LogFileError):
    """The file ends early (no footer or a partial record): what precedes `offset` was read."""


class CorruptLogError(LogFileError):
    """A damaged record at `offset`."""


@dataclass(frozen=True)
class LogMessage:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    message: Any  # a lotsen.messages dataclass (or raw bytes for a non-lotsen channel when raw=True)
    schema: str
    encoding: str


@dataclass
class _Channel:
    topic: str
    encoding: str
    schema: str
    schema_encoding: str


@dataclass
class LogSummary:
    path: str
    messages: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    complete: bool = False
    problems: list[str] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return 0.0 if self.start_ns is None or self.end_ns is None else (self.end_ns - self.start_ns) / 1e9


class LogReader:
    """Iterate a log: `for topic, msg in LogReader(path).messages(topics=...)`.

    Only channels holding lotsen messages (schema `lotsen.*`, JSON) are decoded; the Foxglove views
    are skipped unless `raw=True` (then their bytes are yielded). Not thread-safe; re-iterable."""

    def __init__(self, path: str | os.PathLike, strict: bool = False) -> None:
        self.path = Path(path)
        self.strict = strict
        self.problems: list[LogFileError] = []
        self.metadata: dict[str, dict[str, str]] = {}
        self.complete = False
        self.undecodable = 0
        self.damaged_records = 0  # records inside an intact framing that do not parse (skipped)
        if not self.path.is_file():
            raise DataError(f"{self.path}: no such log file")
        check_input_file(self.path, MAX_LOG_BYTES, DataError, "log file")

    # ---------------------------------------------------------------- low level
    def _problem(self, err: LogFileError) -> None:
        self.problems.append(err)
        if self.strict:
            raise err

    def _records(self) -> Iterator[tuple[int, int, bytes]]:
        """(offset, opcode, body) of the top-level records, chunks opened into their records."""
        from mcap.opcode import Opcode

        self.problems, self.complete = [], False
        size = self.path.stat().st_size
        with open(self.path, "rb") as f:
            magic = f.read(8)
            if magic != MAGIC:
                raise CorruptLogError(self.path, 0, f"not an MCAP file (magic {magic[:8]!r})")
            pos = 8
            while True:
                head = f.read(9)
                if not head:
                    self._problem(TruncatedLogError(self.path, pos, "file ends without an MCAP footer "
                                                    "(recording interrupted); read up to here"))
                    return
                if len(head) < 9:
                    self._problem(TruncatedLogError(self.path, pos, f"partial record header ({len(head)} of 9 bytes)"))
                    return
                opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
                if opcode == 0 or length > _MAX_RECORD:
                    self._problem(CorruptLogError(self.path, pos, f"invalid record (opcode 0x{opcode:02x}, "
                                                  f"length {length}); reading stops"))
                    return
                if pos + 9 + length > size:
                    self._problem(TruncatedLogError(
                        self.path, pos, f"record (opcode 0x{opcode:02x}) needs {length} bytes, only "
                        f"{size - pos - 9} left in the file; read up to here"))
                    return
                body = f.read(length)
                if opcode == Opcode.CHUNK:
                    yield from self._chunk_records(pos, body)
                elif opcode == Opcode.FOOTER:
                    self.complete = True
                    return
                elif opcode == Opcode.DATA_END:
                    # summary section follows; nothing more to stream (footer proves completeness)
                    yield pos, opcode, body
                else:
                    yield pos, opcode, body
                pos += 9 + length

    def _chunk_records(self, pos: int, body: bytes) -> Iterator[tuple[int, int, bytes]]:
        from mcap.data_stream import ReadDataStream
        from mcap.records import Chunk

        try:
            chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
            if chunk.compression == "zstd":
                import zstandard

                data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
            elif chunk.compression == "lz4":
                import lz4.frame

                data = lz4.frame.decompress(chunk.data)
            elif chunk.compression == "":
                data = chunk.data
            else:
                raise ValueError(f"unsupported compression {chunk.compression!r}")
            if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
                raise ValueError("CRC mismatch")
        except Exception as exc:  # noqa: BLE001 - any failure inside a chunk = a damaged chunk
            self._problem(CorruptLogError(self.path, pos, f"damaged chunk ({exc}); chunk skipped"))
            return
        i = 0
        while i + 9 <= len(data):
            opcode, length = data[i], struct.unpack_from("<Q", data, i + 1)[0]
            if i + 9 + length > len(data):
                self._problem(CorruptLogError(self.path, pos, f"chunk record at +{i} overruns the chunk; rest skipped"))
                return
            yield pos, opcode, data[i + 9:i + 9 + length]
            i += 9 + length

    # ---------------------------------------------------------------- messages
    def iter_raw(self) -> Iterator[tuple[_Channel, int, int, bytes]]:
        """(channel, log_time_ns, publish_time_ns, data) in file order."""
        from mcap.opcode import Opcode

        schemas: dict[int, tuple[str, str]] = {}
        channels: dict[int, _Channel] = {}
        unknown_channels = 0
        self.damaged_records = 0
        for pos, opcode, body in self._records():
            if opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.METADATA):
                try:
                    self._definition(opcode, body, schemas, channels)
                except Exception as exc:  # noqa: BLE001 - any byte sequence: a damaged record, skipped and said
                    self.damaged_records += 1
                    self._problem(CorruptLogError(self.path, pos, f"damaged record (opcode 0x{opcode:02x}: "
                                                  f"{type(exc).__name__}); skipped"))
                continue
            if opcode == Opcode.MESSAGE:
                if len(body) < 22:
                    self._problem(CorruptLogError(self.path, pos, "message record too short"))
                    continue
                cid, _seq, log_ns, pub_ns = struct.unpack_from("<HIQQ", body, 0)
                ch = channels.get(cid)
                if ch is None:
                    unknown_channels += 1
                    continue
                yield ch, log_ns, pub_ns, body[22:]
            elif opcode == Opcode.DATA_END:
                self.complete = True  # (footer follows in the summary section)
        if unknown_channels:
            self.problems.append(CorruptLogError(self.path, -1, f"{unknown_channels} messages on channels whose "
                                                 "definition was lost (damaged chunk)"))

    def _definition(self, opcode: int, body: bytes, schemas: dict, channels: dict) -> None:
        """A schema, channel or metadata record into the tables of `iter_raw`."""
        from mcap.data_stream import ReadDataStream
        from mcap.opcode import Opcode
        from mcap.records import Channel, Metadata, Schema

        if opcode == Opcode.SCHEMA:
            s = Schema.read(ReadDataStream(io.BytesIO(body)))
            schemas[s.id] = (s.name, s.encoding)
        elif opcode == Opcode.CHANNEL:
            c = Channel.read(ReadDataStream(io.BytesIO(body)))
            name, enc = schemas.get(c.schema_id, ("", ""))
            channels[c.id] = _Channel(c.topic, c.message_encoding, name, enc)
        else:
            m = Metadata.read(ReadDataStream(io.BytesIO(body)))
            self.metadata[m.name] = dict(m.metadata)

    def read(self, topics: Iterable[str] | None = None, raw: bool = False) -> Iterator[LogMessage]:
        wanted = frozenset(topics) if topics is not None else None
        for ch, log_ns, pub_ns, data in self.iter_raw():
            if wanted is not None and ch.topic not in wanted:
                continue
            if ch.schema.startswith("lotsen.") and ch.encoding == "json" and ch.schema[7:] in codec.MESSAGE_TYPES:
                try:
                    msg = codec.decode_json(ch.schema[7:], data)
                except Exception as exc:  # noqa: BLE001 - DecodeError and whatever damaged bytes raise
                    self.undecodable += 1
                    if self.strict:
                        raise DataError(f"{self.path}: topic {ch.topic}: {exc}") from None
                    continue
                yield LogMessage(ch.topic, log_ns, pub_ns, msg, ch.schema, ch.encoding)
            elif raw:
                yield LogMessage(ch.topic, log_ns, pub_ns, data, ch.schema, ch.encoding)

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, Any]]:
        """(topic, lotsen message) in recording order."""
        for m in self.read(topics):
            yield m.topic, m.message

    def __iter__(self) -> Iterator[tuple[str, Any]]:
        return self.messages()

    def summary(self) -> LogSummary:
        s = LogSummary(str(self.path))
        for ch, log_ns, _pub, _data in self.iter_raw():
            s.messages += 1
            s.per_topic[ch.topic] = s.per_topic.get(ch.topic, 0) + 1
            s.start_ns = log_ns if s.start_ns is None else min(s.start_ns, log_ns)
            s.end_ns = log_ns if s.end_ns is None else max(s.end_ns, log_ns)
        s.metadata, s.complete = dict(self.metadata), self.complete
        s.problems = [str(p) for p in self.problems]
        return s


def read_log(path: str | os.PathLike, topics: Iterable[str] | None = None) -> list[tuple[str, Any]]:
    """All (topic, message) pairs of a log (tolerates a truncated tail)."""
    return list(LogReader(path).messages(topics))


def metadata_json(reader: LogReader) -> str:
    return json.dumps(reader.metadata, indent=2)
