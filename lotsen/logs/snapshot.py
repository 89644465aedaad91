"""Readable snapshots of an MCAP file still being recorded: how far its records are complete
(a walk over the record headers, not their contents), and the bytes of a copy cut there and closed
with a DataEnd and an empty footer, so any MCAP reader takes it (read front to back: no index)."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from lotsen.logs.recover import _FOOTER_LEN, MAGIC, has_footer

# MCAP records: opcode u8, length u64 LE, content
_OP_FOOTER, _OP_CHUNK, _OP_DATA_END = 0x02, 0x06, 0x0F
_MAX_RECORD = 1 << 31  # longer: corruption (the recorder's chunks are a few MB)


@dataclass(frozen=True)
class DataExtent:
    """How far a log file is readable: `end` is the offset after its last complete record
    (`closed`: the file ends with its footer, it is complete as it is); `start_ns`/`end_ns` the
    log times covered by its complete chunks (None before the first chunk)."""

    end: int
    closed: bool = False
    start_ns: int | None = None
    end_ns: int | None = None

    @property
    def duration_s(self) -> float:
        return 0.0 if self.start_ns is None or self.end_ns is None else max(0, self.end_ns - self.start_ns) / 1e9


def scan_extent(path: str | Path, since: DataExtent | None = None) -> DataExtent | None:
    """Walk the record headers (not their contents) from `since.end` (or the start) to the last
    complete record; None when the file is not an MCAP file. Cheap: one small read per record."""
    size = os.stat(path).st_size
    closed = has_footer(path, size)
    if since is not None and since.closed:
        return since if closed and since.end == size else _walk(path, size, None, closed)
    return _walk(path, size, since, closed)


def _walk(path: str | Path, size: int, since: DataExtent | None, closed: bool) -> DataExtent | None:
    with open(path, "rb") as f:
        if since is None:
            if f.read(len(MAGIC)) != MAGIC:
                return None
            pos, start_ns, end_ns = len(MAGIC), None, None
        else:
            pos, start_ns, end_ns = since.end, since.start_ns, since.end_ns
        while True:
            f.seek(pos)
            head = f.read(9)
            if len(head) < 9:
                break
            op, length = head[0], struct.unpack_from("<Q", head, 1)[0]
            if length > _MAX_RECORD or pos + 9 + length > size or op in (_OP_DATA_END, _OP_FOOTER):
                break  # an incomplete record (still being written), or the end of the data
            if op == _OP_CHUNK and length >= 16:
                t0, t1 = struct.unpack("<QQ", f.read(16))
                if t1 >= t0 > 0:
                    start_ns = t0 if start_ns is None else min(start_ns, t0)
                    end_ns = t1 if end_ns is None else max(end_ns, t1)
            pos += 9 + length
    return DataExtent(size if closed else pos, closed, start_ns, end_ns)


def snapshot_tail() -> bytes:
    """What closes a cut data section: DataEnd (no CRC: 0), a footer with no summary, the magic."""
    data_end = struct.pack("<BQI", _OP_DATA_END, 4, 0)
    footer = struct.pack("<BQQQI", _OP_FOOTER, 20, 0, 0, 0)
    return data_end + footer + MAGIC


def snapshot_chunks(path: str | Path, extent: DataExtent, block: int = 1 << 20) -> Iterator[bytes]:
    """The bytes of a readable snapshot: exactly `extent.end` bytes of the file, then the tail
    (total `extent.end + len(snapshot_tail())`, whatever the recorder writes meanwhile)."""
    left = extent.end
    with open(path, "rb") as f:
        while left > 0:
            data = f.read(min(block, left))
            if not data:  # the file shrank: never true for a recording; end short rather than pad
                return
            left -= len(data)
            yield data
    yield snapshot_tail()
