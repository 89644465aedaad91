"""The WebSocket hub: one connection per browser, telemetry fan-out, control messages in.

Threads: the bus is read by a small reader thread through `bus.queue(...)` (drop-oldest, so a
slow web side never blocks the control loop). It keeps the latest value per topic and, when a
new pose arrives (and at least 0.8 telemetry periods have passed), builds one frame, encodes it
once and hands it to the event loop, which offers it to every client. Each client has its own
sender task with a one-frame telemetry slot (a slow browser gets fewer, never older, frames) and a
bounded queue for replies and events. Everything that touches the bus from here goes through
`publish` (thread-safe; in the web process it hands the message to the Zenoh bridge).

Admission (`lotsen.web.admission`): every connection is accepted and, over the limits, the
oldest viewers of the busiest address are closed, never the pilot: the seat stays reachable.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import threading
from collections import deque
from typing import Any, Callable
from urllib.parse import urlsplit

from starlette.websockets import WebSocket, WebSocketDisconnect, WebSocketState

from lotsen.errors import ConfigError
from lotsen.planning import GeoOrigin, PlannerConfig
from lotsen.runtime.bus import Bus
from lotsen.web.admission import choose_evictions
from lotsen.web.auth import AuthGuard, PilotSeat, address_key
from lotsen.web.control import ControlHandler, Publish, RunBlocking, Session, TileJobs, _to_thread
from lotsen.web.options import WebOptions
from lotsen.web.pairing import PilotCredential
from lotsen.web.telemetry import TOPICS, TelemetryState
from lotsen.web.tiles import Preloader, PreloadProgress, TileStore
from lotsen.web.validation import MAX_MESSAGE_CHARS, VIEWER_ALLOWED, VIEWER_MAX_MESSAGE_CHARS

LINK_PERIOD_S = 0.2  # LinkStatus at 5 Hz
COVERAGE_PERIOD_S = 1.0  # the coverage layer's changed cells, at most this often
SLOW_QUEUE = 4  # planning requests waiting per connection
_seq = itertools.count(1)


def dumps(obj: Any) -> str:
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


class Client:
    def __init__(self, ws: WebSocket, session: Session, hub: "Hub") -> None:
        self.ws = ws
        self.session = session
        self.hub = hub
        self.address = session.address
        self.seq = next(_seq)
        self.frame: str | None = None
        self.pending: deque[str] = deque(maxlen=256)
        self.wake = asyncio.Event()
        self.slow: asyncio.Queue = asyncio.Queue(maxsize=SLOW_QUEUE)
        self.frames_sent = 0
        self.evicted = ""

    @property
    def is_pilot(self) -> bool:
        return self.hub.seat.is_pilot(self.session)

    def offer_frame(self, text: str) -> None:
        self.frame = text
        self.wake.set()

    def send(self, obj: dict) -> None:
        self.pending.append(dumps(obj))
        self.wake.set()

    async def sender(self) -> None:
        try:
            while True:
                await self.wake.wait()
                self.wake.clear()
                while self.pending:
                    await self.ws.send_text(self.pending.popleft())
                if self.frame is not None:
                    text, self.frame = self.frame, None
                    await self.ws.send_text(text)
                    self.frames_sent += 1
        except (WebSocketDisconnect, RuntimeError, OSError):
            pass  # the receive loop notices the closed socket and cleans up

    async def slow_worker(self) -> None:
        while True:
            job = await self.slow.get()
            for reply in await job:
                self.send(reply)


class TileService(TileJobs):
    """One tile pre-load at a time for the whole server; progress goes to every page."""

    def __init__(self, hub: "Hub", options: WebOptions) -> None:
        self.hub = hub
        self.options = options
        self.store = TileStore(options.tile_dir)
        self.preloader: Preloader | None = None
        self.progress: PreloadProgress | None = None
        self.task: asyncio.Task | None = None

    @property
    def running(self) -> bool:
        return self.task is not None and not self.task.done()

    def start(self, session: Session, f: dict) -> dict:
        if self.running:
            raise ConfigError("tiles_preload: a pre-load is already running; cancel it first")
        p = Preloader(self.store, self.options.tile_url, max_tiles=self.options.tile_max_count,
                      max_zoom=self.options.tile_max_zoom)
        tiles = p.plan(f["south"], f["west"], f["north"], f["east"], f["zoom_min"], f["zoom_max"])
        self.preloader = p
        self.progress = PreloadProgress(total=len(tiles))
        loop = asyncio.get_running_loop()

        def report(prog: PreloadProgress) -> None:  # worker thread
            msg = dumps({"type": "tiles_progress", **prog.as_dict()})
            try:
                loop.call_soon_threadsafe(self.hub._broadcast_events, [msg])
            except RuntimeError:
                pass

        async def job() -> None:
            self.progress = await asyncio.to_thread(p.run, tiles, report)

        self.task = loop.create_task(job())
        return {"started": True, "total": len(tiles), "zoom_min": f["zoom_min"], "zoom_max": f["zoom_max"]}

    def cancel(self) -> bool:
        if self.running and self.preloader is not None:
            self.preloader.cancel.set()
            return True
        return False

    def info(self) -> dict:
        return {"enabled": bool(self.options.tile_dir), "attribution": self.options.tile_attribution,
                "max_count": self.options.tile_max_count, "max_zoom": self.options.tile_max_zoom,
                "source": urlsplit(self.options.tile_url).netloc,
                "progress": self.progress.as_dict() if self.progress is not None else None}


class Hub:
    def __init__(self, bus: Bus, clock: Callable[[], float], publish: Publish, options: WebOptions,
                 origin: GeoOrigin | None = None, run_blocking: RunBlocking = _to_thread,
                 planner_config: PlannerConfig | None = None) -> None:
        self.bus = bus
        self.clock = clock
        self.options = options
        self.origin = origin
        self.period_s = 1.0 / options.telemetry_rate_hz
        # the boat's credential file when paired (re-read when `lotsen pair --new` replaces it)
        credential = PilotCredential(options.credential_file).current if options.credential_file else options.pilot_token
        self.seat = PilotSeat(credential, options.link_timeout_s, clock)
        self.tiles = TileService(self, options) if options.tile_dir else None
        self.handler = ControlHandler(self.seat, publish, clock, planner_config=planner_config,
                                      run_blocking=run_blocking, notify=self._notify, origin=origin,
                                      auth_guard=AuthGuard(clock), tiles=self.tiles,
                                      viewer_may_estop=options.viewer_may_estop,
                                      broadcast=lambda m: self._broadcast_events([dumps(m)]),
                                      rerun=lambda: self.state.coverage.rerun_route())
        self.clients: dict[Session, Client] = {}
        self.loop: asyncio.AbstractEventLoop | None = None
        self.state = TelemetryState(options.battery_capacity_ah)
        self.frames_built = 0
        self.evictions = 0
        self._stop = threading.Event()
        self._reader: threading.Thread | None = None
        self._queue = None
        self._tasks: list[asyncio.Task] = []

    # -- life cycle (called on the server's event loop) -----------------------------------------
    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        self._queue = self.bus.queue(TOPICS, maxlen=4096)
        # what the core published before we subscribed (the route it holds, its path, ...)
        for topic in TOPICS:
            latest = self.bus.latest.get(topic)
            if latest is not None:
                self.state.update(topic, latest)
        self.state.take_events()
        self._reader = threading.Thread(target=self._read_loop, name="web-telemetry", daemon=True)
        self._reader.start()
        self._tasks.append(loop.create_task(self._link_loop()))

    def stop(self) -> None:
        self._stop.set()
        if self.tiles is not None:
            self.tiles.cancel()
        if self._queue is not None:
            self.bus.remove_queue(self._queue)
        if self._reader is not None:
            self._reader.join(timeout=2.0)
        for t in self._tasks:
            t.cancel()

    async def _link_loop(self) -> None:
        while True:
            self.handler.link_tick()
            await asyncio.sleep(LINK_PERIOD_S)

    # -- telemetry (reader thread) ---------------------------------------------------------------
    def link_json(self) -> dict:
        holder = self.seat.holder
        return {"pilot": holder is not None, "clients": len(self.clients), "ever": self.seat.ever_held,
                "pilot_silent_s": round(self.seat.silent_s(), 2) if holder is not None else None}

    def _read_loop(self) -> None:
        q = self._queue
        last_frame = -1e9
        last_coverage = -1e9
        while not self._stop.is_set():
            # with a page connected: up in time for its next frame; without: only what arrives
            # (logs, alerts, routes) wakes it, or the coverage period (a 40 Hz poll for nobody)
            item = q.get(timeout=self.period_s / 2 if self.clients else COVERAGE_PERIOD_S)
            items = ([item] if item is not None else []) + q.get_all()
            for topic, msg in items:
                self.state.update(topic, msg)
            events = self.state.take_events()
            if self.clock() - last_coverage >= COVERAGE_PERIOD_S:
                last_coverage = self.clock()
                cov = self.state.coverage_event()
                if cov is not None:
                    events.append(cov)
            if events:
                self._call(self._broadcast_events, [dumps(e) for e in events])
            now = self.clock()
            since = now - last_frame
            # a frame per new pose (at most telemetry_rate_hz), or at half rate when no pose flows
            if (self.state.pose_updated and since >= 0.8 * self.period_s) or since >= 2 * self.period_s:
                if self.clients:
                    self._call(self._broadcast_frame, dumps(self.state.frame(now, self.link_json())))
                    self.frames_built += 1
                last_frame = now

    def _call(self, fn: Callable, arg: Any) -> None:
        if self.loop is not None and not self.loop.is_closed():
            try:
                self.loop.call_soon_threadsafe(fn, arg)
            except RuntimeError:  # loop closing during shutdown
                pass

    def _broadcast_frame(self, text: str) -> None:
        for c in self.clients.values():
            c.offer_frame(text)

    def _broadcast_events(self, texts: list[str]) -> None:
        for c in self.clients.values():
            for t in texts:
                c.pending.append(t)
            c.wake.set()

    def _notify(self, session: Session, msg: dict) -> None:
        c = self.clients.get(session)
        if c is not None:
            c.send(msg)

    # -- one connection ---------------------------------------------------------------------------
    @staticmethod
    def origin_allowed(ws: WebSocket) -> bool:
        """Browsers send Origin: a page from another site may not open our socket (it could
        only watch without the token, but it has no business here either)."""
        origin = ws.headers.get("origin")
        if origin is None:
            return True  # not a browser (scripts, benchmarks)
        host = ws.headers.get("host", "")
        return urlsplit(origin).netloc.lower() == host.lower()

    def hello(self, session: Session) -> dict:
        o = self.origin
        last = self.handler.last_upload
        return {"type": "hello", "session": session.id, "telemetry_rate_hz": self.options.telemetry_rate_hz,
                "link_timeout_s": self.options.link_timeout_s, "pilot_present": self.seat.holder is not None,
                "pilot_ever": self.seat.ever_held, "server_t": round(self.clock(), 4),
                "origin": {"lat": o.lat_deg, "lon": o.lon_deg, "h": o.height_m} if o is not None else None,
                "tiles": self.tiles.info() if self.tiles is not None else {"enabled": False},
                "logs": bool(self.options.log_dir),
                "uploaded_route_id": last["route_id"] if last else None,
                "uploaded_detours": last.get("detours", []) if last else [],
                "settings": self.handler.settings.summary(),
                "limits": {"speed_max_mps": self.handler.planner_config.speed_max_mps},
                "viewer_may": sorted(VIEWER_ALLOWED),
                "viewer_may_estop": self.options.viewer_may_estop,
                "max_chars": {"pilot": MAX_MESSAGE_CHARS, "viewer": VIEWER_MAX_MESSAGE_CHARS}}

    async def _evict(self, client: Client, reason: str) -> None:
        client.evicted = reason
        self.evictions += 1
        self.clients.pop(client.session, None)
        try:
            await client.ws.send_text(dumps({"type": "evicted", "reason": reason}))
            await client.ws.close(code=1013, reason=reason[:120])
        except (RuntimeError, OSError, WebSocketDisconnect):
            pass

    async def serve(self, ws: WebSocket) -> None:
        if not self.origin_allowed(ws):
            await ws.close(code=1008, reason="origin not allowed")
            return
        address = address_key(ws.client.host if ws.client else None)
        for victim, reason in choose_evictions(list(self.clients.values()), address, self.options.max_viewers,
                                               self.options.max_per_address):
            await self._evict(victim, reason)
        await ws.accept()
        session = self.handler.open_session(address)
        client = Client(ws, session, self)
        self.clients[session] = client
        tasks = [asyncio.create_task(client.sender()), asyncio.create_task(client.slow_worker())]
        client.send(self.hello(session))
        for event in self.state.replay_events(self.clock()):
            client.send(event)
        try:
            while True:
                event = await ws.receive()
                if event["type"] == "websocket.disconnect":
                    break
                raw = event.get("text")
                replies, job = self.handler.receive(session, raw if raw is not None else event.get("bytes"))
                for r in replies:
                    client.send(r)
                if job is not None:
                    try:
                        client.slow.put_nowait(job)
                    except asyncio.QueueFull:
                        job.close()
                        client.send({"type": "error", "code": "busy", "error": "too many requests in progress"})
                if session.close_requested:
                    await asyncio.sleep(0.05)  # let the last error reach the client
                    await ws.close(code=1008, reason=session.close_requested)
                    break
        except (WebSocketDisconnect, RuntimeError):
            pass
        finally:
            self.handler.close_session(session)
            if self.clients.get(session) is client:
                del self.clients[session]
            for t in tasks:
                t.cancel()
            if ws.client_state == WebSocketState.CONNECTED and not client.evicted:
                try:
                    await ws.close()
                except RuntimeError:
                    pass
