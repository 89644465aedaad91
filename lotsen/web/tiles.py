"""Offline map tiles: Web Mercator tile maths, a folder cache `<dir>/<z>/<x>/<y>.png`, and the
pre-load of an area while online.

The page draws cached tiles under the route (served by the boat's own server at
`/tiles/{z}/{x}/{y}.png`, so no tile server is needed at the lake) and falls back to the metre
grid where none are cached. The pre-load follows the OpenStreetMap tile usage policy
(https://operations.osmfoundation.org/policies/tiles/): an identifying User-Agent, one
connection at a time, tiles already cached are not fetched again, a cap on the number of tiles
per pre-load (`tile_max_count`, default 1000) and on the zoom (`tile_max_zoom`, default 19),
and it stops at the first HTTP 429/403/5xx instead of retrying. It is meant for the few hundred
tiles around one lake, never for bulk downloads.
"""

from __future__ import annotations

import math
import os
import stat
import tempfile
import threading
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from lotsen.errors import ConfigError

USER_AGENT = "lotsen/0.1 (offline tiles for a model-ship operator page; +https://github.com/lotsen)"
MAX_TILE_BYTES = 1 << 20
MAX_INDEX_TILES = 20000  # tiles listed to the page; more are served but not announced
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
JPEG_MAGIC = b"\xff\xd8\xff"
MAX_LAT = 85.05112878


def lonlat_to_tile(lat_deg: float, lon_deg: float, zoom: int) -> tuple[float, float]:
    """Fractional Web Mercator tile coordinates (x east, y south) of a point at `zoom`."""
    lat = math.radians(max(-MAX_LAT, min(MAX_LAT, lat_deg)))
    n = 2.0**zoom
    x = (lon_deg + 180.0) / 360.0 * n
    y = (1.0 - math.asinh(math.tan(lat)) / math.pi) / 2.0 * n
    return x, y


def tile_to_lonlat(x: float, y: float, zoom: int) -> tuple[float, float]:
    """(lat, lon) of the north-west corner of tile (x, y) (fractional allowed)."""
    n = 2.0**zoom
    lon = x / n * 360.0 - 180.0
    lat = math.degrees(math.atan(math.sinh(math.pi * (1.0 - 2.0 * y / n))))
    return lat, lon


def tiles_for_bbox(south: float, west: float, north: float, east: float, zoom_min: int,
                   zoom_max: int) -> list[tuple[int, int, int]]:
    """All tiles (z, x, y) covering the box, coarse zooms first."""
    out = []
    for z in range(zoom_min, zoom_max + 1):
        x0, y0 = lonlat_to_tile(north, west, z)
        x1, y1 = lonlat_to_tile(south, east, z)
        top = 2**z - 1
        for x in range(max(0, int(x0)), min(top, int(x1)) + 1):
            for y in range(max(0, int(y0)), min(top, int(y1)) + 1):
                out.append((z, x, y))
    return out


def tile_image_type(data: bytes) -> str | None:
    if data.startswith(PNG_MAGIC):
        return "image/png"
    if data.startswith(JPEG_MAGIC):
        return "image/jpeg"
    return None


def valid_tile(z: int, x: int, y: int) -> bool:
    return 0 <= z <= 22 and 0 <= x < 2**z and 0 <= y < 2**z


