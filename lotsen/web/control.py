"""Control-message handler: one text frame in, replies out, bus messages published only for
a valid message from the pilot. It has no sockets and no threads of its own, so it is tested
(and fuzzed) directly; the hub feeds it frames and sends the replies.

Who may do what (docs/web.md, "Access rules"): a viewer may authenticate, ping, and convert
routes to and from YAML/GeoJSON (64 kB messages, one viewer conversion at a time in all); every
thing that plans, commands, drives or downloads tiles needs the pilot seat; the emergency stop
too, unless `viewer_may_estop` (extra.web.viewer_may_estop) lets any page stop the boat.
"""

from __future__ import annotations

import asyncio
import dataclasses
import itertools
import re
import secrets
from dataclasses import dataclass, field
from typing import Any, Awaitable, Callable

from lotsen.errors import LotsenError
from lotsen.messages import LinkStatus, ManualCommand, OperatorCommand, Topic
from lotsen.planning import GeoOrigin, PlannerConfig
from lotsen.web.auth import MAX_AUTH_FAILURES, AuthError, AuthGuard, PilotSeat
from lotsen.web.planning_api import export_route, import_route, plan_for_display, plan_for_upload
from lotsen.web.ratelimit import RateLimiter
from lotsen.web.settings import Settings
from lotsen.web.validation import (
    MAX_MESSAGE_CHARS, PILOT_ONLY, VIEWER_MAX_MESSAGE_CHARS, Message, ValidationError, parse_message,
)

Publish = Callable[[str, Any], None]
RunBlocking = Callable[..., Awaitable[Any]]

_ids = itertools.count(1)
MAX_ERROR_CHARS = 600
#: a frame this long is charged to the connection's rate limit before it is even decoded
PRECHARGE_CHARS = 2048


@dataclass(eq=False)
class Session:
    """One WebSocket connection's control state."""

    limiter: RateLimiter
    address: str = "?"  # lotsen.web.auth.address_key of the peer
    id: int = field(default_factory=lambda: next(_ids))
    auth_failures: int = 0
    manual_active: bool = False  # the last manual command was non-zero
    close_requested: str = ""  # reason, when the hub should close the socket
    last_rate_error_s: float = -1e9
    source: str = "web"  # who asks, in OperatorCommand.source ("mavlink:255" for a ground station)
    link_timeout_s: float | None = None  # own silence limit as pilot (a ground station's); None: the seat's


async def _to_thread(fn: Callable[..., Any], *args: Any) -> Any:
    return await asyncio.to_thread(fn, *args)


class TileJobs:
    """What the handler needs of the tile pre-load (the hub implements it)."""

    def start(self, session: Session, fields: dict) -> dict:  # pragma: no cover - interface
        """Start a pre-load in the background; ConfigError when the request breaks the caps."""
        raise NotImplementedError

    def cancel(self) -> bool:  # pragma: no cover - interface
        raise NotImplementedError


