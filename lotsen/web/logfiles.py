"""The MCAP logs of `config.logging.directory`: a list for the page and safe file lookup for
the download (`/logs/<name>`). Only plain `*.mcap` files directly in the folder are served; a name
is never joined to a path before it matched `LOG_NAME` and resolved inside the folder.

A file still being recorded has no summary and no footer yet, and grows while it is sent. Its
download is a snapshot (`DataExtent`, `snapshot_tail`): the bytes up to the last complete
record on disk (the recorder closes and flushes a chunk every 0.5 s), followed by a DataEnd and
a footer without summary, which every MCAP reader (the `mcap` library, Foxglove, `mcap info`)
reads front to back. Its length is fixed before the first byte is sent."""

from __future__ import annotations

import os
import re
import struct
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator
from urllib.parse import quote

LOG_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,200}\.mcap$")
MAX_LISTED = 200
#: a file modified this recently is probably still being recorded (no summary/footer yet)
RECORDING_WITHIN_S = 5.0
FOXGLOVE_APP = "https://app.foxglove.dev"


def foxglove_url(file_url: str) -> str:
    """Foxglove's web app opening a remote MCAP file by URL (the browser fetches the file from the
    boat: it must be reachable from the browser, and over https unless the boat is localhost)."""
    return f"{FOXGLOVE_APP}/?ds=remote-file&ds.url={quote(file_url, safe='')}"


def list_logs(directory: str | Path, now: float | None = None) -> list[dict]:
    d = Path(directory) if directory else None
    if d is None or not d.is_dir():
        return []
    now = time.time() if now is None else now
    out = []
    for p in d.iterdir():
        if not LOG_NAME.match(p.name) or not p.is_file() or p.is_symlink():
            continue
        st = p.stat()
        out.append({"name": p.name, "size": st.st_size, "mtime": round(st.st_mtime, 1),
                    "recording": now - st.st_mtime < RECORDING_WITHIN_S})
    out.sort(key=lambda e: e["mtime"], reverse=True)
    return out[:MAX_LISTED]


def resolve_log(directory: str | Path, name: str) -> Path | None:
    """The file for `name`, or None when the name is not a plain log file name in the folder."""
    if not directory or not LOG_NAME.match(name):
        return None
    root = Path(directory).resolve()
    p = (root / name).resolve()
    if p.parent != root or not p.is_file():
        return None
    return p


# -- snapshots of a file being recorded (MCAP records: opcode u8, length u64 LE, content) ---------
MAGIC = b"\x89MCAP0\r\n"
_OP_FOOTER, _OP_CHUNK, _OP_DATA_END = 0x02, 0x06, 0x0F
_FOOTER_LEN = 1 + 8 + 20
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


def has_footer(path: str | Path, size: int) -> bool:
    if size < 2 * len(MAGIC) + _FOOTER_LEN:
        return False
    with open(path, "rb") as f:
        f.seek(size - len(MAGIC) - _FOOTER_LEN)
        tail = f.read(_FOOTER_LEN + len(MAGIC))
    return tail[-8:] == MAGIC and tail[0] == _OP_FOOTER and struct.unpack_from("<Q", tail, 1)[0] == 20


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


class ExtentCache:
    """The last extent per file, so the live indicator's polling walks only the new records."""

    def __init__(self) -> None:
        self._known: dict[str, tuple[int, DataExtent]] = {}

    def get(self, path: Path) -> DataExtent | None:
        key = str(path)
        st = path.stat()
        old = self._known.get(key)
        if old is not None and old[0] == st.st_ino and old[1].end > st.st_size:
            old = None  # replaced or truncated: start again
        ext = scan_extent(path, old[1] if old is not None and old[0] == st.st_ino else None)
        if ext is not None:
            self._known[key] = (st.st_ino, ext)
            if len(self._known) > 4 * MAX_LISTED:
                self._known.clear()
        return ext


def recordings(directory: str | Path, cache: ExtentCache, now: float | None = None) -> list[dict]:
    """The files being recorded now (no footer yet, written to within RECORDING_WITHIN_S): name,
    size, duration of the complete chunks, and how much a download gets now (`readable_bytes`)."""
    now = time.time() if now is None else now
    out = []
    for e in list_logs(directory, now):
        if not e["recording"]:
            continue
        ext = cache.get(Path(directory) / e["name"])
        if ext is None or ext.closed:
            continue
        out.append({**e, "duration_s": round(ext.duration_s, 1), "readable_bytes": ext.end + len(snapshot_tail())})
    return out
