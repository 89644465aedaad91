"""HTTP and WebSocket routes: the page, its static assets (shipped in the package, nothing from
a CDN), the `/ws` socket, cached map tiles, the MCAP logs, and security headers on every response.

| path | what | who |
|---|---|---|
| `/`, `/static/...` | the page | anyone who reaches the server |
| `/ws` | telemetry, control (pilot token inside) | anyone (control: the pilot) |
| `/api/health` | liveness, no secrets | anyone |
| `/api/tiles`, `/tiles/{z}/{x}/{y}.png` | the offline tile cache | anyone |
| `/api/logs`, `/logs/{name}.mcap` | MCAP logs (GET, HEAD, Range; CORS for Foxglove's web app) | anyone |
| `/api/recording` | the files being recorded: name, size, duration | anyone |

A file being recorded downloads as a snapshot with a fixed length (lotsen.web.logfiles): readable,
up to the last chunk on disk; no Range (the next request would get a different snapshot).
"""

from __future__ import annotations

import asyncio
import time
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request, WebSocket
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse
from fastapi.staticfiles import StaticFiles

from lotsen.logs.snapshot import scan_extent, snapshot_chunks, snapshot_tail
from lotsen.web.hub import Hub
from lotsen.web.logfiles import (
    FOXGLOVE_APP, RECORDING_WITHIN_S, ExtentCache, foxglove_url, list_logs, recordings, resolve_log,
)
from lotsen.web.tiles import tile_image_type, valid_tile

STATIC = Path(__file__).resolve().parent / "static"

#: the page may load only its own files (tiles included) and talk only to its own server
SECURITY_HEADERS = {
    "Content-Security-Policy": ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
                                "connect-src 'self'; media-src 'self' data:; frame-ancestors 'none'; base-uri 'none'; "
                                "form-action 'none'"),
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-cache",
}

#: Foxglove's web app fetches a remote MCAP from the browser: it needs CORS (and, from a public
#: site to a private address, Chrome's Private Network Access preflight)
LOG_CORS = {"Access-Control-Allow-Origin": FOXGLOVE_APP, "Vary": "Origin",
            "Access-Control-Expose-Headers": "Content-Length, Content-Range, Accept-Ranges, ETag, Last-Modified"}


async def iterate_in_thread(chunks):
    """A file's blocks read off the event loop (the loop also serves the pilot's socket)."""
    it = iter(chunks)
    while True:
        block = await asyncio.to_thread(next, it, None)
        if block is None:
            return
        yield block


def create_app(hub: Hub) -> FastAPI:
    @asynccontextmanager
    async def lifespan(app: FastAPI):
        hub.start(asyncio.get_running_loop())
        try:
            yield
        finally:
            hub.stop()

    app = FastAPI(title="lotsen operator", docs_url=None, redoc_url=None, openapi_url=None, lifespan=lifespan)
    extents = ExtentCache()

    @app.middleware("http")
    async def security_headers(request: Request, call_next):
        response = await call_next(request)
        for k, v in SECURITY_HEADERS.items():
            response.headers.setdefault(k, v)
        return response

    @app.get("/", include_in_schema=False)
    async def index() -> FileResponse:
        return FileResponse(STATIC / "index.html", media_type="text/html")

    @app.get("/api/health")
    async def health() -> JSONResponse:
        """Liveness for scripts: no secrets, no control."""
        return JSONResponse({"ok": True, "clients": len(hub.clients), "pilot": hub.seat.holder is not None,
                             "frames": hub.frames_built})

    # -- offline map tiles --------------------------------------------------------------------
    @app.get("/api/tiles")
    async def tiles_index() -> JSONResponse:
        if hub.tiles is None:
            return JSONResponse({"enabled": False, "count": 0, "zooms": {}})
        index = await asyncio.to_thread(hub.tiles.store.index)
        return JSONResponse({**hub.tiles.info(), **index})

    @app.get("/tiles/{z}/{x}/{y}.png")
    async def tile(z: int, x: int, y: int) -> Response:
        if hub.tiles is None or not valid_tile(z, x, y):
            return Response(status_code=404)
        data = await asyncio.to_thread(hub.tiles.store.read, z, x, y)
        if data is None:
            return Response(status_code=404)
        return Response(data, media_type=tile_image_type(data) or "application/octet-stream",
                        headers={"Cache-Control": "public, max-age=86400"})

    # -- logs ------------------------------------------------------------------------------------
    @app.get("/api/logs")
    async def logs(request: Request) -> JSONResponse:
        entries = await asyncio.to_thread(list_logs, hub.options.log_dir)
        base = str(request.base_url).rstrip("/")
        for e in entries:
            e["url"] = f"/logs/{e['name']}"
            e["foxglove"] = foxglove_url(f"{base}/logs/{e['name']}")
        return JSONResponse({"directory_set": bool(hub.options.log_dir), "logs": entries})

    @app.get("/api/recording")
    async def recording() -> JSONResponse:
        active = await asyncio.to_thread(recordings, hub.options.log_dir, extents)
        for e in active:
            e["url"] = f"/logs/{e['name']}"
        return JSONResponse({"directory_set": bool(hub.options.log_dir), "recording": active})

    @app.api_route("/logs/{name}", methods=["GET", "HEAD"])
    async def log_file(name: str, request: Request) -> Response:
        p = resolve_log(hub.options.log_dir, name)
        if p is None:
            return Response(status_code=404, headers=LOG_CORS)
        ext = await asyncio.to_thread(scan_extent, p)
        if ext is None or ext.closed:  # complete (or not ours to judge): the file as it is
            return FileResponse(p, media_type="application/octet-stream", filename=p.name, headers=LOG_CORS)
        # still recording (or killed before it closed the file): a snapshot of fixed length,
        # readable up to the last complete chunk
        recording = time.time() - p.stat().st_mtime < RECORDING_WITHIN_S
        headers = {**LOG_CORS, "Content-Length": str(ext.end + len(snapshot_tail())), "Accept-Ranges": "none",
                   "Content-Disposition": f'attachment; filename="{p.stem}.partial.mcap"' if recording else
                   f'attachment; filename="{p.name}"',
                   "Cache-Control": "no-store", "X-Lotsen-Recording": "snapshot"}
        if request.method == "HEAD":
            return Response(status_code=200, headers=headers, media_type="application/octet-stream")
        return StreamingResponse(iterate_in_thread(snapshot_chunks(p, ext)), headers=headers,
                                 media_type="application/octet-stream")

    @app.options("/logs/{name}")
    async def log_preflight(name: str) -> Response:
        return Response(status_code=204, headers={
            **LOG_CORS, "Access-Control-Allow-Methods": "GET, HEAD", "Access-Control-Allow-Headers": "Range",
            "Access-Control-Allow-Private-Network": "true", "Access-Control-Max-Age": "600"})

    @app.websocket("/ws")
    async def ws(websocket: WebSocket) -> None:
        await hub.serve(websocket)

    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    return app