class ControlHandler:
    """Validates, authorises, rate-limits and turns messages into bus publications.

    `publish(topic, msg)` must be thread-safe towards the nodes. `run_blocking(fn, *args)` runs a
    module-level function with picklable arguments away from the event loop (the stack binds it to
    the planner worker process with its time and memory budget); every planner call and every
    route conversion goes through it. `notify(session, reply)` sends a message to another session
    (a pilot that was taken over).
    """

    def __init__(self, seat: PilotSeat, publish: Publish, clock: Callable[[], float],
                 planner_config: PlannerConfig | None = None, run_blocking: RunBlocking = _to_thread,
                 notify: Callable[[Session, dict], None] | None = None, origin: GeoOrigin | None = None,
                 auth_guard: AuthGuard | None = None, tiles: TileJobs | None = None,
                 viewer_may_estop: bool = False, broadcast: Callable[[dict], None] | None = None,
                 rerun: Callable[[], dict] | None = None) -> None:
        self.seat = seat
        self.publish = publish
        self.clock = clock
        self.planner_config = planner_config or PlannerConfig()
        self.run_blocking = run_blocking
        self.notify = notify or (lambda s, m: None)
        self.sessions: set[Session] = set()
        self.origin = origin  # geographic origin of the local frame, for GeoJSON export
        self.auth_guard = auth_guard or AuthGuard(clock)
        self.tiles = tiles
        self.viewer_may_estop = viewer_may_estop
        self.viewer_jobs = 0  # conversions in flight for viewers (all together)
        self.last_upload: dict | None = None  # {"route_id", "route", "detours"} of the pilot's last upload
        self.settings = Settings(self.planner_config)  # the parameter sheet (lotsen.web.settings)
        self.broadcast = broadcast or (lambda m: None)  # a message to every page
        self.rerun = rerun  # the route over the holes of the held survey (lotsen.web.coverage)
        # the mission's time and energy predicted (route, conditions) -> dict, run in the planner worker; set
        # by the stack (lotsen.stack.page_prediction.PagePredictor), with what the estimator knows now (the
        # stack's EstimatedConditions: the current and the sea; None: nothing known, still water)
        self.predict: Callable[[dict, Any], dict] | None = None
        self.estimated_current: Callable[[], Any] = lambda: None
        self._instance = secrets.token_hex(4)  # request ids of this process never repeat an earlier one's

    # -- connection life cycle ---------------------------------------------------------------
    def open_session(self, address: str = "?") -> Session:
        s = Session(limiter=RateLimiter(self.clock), address=address)
        self.sessions.add(s)
        return s

    def close_session(self, session: Session) -> None:
        """The socket is gone: a pilot's seat is freed and the boat gets a zero manual command."""
        self.sessions.discard(session)
        if self.seat.release(session):
            self._stop_manual(session)

    def _stop_manual(self, session: Session | None) -> None:
        if session is not None:
            session.manual_active = False
        self.publish(Topic.MANUAL, ManualCommand(stamp_s=self.clock(), surge=0.0, sway=0.0, yaw=0.0))

    def link_tick(self) -> LinkStatus:
        """Called at ~5 Hz: publish the pilot's liveness; a silent pilot's driving is zeroed once;
        a pilot seated with a credential that was replaced since (`lotsen pair --new`) loses the seat."""
        holder = self.seat.holder
        if holder is not None and self.seat.holder_revoked():
            self.seat.release(holder)
            self._stop_manual(holder if isinstance(holder, Session) else None)
            self.notify(holder, {"type": "pilot", "pilot": False, "revoked": True,
                                 "reason": "the pilot credential was replaced on the boat (lotsen pair --new): pair again"})
            holder = None
        if isinstance(holder, Session) and holder.manual_active and self.seat.stale():
            self._stop_manual(holder)
        # a pilot that is connected but silent (frozen tab, half-open Wi-Fi) counts as gone
        status = LinkStatus(stamp_s=self.clock(), pilot_connected=holder is not None and not self.seat.stale(),
                            last_heard_s=self.seat.last_heard_s,
                            viewers=len(self.sessions) - (1 if holder is not None else 0))
        self.publish(Topic.LINK, status)
        return status

    # -- messages ----------------------------------------------------------------------------
    SLOW = frozenset({"plan", "route", "export", "import", "rerun", "predict"})  # planner and conversions

    def receive(self, session: Session, raw: Any) -> tuple[list[dict], Awaitable[list[dict]] | None]:
        """Validate, authorise and rate-limit one frame. Fast messages are executed at once;
        slow ones (planning, conversions) come back as a coroutine for the caller to await, so a
        connection's manual driving is never queued behind a planner run. Never raises."""
        try:
            return self._receive(session, raw)
        except Exception as exc:  # noqa: BLE001 - no input may take the server down
            return [_error(None, "internal", f"failed: {exc!r}")], None

    def _receive(self, session: Session, raw: Any) -> tuple[list[dict], Awaitable[list[dict]] | None]:
        is_pilot = self.seat.is_pilot(session)
        precharged = isinstance(raw, (str, bytes)) and len(raw) > PRECHARGE_CHARS
        if precharged and not session.limiter.allow("other"):  # big frames pay before decoding
            return self._rate_error(session, None), None
        try:
            msg = parse_message(raw, MAX_MESSAGE_CHARS if is_pilot else VIEWER_MAX_MESSAGE_CHARS)
        except ValidationError as exc:
            if not precharged and not session.limiter.allow("other"):
                return self._rate_error(session, exc.mid), None
            return [_error(exc.mid, exc.code, str(exc))], None
        kind = msg.type if msg.type in ("manual", "ping") else "other"
        if not precharged and not session.limiter.allow(kind):
            return self._rate_error(session, msg.id), None
        viewer_estop = self.viewer_may_estop and msg.type == "command" and msg.fields.get("action") == "estop"
        if msg.type in PILOT_ONLY and not is_pilot and not viewer_estop:
            return [_error(msg.id, "not_pilot", f"{msg.type}: only the pilot may do this; "
                                                "take the controls with the pilot token first")], None
        self.seat.heard(session)
        method = getattr(self, f"_on_{msg.type}")
        if msg.type in self.SLOW:
            if not is_pilot:
                if self.viewer_jobs >= 1:
                    return [_error(msg.id, "busy", f"{msg.type}: a viewer conversion is running; "
                                                   "viewers convert one at a time, try again")], None
                return [], self._viewer_job(method(session, msg), msg)
            return [], self._guarded(method(session, msg), msg)
        try:
            return method(session, msg), None
        except LotsenError as exc:
            return [_error(msg.id, "invalid", str(exc))], None
        except Exception as exc:  # noqa: BLE001 - no input may take the server down
            return [_error(msg.id, "internal", f"{msg.type}: failed: {exc!r}")], None

    async def handle(self, session: Session, raw: Any) -> list[dict]:
        """All replies to one frame, slow work included (tests, simple callers)."""
        replies, job = self.receive(session, raw)
        return replies + (await job if job is not None else [])

    async def _guarded(self, coro: Awaitable[list[dict]], msg: Message) -> list[dict]:
        try:
            return await coro
        except LotsenError as exc:
            return [_error(msg.id, "invalid", str(exc))]
        except Exception as exc:  # noqa: BLE001
            return [_error(msg.id, "internal", f"{msg.type}: failed: {exc!r}")]

    async def _viewer_job(self, coro: Any, msg: Message) -> list[dict]:
        if self.viewer_jobs >= 1:  # another viewer's job started since this one was accepted
            coro.close()
            return [_error(msg.id, "busy", f"{msg.type}: a viewer conversion is running; try again")]
        self.viewer_jobs += 1
        try:
            return await self._guarded(coro, msg)
        finally:
            self.viewer_jobs -= 1

    def _rate_error(self, session: Session, mid: int | None) -> list[dict]:
        now = self.clock()
        if now - session.last_rate_error_s < 1.0:
            return []  # one error a second is enough; the rest are dropped silently
        session.last_rate_error_s = now
        return [_error(mid, "rate_limited", "rate limit exceeded: message dropped "
                                            "(manual 30/s, ping 20/s, others 5/s)")]

    def _on_auth(self, session: Session, msg: Message) -> list[dict]:
        # the right credential first: it is never throttled, also when another client behind the
        # same address spent the guessing budget (a phone hotspot, one NAT for the jetty)
        if not self.seat.token_ok(msg.fields["token"]):
            spent = not self.auth_guard.allow(session.address)
            session.auth_failures += 1
            if not spent:
                self.auth_guard.failed(session.address)
            if spent or session.auth_failures >= MAX_AUTH_FAILURES:
                session.close_requested = "too many wrong tokens"
            if spent:
                return [_error(msg.id, "rate_limited", "auth: too many wrong tokens from your address "
                               f"(5, then one every {self.auth_guard.wait_s():g} s); wait and try again")]
            return [_error(msg.id, "bad_token", "auth: wrong pilot token")]
        try:
            change = self.seat.claim(session, msg.fields["token"], msg.fields.get("takeover", False))
        except AuthError as exc:
            return [_error(msg.id, exc.code, str(exc))]
        if change.previous is not None:
            if isinstance(change.previous, Session):
                change.previous.manual_active = False
            self.notify(change.previous, {"type": "pilot", "pilot": False, "reason": "taken over by another pilot"})
            self._stop_manual(None)
        return [{"type": "auth_ok", "id": msg.id, "pilot": True}]

    def _on_release(self, session: Session, msg: Message) -> list[dict]:
        self.seat.release(session)
        self._stop_manual(session)
        return [{"type": "pilot", "id": msg.id, "pilot": False, "reason": "released"}]

    def _on_ping(self, session: Session, msg: Message) -> list[dict]:
        return [{"type": "pong", "id": msg.id, "t": msg.fields.get("t"), "server_t": round(self.clock(), 4)}]

    def _on_command(self, session: Session, msg: Message) -> list[dict]:
        action = msg.fields["action"]
        # the page's id of this press; without one, one of ours (the boat answers each id once)
        request = msg.fields.get("request") or f"web-{self._instance}-{next(_ids)}"
        self.publish(Topic.OPERATOR, OperatorCommand(stamp_s=self.clock(), action=action, source=session.source,
                                                     request_id=request))
        # "requested", not "done": the boat's own answer comes as `confirmed` (operator/ack)
        return [{"type": "ack", "id": msg.id, "action": action, "request": request}]

    def _on_manual(self, session: Session, msg: Message) -> list[dict]:
        f = msg.fields
        self.publish(Topic.MANUAL, ManualCommand(stamp_s=self.clock(), surge=f["surge"], sway=f["sway"], yaw=f["yaw"]))
        session.manual_active = any(f[k] != 0.0 for k in ("surge", "sway", "yaw"))
        return []

    async def _on_plan(self, session: Session, msg: Message) -> list[dict]:
        result = await self.run_blocking(plan_for_display, msg.fields["route"], self.planner_config)
        return [{"type": "plan_result", "id": msg.id, **result}]

    async def _on_route(self, session: Session, msg: Message) -> list[dict]:
        """Upload: plan once (in the worker), publish that very plan as a PlannedRoute; the boat's
        read-back (planning/active_route) carries the same route_id."""
        result = await self.run_blocking(plan_for_upload, msg.fields["route"], self.planner_config,
                                         self.clock(), "web")
        if not result["ok"]:
            return [{**_error(msg.id, "route_invalid", result["errors"][0]["message"]), "errors": result["errors"]}]
        if not self.seat.is_pilot(session):  # the seat may have changed while planning
            return [_error(msg.id, "not_pilot", "route: you are no longer the pilot")]
        planned = dataclasses.replace(result.pop("message"), stamp_s=self.clock())
        self.publish(Topic.ROUTE, planned)
        self.last_upload = {"route_id": planned.route_id, "route": result["route"], "detours": result["detours"]}
        return [{"type": "route_ok", "id": msg.id, **{k: result[k] for k in (
            "route_id", "route", "path", "length_m", "duration_s", "segments", "start_ramp", "detours")}}]

    async def _on_export(self, session: Session, msg: Message) -> list[dict]:
        text = await self.run_blocking(export_route, msg.fields["route"], msg.fields["format"], self.origin)
        return [{"type": "export_result", "id": msg.id, "format": msg.fields["format"], "text": text}]

    async def _on_import(self, session: Session, msg: Message) -> list[dict]:
        route = await self.run_blocking(import_route, msg.fields["text"], msg.fields["format"], self.origin)
        return [{"type": "import_result", "id": msg.id, "route": route}]

    async def _on_predict(self, session: Session, msg: Message) -> list[dict]:
        """The route's time and energy before the boat leaves: flown on the model in use in the current
        and the sea the estimator knows now (lotsen.stack.prediction), in the planner worker."""
        if self.predict is None:
            raise LotsenError("predict: this server has no prediction (the boat's stack sets it)")
        result = await self.run_blocking(self.predict, msg.fields["route"], self.estimated_current())
        return [{"type": "predict_result", "id": msg.id, **result}]

    async def _on_rerun(self, session: Session, msg: Message) -> list[dict]:
        """The route over the holes of the survey the boat holds, for the editor (the pilot checks
        and uploads it like any route)."""
        if self.rerun is None:
            raise LotsenError("re-run: this server keeps no coverage layer")
        route = await self.run_blocking(self.rerun)
        return [{"type": "rerun_result", "id": msg.id, "route": route}]

    def _on_pair_qr(self, session: Session, msg: Message) -> list[dict]:
        """The QR code of the pairing address on the page's own origin (the pilot shows it to pair
        another phone; it carries the credential the pilot already holds)."""
        origin = msg.fields["origin"]
        if not re.fullmatch(r"https?://[A-Za-z0-9.\-\[\]:]{1,180}", origin):
            raise LotsenError(f"pair_qr: origin {origin[:60]!r} is not scheme://host[:port]")
        from lotsen.web.pairing import pairing_url, qr_svg

        url = pairing_url(origin, self.seat.current_token())
        return [{"type": "pair_qr", "id": msg.id, "url": url, "svg": qr_svg(url)}]

    def _on_tiles_preload(self, session: Session, msg: Message) -> list[dict]:
        """Starts the download in the background (progress as `tiles_progress` to every page)."""
        if self.tiles is None:
            return [_error(msg.id, "invalid", "tiles_preload: this server has no tile cache (extra.web.tile_dir)")]
        return [{"type": "tiles_started", "id": msg.id, **self.tiles.start(session, msg.fields)}]

    def _on_params(self, session: Session, msg: Message) -> list[dict]:
        """The pilot changes a planner limit (lotsen.web.settings): refused with the reason, or
        used from the next plan on; every page gets the new sheet."""
        self.planner_config = self.settings.set(msg.fields["name"], msg.fields["value"], self.clock())
        summary = self.settings.summary()
        self.broadcast(summary)
        return [{"type": "params_ok", "id": msg.id, "name": msg.fields["name"], "value": msg.fields["value"]}]

    def _on_tiles_cancel(self, session: Session, msg: Message) -> list[dict]:
        cancelled = self.tiles.cancel() if self.tiles is not None else False
        return [{"type": "tiles_cancelled", "id": msg.id, "cancelled": cancelled}]


def _error(mid: int | None, code: str, text: str) -> dict:
    text = str(text)
    if len(text) > MAX_ERROR_CHARS:
        text = text[:MAX_ERROR_CHARS - 1] + "…"
    return {"type": "error", "id": mid, "code": code, "error": text}
