"""Recover a recording that was never closed: a killed process, a power cut, a full disk.

Such a file has chunks but no summary and no footer, so a seeking reader (Foxglove,
`mcap.reader.make_reader(f).iter_messages()`, `mcap info`) refuses it (the mcap Python reader
says `RecordLengthLimitExceeded`: it takes the last bytes for a footer). `recover_mcap` reads the
file front to back, record by record, the way a stream reader does, and writes what it read as a
complete file: the same schemas, channels (with their metadata), messages (times and sequence
numbers), metadata and attachments, chunked and indexed, with a summary and a footer, plus a
`lotsen_recovery` metadata record that says what was done.

What is lost: only what never reached the disk, and a damaged record. The recorder flushes a
closed chunk every `flush_period_s` (0.5 s), so a killed recording loses the messages of the
open chunk and the writer queue: at most about one second (tests/logs/test_recover.py kills a
writer with SIGKILL and measures it). A chunk cut short by a power cut is decompressed as far as
it goes and its complete messages are kept (`salvaged_from_partial_chunk`); its header still says
until when it had messages, which gives `tail_lost_s` (a lower bound of the time lost).

`recover_directory` does this for every unclosed `*.mcap` of a log directory (`lotsen run` calls
it at start): `X.mcap` is recovered to `X.recovered.mcap`, then the original is renamed
`X.mcap.unclosed`, byte for byte untouched (for forensics; delete it when the recovered file is
fine). The rename keeps the directory free of files a seeking reader refuses and makes the next
start skip it; the recorder's run numbering counts `X_runNNN.recovered.mcap`. A file still being
written (its recorder holds an advisory lock) is left alone.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterator

from lotsen.errors import DataError, LotsenError
from lotsen.files import MAX_LOG_BYTES, check_input_file, same_file
from lotsen.logs.reader import MAGIC, CorruptLogError

_MAX_RECORD = 1 << 31  # a longer record is corruption in a lotsen log (as in LogReader)
_FOOTER_LEN = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, crc
RECOVERED_SUFFIX = ".recovered.mcap"
UNCLOSED_SUFFIX = ".unclosed"


@dataclass
class RecoveryStats:
    """What `recover_mcap` kept and what it could not."""

    source: str
    output: str = ""
    messages: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    schemas: int = 0
    channels: int = 0
    metadata: int = 0
    attachments: int = 0
    start_ns: int | None = None  # log time of the first and last message kept
    end_ns: int | None = None
    source_bytes: int = 0
    bytes_read: int = 0  # the source was intact up to this offset
    tail_bytes_lost: int = 0  # source_bytes - bytes_read: a cut or damaged record at the end
    salvaged_from_partial_chunk: int = 0  # messages decoded from a chunk cut short
    tail_lost_s: float = 0.0  # time between the last message kept and the end of a cut chunk (>= 0)
    damaged_chunks: int = 0  # skipped (bad compression or CRC) with the framing intact
    lost_on_unknown_channels: int = 0  # messages whose channel definition was in a damaged chunk
    damaged_records: int = 0  # records inside the framing that do not parse (skipped)
    already_recovered: bool = False  # recover_directory: recovered at an earlier start
    source_was_complete: bool = False  # the source already had a footer
    problems: list[str] = field(default_factory=list)
    error: str = ""  # recover_directory: why this file was not recovered (then output is "")

    @property
    def duration_s(self) -> float:
        return 0.0 if self.start_ns is None or self.end_ns is None else (self.end_ns - self.start_ns) / 1e9

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "duration_s": self.duration_s}

    def summary_line(self) -> str:
        if self.error:
            return f"{self.source}: not recovered: {self.error}"
        lost = (f"{self.tail_bytes_lost} bytes at the end unreadable"
                + (f", {self.salvaged_from_partial_chunk} messages salvaged from a cut chunk" if
                   self.salvaged_from_partial_chunk else "")
                + (f", >= {self.tail_lost_s:.2f} s of a cut chunk lost" if self.tail_lost_s > 0 else ""))
        return (f"{self.source} -> {self.output}: {self.messages} messages over {self.duration_s:.2f} s on "
                f"{self.channels} channels ({len(self.per_topic)} topics), {self.metadata} metadata, "
                f"{self.attachments} attachments; {lost}"
                + (f"; {self.damaged_chunks} damaged chunks skipped" if self.damaged_chunks else "")
                + (f"; {self.damaged_records} damaged records skipped" if self.damaged_records else ""))

    @property
    def nothing_recovered(self) -> bool:
        """Not one message could be read: the output holds nothing of the recording."""
        return not self.error and not self.already_recovered and self.messages == 0


# ---------------------------------------------------------------------------------- checks
def has_footer(path: str | os.PathLike, size: int | None = None) -> bool:
    """Does the file end with an MCAP footer record and the closing magic (what a seeking reader
    looks for first)? `size`: the file's length as already known (a file still growing)."""
    p = Path(path)
    size = p.stat().st_size if size is None else size
    if size < len(MAGIC) * 2 + _FOOTER_LEN:
        return False
    with open(p, "rb") as f:
        f.seek(size - len(MAGIC) - _FOOTER_LEN)
        tail = f.read(_FOOTER_LEN + len(MAGIC))
    return tail[-8:] == MAGIC and tail[0] == 0x02 and struct.unpack_from("<Q", tail, 1)[0] == 20