class TileStore:
    """The cache folder. Files are written atomically (temporary file + rename)."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)

    def path(self, z: int, x: int, y: int) -> Path:
        if not valid_tile(z, x, y):
            raise ValueError(f"no tile {z}/{x}/{y}")
        return self.root / str(z) / str(x) / f"{y}.png"

    def has(self, z: int, x: int, y: int) -> bool:
        return self.path(z, x, y).is_file()

    def read(self, z: int, x: int, y: int) -> bytes | None:
        """A cached tile's bytes, or None. Never follows a link out of the cache: the file and its
        folders must resolve inside the cache folder (a link in the cache pointing at /etc/passwd
        was served to anyone, issue 41), and the file is opened without following a last link."""
        p = self.path(z, x, y)
        try:
            root = self.root.resolve(strict=True)
            real = p.resolve(strict=True)
        except (OSError, RuntimeError):
            return None
        if not real.is_relative_to(root) or p.is_symlink():
            return None
        try:
            fd = os.open(real, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except OSError:
            return None
        with os.fdopen(fd, "rb") as f:
            if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
                return None
            data = f.read(MAX_TILE_BYTES + 1)
        return data if len(data) <= MAX_TILE_BYTES else None

    def write(self, z: int, x: int, y: int, data: bytes) -> None:
        p = self.path(z, x, y)
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=p.parent, suffix=".part")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
            os.replace(tmp, p)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    def index(self, limit: int = MAX_INDEX_TILES) -> dict:
        """{"count": n, "zooms": {"z": [[x, y], ...]}} of the cached tiles (at most `limit` listed)."""
        zooms: dict[str, list[list[int]]] = {}
        count = 0
        if not self.root.is_dir():
            return {"count": 0, "zooms": {}, "truncated": False}
        for zdir in sorted(self.root.iterdir(), key=lambda p: p.name):
            if not zdir.name.isdigit():
                continue
            for xdir in zdir.iterdir():
                if not xdir.name.isdigit():
                    continue
                for f in xdir.glob("*.png"):
                    if f.stem.isdigit():
                        count += 1
                        if count <= limit:
                            zooms.setdefault(zdir.name, []).append([int(xdir.name), int(f.stem)])
        return {"count": count, "zooms": zooms, "truncated": count > limit}


@dataclass
class PreloadProgress:
    total: int
    done: int = 0  # fetched or already cached
    fetched: int = 0
    cached: int = 0
    failed: int = 0
    state: str = "running"  # running | done | cancelled | failed
    error: str = ""
    bytes: int = 0

    def as_dict(self) -> dict:
        return {"total": self.total, "done": self.done, "fetched": self.fetched, "cached": self.cached,
                "failed": self.failed, "state": self.state, "error": self.error, "bytes": self.bytes}


def _fetch(url: str, timeout_s: float) -> bytes:
    req = urllib.request.Request(url, headers={"User-Agent": USER_AGENT, "Accept": "image/png,image/*"})
    with urllib.request.urlopen(req, timeout=timeout_s) as r:  # noqa: S310 - http(s) checked by the caller
        data = r.read(MAX_TILE_BYTES + 1)
    if len(data) > MAX_TILE_BYTES:
        raise ValueError(f"tile larger than {MAX_TILE_BYTES} bytes")
    return data


@dataclass
class Preloader:
    """Downloads the tiles of a box into a `TileStore`, one at a time, with progress."""

    store: TileStore
    url_template: str
    max_tiles: int = 1000
    max_zoom: int = 19
    timeout_s: float = 10.0
    fetch: Callable[[str, float], bytes] = _fetch
    cancel: threading.Event = field(default_factory=threading.Event)

    def plan(self, south: float, west: float, north: float, east: float, zoom_min: int,
             zoom_max: int) -> list[tuple[int, int, int]]:
        """The tiles to pre-load; ConfigError when the request breaks the caps (nothing fetched)."""
        if zoom_max > self.max_zoom:
            raise ConfigError(f"tiles_preload.zoom_max: {zoom_max} above the limit {self.max_zoom} "
                              "(extra.web.tile_max_zoom; the tile usage policy forbids bulk downloads at high zoom)")
        tiles = tiles_for_bbox(south, west, north, east, zoom_min, zoom_max)
        if len(tiles) > self.max_tiles:
            raise ConfigError(f"tiles_preload: {len(tiles)} tiles for this area and zoom {zoom_min}-{zoom_max}, "
                              f"at most {self.max_tiles} per pre-load (extra.web.tile_max_count); choose a "
                              "smaller area or a lower zoom")
        return tiles

    def run(self, tiles: list[tuple[int, int, int]],
            on_progress: Callable[[PreloadProgress], None] | None = None) -> PreloadProgress:
        prog = PreloadProgress(total=len(tiles))
        report = on_progress or (lambda p: None)
        for z, x, y in tiles:
            if self.cancel.is_set():
                prog.state = "cancelled"
                break
            if self.store.has(z, x, y):
                prog.cached += 1
            else:
                url = self.url_template.format(z=z, x=x, y=y)
                try:
                    data = self.fetch(url, self.timeout_s)
                    if tile_image_type(data) is None:
                        raise ValueError("not a PNG or JPEG image")
                    self.store.write(z, x, y, data)
                    prog.fetched += 1
                    prog.bytes += len(data)
                except urllib.error.HTTPError as exc:
                    prog.failed += 1
                    if exc.code in (403, 429) or exc.code >= 500:  # refused or overloaded: stop, no retries
                        prog.state, prog.error = "failed", f"tile server answered HTTP {exc.code} for {z}/{x}/{y}"
                        break
                except (OSError, ValueError) as exc:
                    prog.failed += 1
                    if prog.failed >= 5 and prog.fetched == 0:
                        prog.state, prog.error = "failed", f"tile server not reachable: {str(exc)[:120]}"
                        break
            prog.done += 1
            if prog.done % 5 == 0 or prog.done == prog.total:
                report(prog)
        if prog.state == "running":
            prog.state = "done"
        report(prog)
        return prog
