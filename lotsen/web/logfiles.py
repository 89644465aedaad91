"""The MCAP logs of `config.logging.directory`: a list for the page and safe file lookup for
the download (`/logs/<name>`). Only plain `*.mcap` files directly in the folder are served; a name
is never joined to a path before it matched `LOG_NAME` and resolved inside the folder.

A file still being recorded has no summary and no footer yet, and grows while it is sent. Its
download is a snapshot (`DataExtent`, `snapshot_tail`): the bytes up to the last complete
record on disk (the recorder closes and flushes a chunk every 0.5 s), followed by a DataEnd and
a footer without summary, which every MCAP reader (the `mcap` library, Foxglove, `mcap info`)
reads front to back. Its length is fixed before the first byte is sent."""

from __future__ import annotations

import re
import time
from pathlib import Path
from urllib.parse import quote

from lotsen.logs.snapshot import DataExtent, scan_extent, snapshot_tail

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
    if (root / name).is_symlink():  # never a link, wherever it points (as in the list)
        return None
    p = (root / name).resolve()
    if p.parent != root or not p.is_file():
        return None
    return p


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