def needs_recovery(path: str | os.PathLike) -> bool:
    """True when a seeking reader cannot use the file: no footer, or no readable summary."""
    if not has_footer(path):
        return True
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            return make_reader(f).get_summary() is None
    except Exception:  # noqa: BLE001 - any refusal of the seeking reader means: recover
        return True


def _in_use(path: Path) -> bool:
    """Is a recorder still writing this file? (it holds an exclusive flock; see recorder.py)"""
    try:
        import fcntl
    except ImportError:
        return False
    try:
        with open(path, "rb") as f:
            fcntl.flock(f.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)
    except BlockingIOError:
        return True
    except OSError:
        return False
    return False


# ---------------------------------------------------------------------------------- reading
@dataclass
class _Chunk:
    start_ns: int
    end_ns: int
    compression: str
    data: bytes  # compressed (possibly cut short)
    uncompressed_size: int
    uncompressed_crc: int


def _parse_chunk(body: bytes) -> _Chunk | None:
    """A chunk record's fields; with a cut `body` the data is what is there (None if even the
    header is cut)."""
    if len(body) < 8 + 8 + 8 + 4 + 4:
        return None
    start, end, usize, ucrc, clen = struct.unpack_from("<QQQII", body, 0)
    o = 32
    if len(body) < o + clen + 8:
        return None
    compression = body[o:o + clen].decode("utf-8", "replace")
    o += clen
    dlen = struct.unpack_from("<Q", body, o)[0]
    o += 8
    return _Chunk(start, end, compression, body[o:o + dlen], usize, ucrc)


def _decompress(ch: _Chunk, partial: bool) -> bytes:
    """The chunk's records; `partial`: the data was cut, return as much as decompresses."""
    if ch.compression == "":
        data = ch.data
    elif ch.compression == "zstd":
        import zstandard

        if partial:
            data = zstandard.ZstdDecompressor().decompressobj().decompress(ch.data)
        else:
            data = zstandard.ZstdDecompressor().decompress(ch.data, max_output_size=ch.uncompressed_size)
    elif ch.compression == "lz4":
        import lz4.frame

        data = lz4.frame.LZ4FrameDecompressor().decompress(ch.data) if partial else lz4.frame.decompress(ch.data)
    else:
        raise ValueError(f"unsupported compression {ch.compression!r}")
    if not partial and ch.uncompressed_crc and zlib.crc32(data) != ch.uncompressed_crc:
        raise ValueError("CRC mismatch")
    return data


def _inner_records(data: bytes) -> Iterator[tuple[int, bytes]]:
    """(opcode, body) of the complete records in a chunk's uncompressed data."""
    i = 0
    while i + 9 <= len(data):
        opcode, length = data[i], struct.unpack_from("<Q", data, i + 1)[0]
        if i + 9 + length > len(data):
            return
        yield opcode, data[i + 9:i + 9 + length]
        i += 9 + length


