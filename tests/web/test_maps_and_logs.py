"""Offline map tiles (pre-load while online, served by the boat) and the MCAP logs (list,
download, Foxglove link): the tile maths, the pre-load's caps and manners, and both over HTTP."""

from __future__ import annotations

import json
import struct
import threading
import urllib.error
import urllib.request
import zlib
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest
from websockets.sync.client import connect

from lotsen.errors import ConfigError
from lotsen.web.logfiles import list_logs, resolve_log
from lotsen.web.tiles import Preloader, TileStore, lonlat_to_tile, tile_to_lonlat, tiles_for_bbox

from .conftest import TOKEN, recv_until, start_stack, stop_stack


def png_1x1() -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = zlib.compress(b"\x00\x40\x80\xc0")
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 1, 1, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


PNG = png_1x1()


class TileServer:
    """A stand-in for the online tile server: PNG for every tile, HTTP 429 from `refuse_from_zoom` on."""

    def __init__(self, refuse_from_zoom: int = 17) -> None:
        self.requests: list[str] = []
        outer = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                outer.requests.append(self.path)
                z = int(self.path.strip("/").split("/")[0])
                if z >= refuse_from_zoom:
                    self.send_response(429)
                    self.end_headers()
                    return
                self.send_response(200)
                self.send_header("Content-Type", "image/png")
                self.send_header("Content-Length", str(len(PNG)))
                self.end_headers()
                self.wfile.write(PNG)

            def log_message(self, *args) -> None:
                pass

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.httpd.server_address[1]}/{{z}}/{{x}}/{{y}}.png"
        threading.Thread(target=self.httpd.serve_forever, daemon=True).start()

    def close(self) -> None:
        self.httpd.shutdown()


@pytest.fixture(scope="module")
def tile_server():
    ts = TileServer()
    yield ts
    ts.close()


# -- tile maths and the pre-load ---------------------------------------------------------------
def test_tile_coordinates_round_trip_and_boxes_cover_the_area():
    lat, lon = 53.55, 9.99
    for z in (0, 10, 18):
        x, y = lonlat_to_tile(lat, lon, z)
        la, lo = tile_to_lonlat(x, y, z)
        assert abs(la - lat) < 1e-9 and abs(lo - lon) < 1e-9
    tiles = tiles_for_bbox(53.549, 9.989, 53.551, 9.991, 15, 16)
    assert {z for z, _, _ in tiles} == {15, 16} and len(tiles) <= 2 * 4
    x, y = lonlat_to_tile(lat, lon, 16)
    assert (16, int(x), int(y)) in tiles


def test_preload_fetches_each_tile_once_and_stops_at_the_first_refusal(tmp_path, tile_server):
    store = TileStore(tmp_path)
    p = Preloader(store, tile_server.url, max_tiles=50)
    tiles = p.plan(53.549, 9.989, 53.551, 9.991, 14, 16)
    prog = p.run(tiles)
    assert prog.state == "done" and prog.fetched == len(tiles) and store.index()["count"] == len(tiles)
    n = len(tile_server.requests)
    assert p.run(tiles).cached == len(tiles) and len(tile_server.requests) == n  # not fetched again
    prog = Preloader(store, tile_server.url, max_tiles=50).run(tiles_for_bbox(53.549, 9.989, 53.551, 9.991, 17, 18))
    assert prog.state == "failed" and "429" in prog.error and len(tile_server.requests) == n + 1  # no retries
    with pytest.raises(ConfigError, match="at most 50 per pre-load"):
        p.plan(53.0, 9.0, 54.0, 10.0, 10, 16)
    with pytest.raises(ConfigError, match="above the limit"):
        Preloader(store, tile_server.url, max_zoom=16).plan(53.549, 9.989, 53.551, 9.991, 15, 17)


# -- over the socket and HTTP ----------------------------------------------------------------------
def _get(url: str) -> tuple[int, dict, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as r:
            return r.status, dict(r.headers), r.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), b""


