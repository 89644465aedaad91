"""The MCAP logs of `config.logging.directory`: a list for the page and safe file lookup for
the download (`/logs/<name>`). Only plain `*.mcap` files directly in the folder are served; a name
is never joined to a path before it matched `LOG_NAME` and resolved inside the folder."""

from __future__ import annotations

import re
import time
from pathlib import Path
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