class _Walker:
    """Front-to-back walk of an MCAP file that tolerates a cut or damaged end."""

    def __init__(self, path: Path, stats: RecoveryStats) -> None:
        self.path = path
        self.stats = stats
        self.header: tuple[str, str] = ("", "")  # profile, library
        self.compression = "zstd"
        self.cut_chunk_end_ns: int | None = None  # message_end_time of a chunk cut short

    def records(self) -> Iterator[tuple[int, bytes, bool]]:
        """(opcode, body, from_partial_chunk) of the data section, chunks opened."""
        from mcap.opcode import Opcode

        st = self.stats
        size = st.source_bytes = self.path.stat().st_size
        with open(self.path, "rb") as f:
            magic = f.read(8)
            if magic != MAGIC:
                raise CorruptLogError(self.path, 0, "empty file" if not magic else
                                      f"not an MCAP file (magic {magic[:8]!r})")
            pos = 8
            while True:
                st.bytes_read = pos
                head = f.read(9)
                if len(head) < 9:
                    break  # end of file (or a cut record header)
                opcode, length = head[0], struct.unpack_from("<Q", head, 1)[0]
                if opcode == 0 or length > _MAX_RECORD:
                    st.problems.append(f"invalid record at byte offset {pos} (opcode 0x{opcode:02x}, length "
                                       f"{length}): the rest of the file is unreadable")
                    break
                body = f.read(min(length, max(0, size - pos - 9)))
                if len(body) < length:  # the record was cut
                    if opcode == Opcode.CHUNK:
                        yield from self._cut_chunk(pos, body)
                    else:
                        st.problems.append(f"record (opcode 0x{opcode:02x}) at byte offset {pos} cut short")
                    break
                if opcode == Opcode.CHUNK:
                    yield from self._chunk(pos, body)
                elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                    st.source_was_complete = opcode == Opcode.FOOTER or st.source_was_complete
                    st.bytes_read = size  # the summary section follows: rebuilt, not copied
                    return
                elif opcode == Opcode.HEADER:
                    from mcap.data_stream import ReadDataStream
                    from mcap.records import Header

                    try:
                        h = Header.read(ReadDataStream(io.BytesIO(body)))
                        self.header = (h.profile, h.library)
                    except Exception as exc:  # noqa: BLE001 - a damaged header: the defaults, and say so
                        st.problems.append(f"damaged header record at byte offset {pos} ({type(exc).__name__})")
                else:
                    yield opcode, body, False
                pos += 9 + length
            st.bytes_read = pos

    def _chunk(self, pos: int, body: bytes) -> Iterator[tuple[int, bytes, bool]]:
        ch = _parse_chunk(body)
        try:
            if ch is None:
                raise ValueError("chunk header unreadable")
            data = _decompress(ch, partial=False)
        except Exception as exc:  # noqa: BLE001 - any failure inside a chunk = a damaged chunk
            self.stats.damaged_chunks += 1
            self.stats.problems.append(f"damaged chunk at byte offset {pos} ({exc}); skipped")
            return
        self.compression = ch.compression or "none"
        for opcode, rec in _inner_records(data):
            yield opcode, rec, False

    def _cut_chunk(self, pos: int, body: bytes) -> Iterator[tuple[int, bytes, bool]]:
        ch = _parse_chunk(body)
        if ch is None:
            self.stats.problems.append(f"chunk at byte offset {pos} cut inside its header")
            return
        self.stats.problems.append(f"chunk at byte offset {pos} cut short ({len(body)} bytes of it in the file); "
                                   "its complete messages are kept")
        self.cut_chunk_end_ns = ch.end_ns
        try:
            data = _decompress(ch, partial=True)
        except Exception as exc:  # noqa: BLE001 - garbage in the cut part: what decompressed is gone too
            self.stats.problems.append(f"cut chunk at byte offset {pos} does not decompress ({exc})")
            return
        for opcode, rec in _inner_records(data):
            yield opcode, rec, True