def test_the_pilot_preloads_tiles_that_the_boat_then_serves(tmp_path, tile_server):
    rs = start_stack(extra_web={"tile_dir": str(tmp_path / "tiles"), "tile_url": tile_server.url,
                                "tile_max_count": 40})
    try:
        base = rs.url.rstrip("/")
        assert json.loads(_get(base + "/api/tiles")[2])["count"] == 0
        box = {"south": 53.549, "west": 9.989, "north": 53.551, "east": 9.991, "zoom_min": 14, "zoom_max": 16}
        with connect(rs.ws_url) as ws:
            hello = recv_until(ws, lambda m: m["type"] == "hello")
            assert hello["tiles"]["enabled"] and hello["tiles"]["source"].startswith("127.0.0.1:")
            ws.send(json.dumps({"type": "tiles_preload", **box, "id": 1}))
            assert recv_until(ws, lambda m: m.get("id") == 1)["code"] == "not_pilot"  # a viewer may not
            ws.send(json.dumps({"type": "auth", "token": TOKEN, "id": 2}))
            recv_until(ws, lambda m: m.get("id") == 2)
            ws.send(json.dumps({"type": "tiles_preload", **box, "id": 3}))
            started = recv_until(ws, lambda m: m.get("id") == 3)
            assert started["type"] == "tiles_started" and started["total"] > 0
            done = recv_until(ws, lambda m: m["type"] == "tiles_progress" and m["state"] != "running", timeout=10)
            assert done["state"] == "done" and done["fetched"] == started["total"]
            ws.send(json.dumps({"type": "tiles_preload", **box, "south": 50.0, "id": 4}))
            assert "at most 40" in recv_until(ws, lambda m: m.get("id") == 4)["error"]
        index = json.loads(_get(base + "/api/tiles")[2])
        assert index["count"] == started["total"]
        x, y = index["zooms"]["16"][0]
        status, headers, body = _get(f"{base}/tiles/16/{x}/{y}.png")
        assert status == 200 and body == PNG and headers["content-type"] == "image/png"
        assert _get(f"{base}/tiles/16/0/0.png")[0] == 404 and _get(f"{base}/tiles/3/9/9.png")[0] == 404
        # issue 41: a link in the cache never leads out of it (a file link, a folder link)
        secret = tmp_path / "secret.png"
        secret.write_bytes(PNG + b"the boat's secrets")
        (tmp_path / "tiles" / "16" / "0").mkdir(parents=True)
        (tmp_path / "tiles" / "16" / "0" / "0.png").symlink_to(secret)
        (tmp_path / "tiles" / "13").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
        (tmp_path / "elsewhere" / "1").mkdir(parents=True)
        (tmp_path / "elsewhere" / "1" / "1.png").write_bytes(PNG)
        assert _get(f"{base}/tiles/16/0/0.png")[0] == 404 and _get(f"{base}/tiles/13/1/1.png")[0] == 404
    finally:
        stop_stack(rs)


def small_mcap(path, messages: int = 5) -> int:
    """A complete (closed) MCAP file; its size."""
    from mcap.writer import Writer

    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="test")
        ch = w.register_channel("t", "json", w.register_schema("s", "jsonschema", b"{}"))
        for i in range(messages):
            w.add_message(ch, log_time=(i + 1) * 10**9, data=b"{}", publish_time=(i + 1) * 10**9)
        w.finish()
    return path.stat().st_size


def test_logs_are_listed_and_downloaded_and_nothing_else_is(tmp_path):
    size = small_mcap(tmp_path / "2026-11-23_run.mcap")
    (tmp_path / "notes.txt").write_text("not a log")
    (tmp_path / "inner").mkdir()
    (tmp_path / "inner" / "hidden.mcap").write_bytes(b"x")
    assert [e["name"] for e in list_logs(tmp_path)] == ["2026-11-23_run.mcap"]
    assert resolve_log(tmp_path, "../secret.mcap") is None and resolve_log(tmp_path, "notes.txt") is None
    outside = tmp_path.parent / f"{tmp_path.name}-outside.mcap"
    small_mcap(outside)
    (tmp_path / "leak.mcap").symlink_to(outside)  # a link out of the folder is neither listed nor served
    assert resolve_log(tmp_path, "leak.mcap") is None
    rs = start_stack(log_dir=str(tmp_path))
    try:
        base = rs.url.rstrip("/")
        listing = json.loads(_get(base + "/api/logs")[2])
        assert listing["directory_set"] and [e["name"] for e in listing["logs"]] == ["2026-11-23_run.mcap"]
        entry = listing["logs"][0]
        assert entry["foxglove"].startswith("https://app.foxglove.dev/?ds=remote-file&ds.url=http%3A%2F%2F127.0.0.1")
        status, headers, body = _get(base + entry["url"])
        assert status == 200 and body.startswith(b"\x89MCAP0") and len(body) == size  # a closed file: as it is
        assert headers["access-control-allow-origin"] == "https://app.foxglove.dev"
        assert "attachment" in headers["content-disposition"]
        for bad in ("notes.txt", "..%2Fnotes.txt", "inner%2Fhidden.mcap", "%2Fetc%2Fpasswd", "leak.mcap"):
            assert _get(f"{base}/logs/{bad}")[0] == 404, bad
    finally:
        stop_stack(rs)


def _read_mcap(data: bytes) -> list:
    import io

    from mcap.reader import make_reader

    return [(c.topic, m.log_time) for _, c, m in make_reader(io.BytesIO(data)).iter_messages()]


def test_the_file_being_recorded_downloads_as_a_readable_snapshot(tmp_path):
    """While the recorder writes (chunks closed every 0.2 s here), every download is a complete
    MCAP up to a recent point, its length fixed in the header (never "content longer than
    Content-Length"); /api/recording names the file with its size and duration; once the
    recorder closes the file, the download is the file itself."""
    import time

    from lotsen.logs.recorder import McapRecorder, RecorderConfig
    from lotsen.logs.snapshot import scan_extent
    from lotsen.web.logfiles import ExtentCache

    rs = start_stack(log_dir=str(tmp_path))
    rec = McapRecorder(RecorderConfig(directory=str(tmp_path), flush_period_s=0.2, fsync=False)).attach(rs.stack.bus)
    try:
        path = rec.start()
        base = rs.url.rstrip("/")
        time.sleep(1.5)
        sizes = []
        lags = []
        for _ in range(4):
            t_request = time.time()
            status, headers, body = _get(f"{base}/logs/{path.name}")
            assert status == 200 and headers["x-lotsen-recording"] == "snapshot"
            assert int(headers["content-length"]) == len(body)
            assert headers["content-disposition"].endswith(f'{path.stem}.partial.mcap"')
            msgs = _read_mcap(body)
            assert len(msgs) > 20 and len({t for t, _ in msgs}) > 3  # several topics, readable
            sizes.append(len(body))
            lags.append(t_request - max(t for _, t in msgs) / 1e9)
            time.sleep(0.4)
        assert sizes == sorted(sizes) and sizes[-1] > sizes[0]  # it follows the recording
        print(f"snapshot lag behind the request: {[round(x, 2) for x in lags]} s")
        assert max(lags) < 2.0  # up to a recent point (flush 0.2 s, queue, writer thread)
        # "a recent point": the snapshot ends within about a second of what the recorder has taken in
        ext = scan_extent(path)
        assert not ext.closed and ext.duration_s > 1.0
        listing = json.loads(_get(base + "/api/recording")[2])["recording"]
        assert [e["name"] for e in listing] == [path.name]
        assert listing[0]["size"] > 0 and listing[0]["duration_s"] > 1.0
        assert listing[0]["readable_bytes"] <= path.stat().st_size + 50
        cache = ExtentCache()
        first = cache.get(path)
        time.sleep(0.5)
        assert cache.get(path).end >= first.end  # incremental: walks only the new records
        rec.stop()
        status, headers, body = _get(f"{base}/logs/{path.name}")
        assert status == 200 and "x-lotsen-recording" not in headers and len(body) == path.stat().st_size
        assert len(_read_mcap(body)) >= len(msgs)
        assert json.loads(_get(base + "/api/recording")[2])["recording"] == []
    finally:
        rec.close()
        stop_stack(rs)


def test_snapshot_cuts_a_partly_written_record(tmp_path):
    """A chunk half on disk is left out; the cut file still reads."""
    from mcap.writer import Writer

    from lotsen.logs.snapshot import scan_extent, snapshot_chunks

    p = tmp_path / "live.mcap"
    f = open(p, "wb")
    w = Writer(f, chunk_size=200)
    w.start(profile="", library="test")
    ch = w.register_channel("t", "json", w.register_schema("s", "jsonschema", b"{}"))
    for i in range(40):
        w.add_message(ch, log_time=(i + 1) * 10**8, data=b'{"x": 1234567890}', publish_time=0)
    f.flush()
    whole = p.read_bytes()
    p.write_bytes(whole + b"\x06" + (10**6).to_bytes(8, "little") + b"partial")  # a chunk being written
    ext = scan_extent(p)
    assert ext.end == len(whole) and not ext.closed and ext.start_ns == 10**8
    msgs = _read_mcap(b"".join(snapshot_chunks(p, ext)))
    assert len(msgs) >= 30 and msgs == sorted(msgs, key=lambda m: m[1])
    assert scan_extent(tmp_path / "live.mcap") == ext
    (tmp_path / "not.mcap").write_bytes(b"hello")
    assert scan_extent(tmp_path / "not.mcap") is None
    f.close()