# ---------------------------------------------------------------------------------- writing
def recover_mcap(src: str | os.PathLike, dst: str | os.PathLike, *, fsync: bool = True) -> RecoveryStats:
    """Read `src` (complete, unclosed, cut or partly damaged) as a stream and write every record
    that is intact to `dst` as a complete, indexed MCAP with summary. `dst` appears atomically
    (written to `dst.part`, then renamed). Raises DataError when `src` is missing or not MCAP."""
    from mcap.data_stream import ReadDataStream
    from mcap.opcode import Opcode
    from mcap.records import Attachment, Channel, Metadata, Schema
    from mcap.writer import CompressionType, Writer

    from lotsen import __version__

    src, dst = Path(src), Path(dst)
    if not src.exists():
        raise DataError(f"{src}: no such log file")
    check_input_file(src, MAX_LOG_BYTES, DataError, "log file")
    if src.resolve() == dst.resolve() or same_file(src, dst):
        raise DataError(f"{dst}: the output must not be the file being recovered (nor a link to it)")
    stats = RecoveryStats(source=str(src), output=str(dst))
    walker = _Walker(src, stats)
    records = walker.records()
    # the header comes first: read up to the first record so profile and compression are known
    first = next(records, None)
    comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    part = dst.with_name(dst.name + ".part")
    try:
        out = open(part, "wb")
    except OSError as exc:
        raise DataError(f"{dst}: cannot write the recovered file: {exc.strerror or exc}") from None
    try:
        with out:
            writer = Writer(out, compression=comp.get(walker.compression, CompressionType.ZSTD))
            profile, library = walker.header
            writer.start(profile=profile, library=f"{library} (recovered by lotsen {__version__})".strip())
            schema_ids: dict[int, int] = {}
            channel_ids: dict[int, int] = {}
            channel_topic: dict[int, str] = {}
            pending_channels: dict[int, Channel] = {}  # seen before their schema (never by lotsen)

            def add_channel(c: Channel) -> None:
                sid = schema_ids.get(c.schema_id, 0) if c.schema_id else 0
                channel_ids[c.id] = writer.register_channel(c.topic, c.message_encoding, sid, dict(c.metadata))
                channel_topic[c.id] = c.topic
                stats.channels += 1

            def chained() -> Iterator[tuple[int, bytes, bool]]:
                if first is not None:
                    yield first
                yield from records

            def copy(opcode: int, body: bytes, salvaged: bool) -> None:
                if opcode == Opcode.MESSAGE:
                    if len(body) < 22:
                        return
                    cid, seq, log_ns, pub_ns = struct.unpack_from("<HIQQ", body, 0)
                    new = channel_ids.get(cid)
                    if new is None:
                        stats.lost_on_unknown_channels += 1
                        return
                    writer.add_message(new, log_time=log_ns, data=body[22:], publish_time=pub_ns, sequence=seq)
                    stats.messages += 1
                    topic = channel_topic[cid]
                    stats.per_topic[topic] = stats.per_topic.get(topic, 0) + 1
                    stats.start_ns = log_ns if stats.start_ns is None else min(stats.start_ns, log_ns)
                    stats.end_ns = log_ns if stats.end_ns is None else max(stats.end_ns, log_ns)
                    stats.salvaged_from_partial_chunk += salvaged
                elif opcode == Opcode.SCHEMA:
                    s = Schema.read(ReadDataStream(io.BytesIO(body)))
                    if s.id not in schema_ids:
                        schema_ids[s.id] = writer.register_schema(s.name, s.encoding, s.data)
                        stats.schemas += 1
                        for cid in [k for k, c in pending_channels.items() if c.schema_id == s.id]:
                            add_channel(pending_channels.pop(cid))
                elif opcode == Opcode.CHANNEL:
                    c = Channel.read(ReadDataStream(io.BytesIO(body)))
                    if c.id in channel_ids:
                        return
                    if c.schema_id and c.schema_id not in schema_ids:
                        pending_channels[c.id] = c
                    else:
                        add_channel(c)
                elif opcode == Opcode.METADATA:
                    m = Metadata.read(ReadDataStream(io.BytesIO(body)))
                    writer.add_metadata(m.name, dict(m.metadata))
                    stats.metadata += 1
                elif opcode == Opcode.ATTACHMENT:
                    a = Attachment.read(ReadDataStream(io.BytesIO(body)))
                    writer.add_attachment(a.create_time, a.log_time, a.name, a.media_type, a.data)
                    stats.attachments += 1
                # message indexes, chunk indexes, statistics, ...: rebuilt by the writer

            for opcode, body, salvaged in chained():
                try:
                    copy(opcode, body, salvaged)
                except Exception as exc:  # noqa: BLE001 - a damaged record (any byte sequence): skipped, counted
                    stats.damaged_records += 1
                    if stats.damaged_records <= 20:
                        stats.problems.append(f"damaged record (opcode 0x{opcode:02x}) skipped "
                                              f"({type(exc).__name__}: {str(exc)[:80]})")
            if stats.damaged_records > 20:
                stats.problems.append(f"... {stats.damaged_records} damaged records skipped in all")
            stats.tail_bytes_lost = max(0, stats.source_bytes - stats.bytes_read)
            cut_end = walker.cut_chunk_end_ns
            if cut_end is not None and stats.end_ns is not None:
                stats.tail_lost_s = max(0.0, (cut_end - stats.end_ns) / 1e9)
            if stats.lost_on_unknown_channels:
                stats.problems.append(f"{stats.lost_on_unknown_channels} messages on channels whose definition "
                                      "was lost (damaged chunk)")
            writer.add_metadata("lotsen_recovery", {
                "source": src.name, "source_bytes": str(stats.source_bytes), "bytes_read": str(stats.bytes_read),
                "tail_bytes_lost": str(stats.tail_bytes_lost), "messages": str(stats.messages),
                "salvaged_from_partial_chunk": str(stats.salvaged_from_partial_chunk),
                "tail_lost_s": f"{stats.tail_lost_s:.3f}", "damaged_chunks": str(stats.damaged_chunks),
                "source_was_complete": str(stats.source_was_complete).lower(),
                "lotsen_version": __version__, "problems": "; ".join(stats.problems)[:4000]})
            writer.finish()
            out.flush()
            if fsync:
                os.fsync(out.fileno())
        os.replace(part, dst)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    return stats


def recovered_path(path: str | os.PathLike) -> Path:
    """`X.mcap` -> `X.recovered.mcap` (next to it)."""
    p = Path(path)
    stem = p.name[:-5] if p.name.endswith(".mcap") else p.name
    return p.with_name(stem + RECOVERED_SUFFIX)


def recover_directory(directory: str | os.PathLike, *, fsync: bool = True) -> list[RecoveryStats]:
    """Recover every unclosed `*.mcap` in `directory` (not recursive): `X.mcap` ->
    `X.recovered.mcap`, and the original renamed `X.mcap.unclosed` (bytes untouched). Files a
    recorder still writes are skipped. A file that cannot be recovered keeps its name and gets a
    RecoveryStats with `error` set; the others are unaffected. A missing directory: []."""
    d = Path(directory)
    if not d.is_dir():
        return []
    out: list[RecoveryStats] = []
    for p in sorted(d.glob("*.mcap")):
        try:
            if not p.is_file() or _in_use(p):
                continue
            if p.stat().st_size == 0:  # killed before the first write reached the disk
                p.rename(p.with_name(p.name + UNCLOSED_SUFFIX))
                out.append(RecoveryStats(source=str(p), error=f"empty file (nothing was written); renamed "
                                                              f"{p.name + UNCLOSED_SUFFIX}"))
                continue
            if not needs_recovery(p):
                continue
            dst = recovered_path(p)
            if dst.exists() and not needs_recovery(dst):
                stats = RecoveryStats(source=str(p), output=str(dst), already_recovered=True)  # not renamed then
                stats.problems.append("already recovered")
            else:
                stats = recover_mcap(p, dst, fsync=fsync)
            p.rename(p.with_name(p.name + UNCLOSED_SUFFIX))
        except (LotsenError, OSError) as exc:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
            out.append(RecoveryStats(source=str(p), error=reason))
            continue
        out.append(stats)
    return out
