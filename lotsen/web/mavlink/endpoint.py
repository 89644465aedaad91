"""The MAVLink 2 endpoint: ground stations as clients of the supervisor beside the page.

Threads: one reader per connection (pymavlink's `recv_match`) hands every message to the web
server's event loop, where the page's control handler, pilot seat and planner worker live; one
telemetry thread drains a bus queue (drop-oldest, as the page's hub) and sends each connection
its messages at their rates. Sends to one connection are serialised by its lock.

Rules (docs/mavlink.md): a ground station whose messages carry a good MAVLink 2 signature (secret
key = SHA-256 of the pilot token, MAVProxy's `signing setup` convention) is a pilot session of the
control handler: its first signed message takes the free pilot seat, a command takes over a pilot
silent for longer than its timeout, and its silence (no signed message for `gcs_timeout_s`) is
the link failsafe's, as the page's. Unsigned or wrongly signed ground stations get every telemetry
message and read the mission and the parameters; each command, upload, parameter write or manual
input they send is refused with the reason (COMMAND_ACK / MISSION_ACK / PARAM_VALUE unchanged,
plus a STATUSTEXT). Commands become the page's `command` messages: checked first against the
supervisor's `blocked_actions` (the page's button rule), then published, and COMMAND_ACK waits
for the supervisor's status or refusal.
"""

from __future__ import annotations

import asyncio
import hashlib
import itertools
import json
import math
import os
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any

from lotsen.errors import ConfigError, LotsenError
from lotsen.messages import (
    Alert, BatteryStatus, ControllerStatus, GnssFix, GnssFixType, MissionProgress, RouteMessage, SupervisorStatus,
    ThrustCommand, Topic, VesselState,
)
from lotsen.planning import GeoOrigin
from lotsen.planning.formats.items import (
    FENCE, MISSION, RALLY, MissionItem, MissionItemError, Plan, fence_parts, local_frame, plan_from_route,
    route_from_plan, waypoint_seqs,
)
from lotsen.planning.io import route_from_dict
from lotsen.web.control import Session
from lotsen.web.mavlink import mapping as M
from lotsen.web.mavlink.options import MavlinkExtra
from lotsen.web.mavlink.params import PLANNER, WP_SPEED, ParameterTable

os.environ.setdefault("MAVLINK20", "1")  # before pymavlink picks its wire protocol
from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402

TOPICS = (Topic.STATE, Topic.SUPERVISOR, Topic.GNSS, Topic.BATTERY, Topic.PROGRESS, Topic.CONTROL_STATUS,
          Topic.ALERT, Topic.ACTIVE_ROUTE, Topic.SHIP_COMMAND)
MISSION_TYPES = {0: MISSION, 1: FENCE, 2: RALLY}
MISSION_TYPE_IDS = {v: k for k, v in MISSION_TYPES.items()}
#: default rates (Hz): what ArduPilot streams to a ground station that asks for nothing
DEFAULT_RATES_HZ = {
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: 1.0, mavlink.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0,
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 5.0, mavlink.MAVLINK_MSG_ID_ATTITUDE: 10.0,
    mavlink.MAVLINK_MSG_ID_VFR_HUD: 4.0, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT: 2.0, mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.2,
}
#: REQUEST_DATA_STREAM's groups (ArduPilot's), for Mission Planner and MAVProxy
STREAMS = {2: (mavlink.MAVLINK_MSG_ID_SYS_STATUS, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
               mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT, mavlink.MAVLINK_MSG_ID_MISSION_CURRENT),
           6: (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,), 10: (mavlink.MAVLINK_MSG_ID_ATTITUDE,),
           11: (mavlink.MAVLINK_MSG_ID_VFR_HUD,), 12: (mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,)}
MAX_RATE_HZ = 50.0
UPLOAD_RETRY_S = 1.0
UPLOAD_TRIES = 5
GCS_FORGET_S = 600.0  # a ground station silent this long is forgotten (its session closed)
REFUSAL_REPEAT_S = 5.0  # a refused stream (manual control) says why at most this often
#: ArduPilot Rover 4.5.0, official: QGroundControl and Mission Planner check the version
FLIGHT_SW_VERSION = (4 << 24) | (5 << 16) | (0 << 8) | 255
CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_INT | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2 | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
                | mavlink.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY)
_text_ids = itertools.count(1)


def signing_key(token: str) -> bytes:
    """MAVProxy's `signing setup PASSPHRASE`: the 32-byte secret key is SHA-256 of the passphrase."""
    return hashlib.sha256(token.encode("utf-8")).digest()


@dataclass
class Gcs:
    """One ground station (system, component) on a connection, with its session of the handler."""

    key: tuple[int, int]
    session: Session
    signed: bool = False  # its last message carried a good signature
    signature: str = "none"  # "good", "bad" (another key, replayed), "none"
    last_s: float = 0.0
    refused_s: dict[str, float] = field(default_factory=dict)


@dataclass
class Upload:
    """A plan coming in: MISSION_COUNT, then the items one by one as we request them."""

    gcs: Gcs
    mission_type: str
    count: int
    items: dict[int, MissionItem] = field(default_factory=dict)
    asked_s: float = 0.0
    tries: int = 0


class Link:
    """One pymavlink connection (`--mavlink URL`) and what the ground stations on it asked for."""

    def __init__(self, url: str, conn: Any, index: int) -> None:
        self.url, self.conn, self.index = url, conn, index
        self.lock = threading.Lock()
        self.periods = {mid: 1.0 / hz for mid, hz in DEFAULT_RATES_HZ.items()}
        self.due: dict[int, float] = {}
        self.gcs: dict[tuple[int, int], Gcs] = {}
        self.upload: Upload | None = None
        self.downloads: dict[str, list[MissionItem]] = {}
        self.sent = 0
        self.errors = 0

    def send(self, msg: Any) -> None:
        with self.lock:
            try:
                self.conn.mav.send(msg)
                self.sent += 1
            except (OSError, ValueError, AttributeError):  # a ground station gone, a radio unplugged
                self.errors += 1

    def heard_from(self) -> bool:
        return bool(self.gcs)


def open_connection(url: str, system_id: int, component_id: int) -> Any:
    """pymavlink's connection for `url` (udpin/udpout/tcpin/tcp or a serial device[,baud]); ConfigError
    when it cannot be opened (port in use, no such device)."""
    device, baud = url, 57600
    if not url.split(":", 1)[0] in ("udpin", "udpout", "udp", "tcpin", "tcp") and "," in url:
        device, baud_text = url.rsplit(",", 1)
        baud = int(baud_text)
    try:
        return mavutil.mavlink_connection(device, baud=baud, source_system=system_id, source_component=component_id,
                                          autoreconnect=True, dialect="ardupilotmega")
    except (OSError, ValueError) as exc:
        raise ConfigError(f"--mavlink {url}: cannot open it ({getattr(exc, 'strerror', None) or exc})") from None


class MavlinkEndpoint:
    """The ground stations' side of the web process (see the module's docstring)."""

    def __init__(self, hub: Any, options: MavlinkExtra, token: str, origin: GeoOrigin | None,
                 model_parameters: dict[str, float], failsafes: Any, controller: str, control_rate_hz: float,
                 command_deadline_s: float, clock: Any = None) -> None:
        self.hub = hub
        self.handler = hub.handler
        self.bus = hub.bus
        self.clock = clock or hub.clock
        self.options = options
        self.token = token
        self.key = signing_key(token)
        self.origin = origin
        self.frame = local_frame(origin) if origin is not None else None
        self.sysid, self.compid = options.system_id, options.component_id
        self.wp_speed_mps = options.default_speed_mps
        self.params = ParameterTable(self._planner_value, model_parameters, failsafes, controller, control_rate_hz,
                                     command_deadline_s, options.gcs_timeout_s, self.sysid, lambda: self.wp_speed_mps)
        self.links: list[Link] = []
        self.loop: asyncio.AbstractEventLoop | None = None
        self.latest: dict[str, Any] = {}
        self.arrival: dict[str, float] = {}
        self.refusals: deque[tuple[float, Alert]] = deque(maxlen=64)
        self.uploaded: dict[str, Any] = {}  # {"route_id", MISSION: [...], FENCE: [...], RALLY: [...], "home"}
        self.pending_fence: dict | None = None  # a fence uploaded while the boat holds no route
        self.pending_fence_items: list[MissionItem] | None = None
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._queue: Any = None
        self._last_mode: str | None = None
        self._last_node = -1
        self._route_cache: tuple[str, Plan | None] = ("", None)
        self.messages_in = 0

    # -- life cycle -------------------------------------------------------------------------------
    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self.loop = loop
        for i, url in enumerate(self.options.endpoints):
            conn = open_connection(url, self.sysid, self.compid)
            # sign what we send; accept unsigned and wrongly signed messages too (telemetry only:
            # each message is judged by its own signature)
            conn.setup_signing(self.key, sign_outgoing=True, allow_unsigned_callback=lambda mav, msgid: True,
                               link_id=i)
            self.links.append(Link(url, conn, i))
        self._queue = self.bus.queue(TOPICS, maxlen=2048)
        for topic in TOPICS:
            msg = self.bus.latest.get(topic)
            if msg is not None:
                self._update(topic, msg, quiet=True)
        for link in self.links:
            t = threading.Thread(target=self._read_loop, args=(link,), name=f"mavlink-read-{link.index}", daemon=True)
            t.start()
            self._threads.append(t)
        t = threading.Thread(target=self._telemetry_loop, name="mavlink-telemetry", daemon=True)
        t.start()
        self._threads.append(t)

    def stop(self) -> None:
        self._stop.set()
        if self._queue is not None:
            self.bus.remove_queue(self._queue)
        for t in self._threads:
            t.join(timeout=2.0)
        for link in self.links:
            try:
                link.conn.close()
            except Exception:  # noqa: BLE001 - closing on the way out
                pass

    def banner(self) -> list[str]:
        return [f"MAVLink endpoint: {link.url} (system {self.sysid}, ArduPilot Rover identity; commands need "
                "MAVLink 2 signing with the pilot token as passphrase)" for link in self.links]

    # -- reading (one thread per connection) --------------------------------------------------------
    def _read_loop(self, link: Link) -> None:
        while not self._stop.is_set():
            try:
                m = link.conn.recv_match(blocking=True, timeout=0.2)
            except Exception:  # noqa: BLE001 - a garbled or hostile frame must not end the link
                link.errors += 1
                time.sleep(0.01)
                continue
            if m is None or m.get_type() == "BAD_DATA":
                continue
            if m.get_srcSystem() == self.sysid and m.get_srcComponent() == self.compid:
                continue  # our own, echoed
            self.messages_in += 1
            if self.loop is not None and not self.loop.is_closed():
                try:
                    self.loop.call_soon_threadsafe(self._on_message, link, m)
                except RuntimeError:
                    return

    def _gcs(self, link: Link, m: Any) -> Gcs:
        key = (m.get_srcSystem(), m.get_srcComponent())
        gcs = link.gcs.get(key)
        if gcs is None:
            session = self.handler.open_session(address=f"mavlink {link.url} {key[0]}/{key[1]}")
            session.source = f"mavlink:{key[0]}"
            session.link_timeout_s = self.options.gcs_timeout_s
            gcs = link.gcs[key] = Gcs(key, session)
        signed = bool(getattr(m, "_signed", False))
        header = getattr(m, "_header", None)
        has_signature = bool(header is not None and header.incompat_flags & mavlink.MAVLINK_IFLAG_SIGNED)
        gcs.signed = signed
        gcs.signature = "good" if signed else "bad" if has_signature else "none"
        gcs.last_s = self.clock()
        return gcs

    def _on_message(self, link: Link, m: Any) -> None:
        """On the event loop: one message of a ground station."""
        try:
            gcs = self._gcs(link, m)
            if gcs.signed:
                self.handler.seat.heard(gcs.session)  # its signed traffic is the pilot's link
                if m.get_type() == "HEARTBEAT" and self.handler.seat.holder is None:
                    self._claim(gcs, takeover=False)  # a free seat goes to the signed ground station
            handler = getattr(self, f"_on_{m.get_type().lower()}", None)
            if handler is not None:
                handler(link, gcs, m)
        except Exception as exc:  # noqa: BLE001 - no message may take the web process down
            self._text(link, "error", f"lotsen: {m.get_type()} failed: {exc!r}"[:200])

    # -- who may act --------------------------------------------------------------------------------
    def _why_unsigned(self, gcs: Gcs) -> str:
        how = "signed with another key (or replayed)" if gcs.signature == "bad" else "not signed"
        return (f"this ground station's messages are {how}: commands need MAVLink 2 signing with the pilot token "
                "as passphrase (MAVProxy: signing setup TOKEN)")

    def _claim(self, gcs: Gcs, takeover: bool) -> str:
        """Take the pilot seat for `gcs` ('' on success, else the reason), as the page's `auth`."""
        if self.handler.seat.is_pilot(gcs.session):
            return ""
        replies, _ = self.handler.receive(gcs.session, json.dumps({"type": "auth", "token": self.token,
                                                                   "takeover": takeover}))
        reply = replies[0] if replies else {}
        if reply.get("type") == "auth_ok":
            self.handler.link_tick()  # the boat hears its new pilot before the first command
            return ""
        return str(reply.get("error", "the pilot seat is not free"))

    def _authorise(self, gcs: Gcs, signed: bool) -> str:
        """'' when `gcs` may act now (a signed message, and it is or becomes the pilot)."""
        if not signed:
            return self._why_unsigned(gcs)
        return self._claim(gcs, takeover=True)

    # -- sending --------------------------------------------------------------------------------------
    def _text(self, link: Link | None, severity: str, text: str) -> None:
        """STATUSTEXT to one connection (None: all), in 50-byte chunks of one id when longer."""
        chunks = M.statustext_chunks(text)
        tid = next(_text_ids) % 65535 + 1 if len(chunks) > 1 else 0
        sev = M.SEVERITY.get(severity, 6)
        for k, chunk in enumerate(chunks):
            msg = mavlink.MAVLink_statustext_message(sev, chunk.encode("utf-8"), tid, k)
            for lk in ([link] if link is not None else self.links):
                lk.send(msg)

    def _ack(self, link: Link, gcs: Gcs, command: int, result: int, text: str = "", severity: str = "warning") -> None:
        if text:
            self._text(link, severity, text)
        link.send(mavlink.MAVLink_command_ack_message(command, result, 0, 0, gcs.key[0], gcs.key[1]))

    def _refuse_stream(self, link: Link, gcs: Gcs, what: str, why: str) -> None:
        now = self.clock()
        if now - gcs.refused_s.get(what, -1e9) >= REFUSAL_REPEAT_S:
            gcs.refused_s[what] = now
            self._text(link, "warning", f"{what} refused: {why}")

    # -- commands -------------------------------------------------------------------------------------
    def _on_command_long(self, link: Link, gcs: Gcs, m: Any) -> None:
        self._command(link, gcs, m.command, (m.param1, m.param2, m.param3, m.param4, m.param5, m.param6, m.param7),
                      m.target_system)

    def _on_command_int(self, link: Link, gcs: Gcs, m: Any) -> None:
        self._command(link, gcs, m.command, (m.param1, m.param2, m.param3, m.param4, m.x, m.y, m.z), m.target_system)

    def _on_set_mode(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system in (0, self.sysid):
            self._command(link, gcs, M.CMD_DO_SET_MODE, (float(m.base_mode), float(m.custom_mode), 0, 0, 0, 0, 0),
                          m.target_system)

    def _command(self, link: Link, gcs: Gcs, command: int, p: tuple, target: int) -> None:
        if target not in (0, self.sysid):
            return
        if command == M.CMD_SET_MESSAGE_INTERVAL:
            self._set_interval(link, int(p[0]), p[1])
            return self._ack(link, gcs, command, M.ACCEPTED)
        if command == M.CMD_REQUEST_MESSAGE:
            msg = self._build(int(p[0]))
            if msg is None:
                return self._ack(link, gcs, command, M.UNSUPPORTED, f"message {int(p[0])}: not sent by lotsen")
            link.send(msg)
            return self._ack(link, gcs, command, M.ACCEPTED)
        if command == M.CMD_GET_HOME_POSITION:
            msg = self._build(mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            if msg is not None:
                link.send(msg)
            return self._ack(link, gcs, command, M.ACCEPTED if msg is not None else M.TEMPORARILY_REJECTED,
                             "" if msg is not None else "no harbour known yet (upload a mission)")
        if command == M.CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            link.send(self._autopilot_version())
            return self._ack(link, gcs, command, M.ACCEPTED)
        if command == M.CMD_REQUEST_PROTOCOL_VERSION:
            return self._ack(link, gcs, command, M.UNSUPPORTED)
        if command == M.CMD_DO_CHANGE_SPEED:
            assert self.loop is not None
            self.loop.create_task(self._change_speed(link, gcs, gcs.signed, float(p[1])))
            return
        req = M.command_request(command, p)
        name = M.COMMAND_NAMES.get(command, f"MAV_CMD {command}")
        if req is None:
            return self._ack(link, gcs, command, M.UNSUPPORTED, f"{name}: not supported by lotsen (docs/mavlink.md)")
        if req.refusal:
            return self._ack(link, gcs, command, M.UNSUPPORTED if req.unsupported else M.DENIED,
                             f"{name} refused: {req.refusal}")
        assert self.loop is not None
        self.loop.create_task(self._action(link, gcs, gcs.signed, command, req.action))

    async def _action(self, link: Link, gcs: Gcs, signed: bool, command: int, action: str) -> None:
        why = self._authorise(gcs, signed)
        if why:
            return self._ack(link, gcs, command, M.DENIED, f"{action} refused: {why}")
        status = self.latest.get(Topic.SUPERVISOR)
        if not isinstance(status, SupervisorStatus):
            return self._ack(link, gcs, command, M.TEMPORARILY_REJECTED,
                             f"{action} refused: the boat's supervisor has not reported yet")
        blocked = dict(b.split(": ", 1) if ": " in b else (b, "not possible now") for b in status.blocked_actions)
        if action in blocked:
            return self._ack(link, gcs, command, M.TEMPORARILY_REJECTED, _refusal_text(action, blocked[action]))
        t0 = self.clock()
        replies, _ = self.handler.receive(gcs.session, json.dumps({"type": "command", "action": action}))
        if not replies or replies[0].get("type") != "ack":
            return self._ack(link, gcs, command, M.DENIED, f"{action} refused: "
                             f"{(replies[0].get('error') if replies else 'no answer')}")
        result, text = await self._outcome(action, t0)
        self._ack(link, gcs, command, result, text, severity="info" if result == M.ACCEPTED else "warning")

    async def _outcome(self, action: str, t0: float) -> tuple[int, str]:
        """ACCEPTED when the supervisor's status shows the action done, TEMPORARILY_REJECTED with
        its reason when it refused (its alert), FAILED when neither came within the timeout."""
        deadline = t0 + self.options.command_timeout_s
        while True:
            for t, alert in list(self.refusals):
                if t >= t0 and alert.code == f"refused:{action}":
                    return M.TEMPORARILY_REJECTED, _refusal_text(action, alert.text.split("refused: ", 1)[-1])
            status = self.latest.get(Topic.SUPERVISOR)
            if isinstance(status, SupervisorStatus) and self.arrival.get(Topic.SUPERVISOR, -1.0) >= t0 \
                    and M.expected(action, status.mode, status.armed):
                return M.ACCEPTED, ""
            if self.clock() > deadline:
                mode = status.mode if isinstance(status, SupervisorStatus) else "?"
                reason = status.reason if isinstance(status, SupervisorStatus) else ""
                return M.FAILED, f"{action}: no confirmation from the boat within {self.options.command_timeout_s:g} s " \
                                 f"(mode {mode}: {reason})"[:300]
            await asyncio.sleep(0.02)

    async def _change_speed(self, link: Link, gcs: Gcs, signed: bool, speed_mps: float) -> None:
        """DO_CHANGE_SPEED: the speed of every node of the route the boat holds (planned again and
        uploaded), and WP_SPEED for the next mission. While the boat moves it is refused: a new
        route stops AUTO (the supervisor holds), which a speed change must not do."""
        cmd = M.CMD_DO_CHANGE_SPEED
        why = self._authorise(gcs, signed)
        if why:
            return self._ack(link, gcs, cmd, M.DENIED, f"change speed refused: {why}")
        limit = self.handler.planner_config.speed_max_mps
        if not (math.isfinite(speed_mps) and 0 < speed_mps <= limit):
            return self._ack(link, gcs, cmd, M.DENIED, f"change speed refused: {speed_mps:g} m/s is outside "
                             f"(0, {limit:g}] m/s (PLN_SPEED_MAX)")
        status = self.latest.get(Topic.SUPERVISOR)
        if isinstance(status, SupervisorStatus) and status.mode in ("AUTO", "RETURN"):
            return self._ack(link, gcs, cmd, M.TEMPORARILY_REJECTED, "change speed refused while the boat follows "
                             "a path: the planner sets each node's speed; switch to HOLD (LOITER), change it, "
                             "then AUTO follows the new plan from its start")
        self.wp_speed_mps = speed_mps
        active = self.latest.get(Topic.ACTIVE_ROUTE)
        if not isinstance(active, RouteMessage) or not active.route:
            return self._ack(link, gcs, cmd, M.ACCEPTED, f"WP_SPEED {speed_mps:g} m/s for the next mission "
                             "(the boat holds no route)", severity="info")
        route = {**active.route, "nodes": [{**n, "speed_mps": speed_mps} for n in active.route["nodes"]]}
        ok, text = await self._upload_route(gcs, route)
        self._ack(link, gcs, cmd, M.ACCEPTED if ok else M.FAILED, text or f"route planned again at {speed_mps:g} m/s",
                  severity="info" if ok else "warning")

    def _set_interval(self, link: Link, msgid: int, interval_us: float) -> None:
        if interval_us < 0:
            link.periods.pop(msgid, None)
        elif interval_us == 0:
            if msgid in DEFAULT_RATES_HZ:
                link.periods[msgid] = 1.0 / DEFAULT_RATES_HZ[msgid]
        else:
            link.periods[msgid] = max(interval_us * 1e-6, 1.0 / MAX_RATE_HZ)
        link.due.pop(msgid, None)

    def _on_request_data_stream(self, link: Link, gcs: Gcs, m: Any) -> None:
        groups = STREAMS.values() if m.req_stream_id == 0 else [STREAMS.get(m.req_stream_id, ())]
        for group in groups:
            for msgid in group:
                if m.start_stop and m.req_message_rate > 0:
                    self._set_interval(link, msgid, 1e6 / min(float(m.req_message_rate), MAX_RATE_HZ))
                elif not m.start_stop:
                    self._set_interval(link, msgid, -1)

    def _on_timesync(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.tc1 == 0:
            link.send(mavlink.MAVLink_timesync_message(time.monotonic_ns(), m.ts1))

    def _on_setup_signing(self, link: Link, gcs: Gcs, m: Any) -> None:
        if bytes(m.secret_key) != self.key:
            self._text(link, "warning", "SETUP_SIGNING ignored: lotsen's key is SHA-256 of the pilot token; a ground "
                                        "station cannot change it (use the token as the signing passphrase)")

    # -- manual control -------------------------------------------------------------------------------
    def _on_manual_control(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target not in (0, self.sysid):
            return
        if not gcs.signed:
            return self._refuse_stream(link, gcs, "manual control", self._why_unsigned(gcs))
        if not self.handler.seat.is_pilot(gcs.session):
            why = self._claim(gcs, takeover=False)
            if why:
                return self._refuse_stream(link, gcs, "manual control", why)

        def axis(v: int) -> float:
            return 0.0 if v == 32767 else max(-1.0, min(1.0, v / 1000.0))  # INT16_MAX: axis not used

        replies, _ = self.handler.receive(gcs.session, json.dumps(
            {"type": "manual", "surge": axis(m.x), "sway": axis(m.y), "yaw": axis(m.r)}))
        if replies and replies[0].get("type") == "error" and replies[0].get("code") != "rate_limited":
            self._refuse_stream(link, gcs, "manual control", str(replies[0].get("error")))

    # -- parameters ---------------------------------------------------------------------------------
    def _planner_value(self, setting: str) -> float:
        return float(getattr(self.handler.planner_config, setting.removeprefix("planner.")))

    def _param_value(self, name: str) -> Any:
        return mavlink.MAVLink_param_value_message(name.encode("ascii"), self.params.value(name),
                                                   mavlink.MAV_PARAM_TYPE_REAL32, len(self.params),
                                                   self.params.index(name))

    def _on_param_request_list(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system in (0, self.sysid):
            for p in self.params.params:
                link.send(self._param_value(p.name))

    def _on_param_request_read(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system not in (0, self.sysid):
            return
        name = _param_id(m.param_id)
        if m.param_index >= 0 and m.param_index < len(self.params) and not name:
            name = self.params.params[m.param_index].name
        if name in self.params.by_name:
            link.send(self._param_value(name))

    def _on_param_set(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system not in (0, self.sysid):
            return
        name = _param_id(m.param_id)
        if name not in self.params.by_name:
            return self._text(link, "warning", f"{name}: no such parameter")
        why = self._authorise(gcs, gcs.signed)
        p = self.params.by_name[name]
        value = float(m.param_value)
        if not why and not p.writable:
            why = f"read-only ({p.doc})"
        if not why and name == WP_SPEED:
            limit = self.handler.planner_config.speed_max_mps
            if not (math.isfinite(value) and 0.05 <= value <= limit):
                why = f"{value:g} m/s is outside [0.05, {limit:g}] m/s (PLN_SPEED_MAX)"
            else:
                self.wp_speed_mps = value
        elif not why:
            replies, _ = self.handler.receive(gcs.session, json.dumps({"type": "params", "name": PLANNER[name],
                                                                       "value": value}, allow_nan=True))
            if not replies or replies[0].get("type") != "params_ok":
                why = str(replies[0].get("error") if replies else "no answer")
        if why:
            self._text(link, "warning", f"{name} not set: {why}")
        # the value now, changed or not: a ground station reads a refusal as the old value coming back
        msg = self._param_value(name)
        for lk in self.links:  # every ground station sees a change
            if lk is link or not why:
                lk.send(msg)

    # -- the mission protocol -------------------------------------------------------------------------
    def _mission_ack(self, link: Link, gcs: Gcs, mission_type: str, result: int, text: str = "") -> None:
        if text:
            self._text(link, "warning" if result else "info", text)
        link.send(mavlink.MAVLink_mission_ack_message(gcs.key[0], gcs.key[1], result, MISSION_TYPE_IDS[mission_type]))

    def _plan_items(self, mission_type: str) -> list[MissionItem]:
        """What a download returns: the items uploaded when the boat still holds that route (the
        read-back returns what was uploaded), else the boat's route as items; home is item 0."""
        status = self.latest.get(Topic.SUPERVISOR)
        route_id = status.route_id if isinstance(status, SupervisorStatus) else ""
        if route_id and self.uploaded.get("route_id") == route_id and mission_type in self.uploaded:
            items = self.uploaded[mission_type]
        else:
            plan = self._route_plan()
            if plan is None:
                return []
            items = {MISSION: [plan.home, *plan.mission], FENCE: plan.fence, RALLY: plan.rally}[mission_type]
        return [replace(it, seq=k) for k, it in enumerate(items) if it is not None]

    def _route_plan(self) -> Plan | None:
        """The boat's route (planning/active_route) as items, cached per route id."""
        active = self.latest.get(Topic.ACTIVE_ROUTE)
        if not isinstance(active, RouteMessage) or not active.route or self.origin is None:
            return None
        if self._route_cache[0] != active.route_id:
            try:
                plan = plan_from_route(route_from_dict(active.route, validate=False), self.origin)
            except LotsenError:
                plan = None
            self._route_cache = (active.route_id, plan)
        return self._route_cache[1]

    def _on_mission_request_list(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system not in (0, self.sysid):
            return
        kind = MISSION_TYPES.get(getattr(m, "mission_type", 0), MISSION)
        link.downloads[kind] = self._plan_items(kind)
        link.send(mavlink.MAVLink_mission_count_message(gcs.key[0], gcs.key[1], len(link.downloads[kind]),
                                                        MISSION_TYPE_IDS[kind]))

    def _send_item(self, link: Link, gcs: Gcs, m: Any, as_int: bool) -> None:
        kind = MISSION_TYPES.get(getattr(m, "mission_type", 0), MISSION)
        items = link.downloads.get(kind)
        if items is None:
            items = link.downloads[kind] = self._plan_items(kind)
        if not 0 <= m.seq < len(items):
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_INVALID_SEQUENCE,
                                     f"{kind} item {m.seq}: there are {len(items)} items")
        it = items[m.seq]
        args = (gcs.key[0], gcs.key[1], it.seq, it.frame, it.command, int(it.seq == 0 and kind == MISSION),
                int(it.autocontinue), it.param1, it.param2, it.param3, it.param4)
        if as_int:
            link.send(mavlink.MAVLink_mission_item_int_message(*args, int(round(it.lat_deg * 1e7)),
                                                               int(round(it.lon_deg * 1e7)), it.alt_m,
                                                               MISSION_TYPE_IDS[kind]))
        else:
            link.send(mavlink.MAVLink_mission_item_message(*args, it.lat_deg, it.lon_deg, it.alt_m,
                                                           MISSION_TYPE_IDS[kind]))

    def _on_mission_request_int(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system in (0, self.sysid):
            if link.upload is None or link.upload.gcs is not gcs:
                self._send_item(link, gcs, m, as_int=True)

    def _on_mission_request(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system in (0, self.sysid):
            if link.upload is None or link.upload.gcs is not gcs:
                self._send_item(link, gcs, m, as_int=False)

    def _on_mission_count(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system not in (0, self.sysid):
            return
        kind = MISSION_TYPES.get(getattr(m, "mission_type", 0), MISSION)
        why = self._authorise(gcs, gcs.signed)
        if why:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_DENIED, f"{kind} upload refused: {why}")
        if self.origin is None:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ERROR, f"{kind} upload refused: the boat "
                                     "has no geographic origin (set `origin` in the launch config)")
        if m.count == 0:
            assert self.loop is not None
            self.loop.create_task(self._clear(link, gcs, kind))
            return
        if m.count > 1000:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_NO_SPACE,
                                     f"{kind} upload refused: {m.count} items, at most 1000")
        link.upload = Upload(gcs, kind, int(m.count))
        self._request_next(link)
        assert self.loop is not None
        self.loop.create_task(self._watch_upload(link, link.upload))

    def _request_next(self, link: Link) -> None:
        up = link.upload
        if up is None:
            return
        seq = next(k for k in range(up.count) if k not in up.items)
        up.asked_s = self.clock()
        up.tries += 1
        link.send(mavlink.MAVLink_mission_request_int_message(up.gcs.key[0], up.gcs.key[1], seq,
                                                              MISSION_TYPE_IDS[up.mission_type]))

    async def _watch_upload(self, link: Link, up: Upload) -> None:
        """Re-request a missing item (lossy radio links); give up after UPLOAD_TRIES."""
        while link.upload is up:
            await asyncio.sleep(UPLOAD_RETRY_S / 4)
            if link.upload is up and self.clock() - up.asked_s > UPLOAD_RETRY_S:
                if up.tries >= UPLOAD_TRIES + len(up.items):
                    link.upload = None
                    self._mission_ack(link, up.gcs, up.mission_type, mavlink.MAV_MISSION_OPERATION_CANCELLED,
                                      f"{up.mission_type} upload cancelled: item {len(up.items)} did not come")
                    return
                self._request_next(link)

    def _on_mission_item_int(self, link: Link, gcs: Gcs, m: Any) -> None:
        self._item(link, gcs, m, m.x * 1e-7, m.y * 1e-7)

    def _on_mission_item(self, link: Link, gcs: Gcs, m: Any) -> None:
        self._item(link, gcs, m, m.x, m.y)

    def _item(self, link: Link, gcs: Gcs, m: Any, lat: float, lon: float) -> None:
        up = link.upload
        if up is None or up.gcs is not gcs or m.target_system not in (0, self.sysid):
            return
        if not gcs.signed:  # every item of an upload must be signed, not only its count
            link.upload = None
            return self._mission_ack(link, gcs, up.mission_type, mavlink.MAV_MISSION_DENIED,
                                     f"{up.mission_type} upload refused: {self._why_unsigned(gcs)}")
        if m.seq in up.items or m.seq >= up.count:
            return
        up.items[m.seq] = MissionItem(m.seq, m.command, m.frame, m.param1, m.param2, m.param3, m.param4, lat, lon,
                                      m.z, bool(m.autocontinue))
        if len(up.items) < up.count:
            up.tries = 0
            self._request_next(link)
            return
        link.upload = None
        assert self.loop is not None
        self.loop.create_task(self._finish_upload(link, up))

    async def _finish_upload(self, link: Link, up: Upload) -> None:
        items = [up.items[k] for k in range(up.count)]
        kind, gcs = up.mission_type, up.gcs
        assert self.origin is not None
        try:
            if kind == MISSION:
                plan = Plan(home=items[0], mission=items[1:])
            elif kind == FENCE:
                plan = Plan(fence=items)
            else:
                plan = Plan(rally=items)
            base = self._base_route()
            if base is None and kind == FENCE:
                self.pending_fence, self.pending_fence_items = fence_parts(items, self.origin), items
                return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ACCEPTED, "fence kept: it goes to the "
                                         "boat with the next mission (the boat holds no route)")
            if base is None and kind == RALLY:
                return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ERROR, "rally refused: the harbour "
                                         "is part of a route; upload the mission first")
            route = route_from_plan(plan, self.origin, self.wp_speed_mps, base)
        except MissionItemError as exc:
            code = mavlink.MAV_MISSION_UNSUPPORTED if "not supported" in str(exc) or "does not" in str(exc) \
                else mavlink.MAV_MISSION_INVALID
            return self._mission_ack(link, gcs, kind, code, f"{kind} refused: {exc}")
        except LotsenError as exc:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_INVALID, f"{kind} refused: {exc}")
        held = self._held_route_id()  # before this upload: the items stored for it stay valid for the parts kept
        ok, text = await self._upload_route(gcs, route, items[1:] if kind == MISSION else None)
        if not ok:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_INVALID, f"{kind} refused: {text}")
        previous = self.uploaded if held and self.uploaded.get("route_id") == held else {}
        kept = {k: previous[k] for k in (MISSION, FENCE, RALLY) if k in previous and k != kind}
        if kind == RALLY:
            kept.pop(MISSION, None)  # its home (item 0) was the old harbour: read back from the route instead
        if kind == MISSION and self.pending_fence_items:
            kept[FENCE] = self.pending_fence_items
        self.uploaded = {**kept, "route_id": text, kind: items}
        self.pending_fence = self.pending_fence_items = None
        self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ACCEPTED)

    def _held_route_id(self) -> str:
        status = self.latest.get(Topic.SUPERVISOR)
        return status.route_id if isinstance(status, SupervisorStatus) else ""

    def _base_route(self) -> dict | None:
        """The route the boat holds (its read-back) with a fence uploaded before it; None: no route."""
        active = self.latest.get(Topic.ACTIVE_ROUTE)
        base = dict(active.route) if isinstance(active, RouteMessage) and active.route else None
        if self.pending_fence is not None:
            base = {k: v for k, v in (base or {}).items() if k not in ("area", "obstacles")}
            base.update(self.pending_fence)
        return base

    async def _upload_route(self, gcs: Gcs, route: dict, mission: list[MissionItem] | None = None) -> tuple[bool, str]:
        """Plan and publish `route` as the page's upload does: (True, route_id) or (False, the
        planner's reason, its node named as the mission item when `mission` is given)."""
        route = {k: v for k, v in route.items() if k != "origin"}
        t0 = self.clock()
        replies, job = self.handler.receive(gcs.session, json.dumps({"type": "route", "route": route}))
        if job is not None:
            replies = replies + await job
        reply = replies[0] if replies else {}
        if reply.get("type") == "route_ok":
            # accepted when the boat says it holds it (its status's route id), as the page's read-back
            rid = str(reply["route_id"])
            deadline = self.clock() + 2 * self.options.command_timeout_s
            while self.clock() < deadline:
                if self._held_route_id() == rid:
                    return True, rid
                for t, alert in list(self.refusals):
                    if t >= t0 and alert.code == "refused:route":
                        return False, alert.text
                await asyncio.sleep(0.02)
            return False, f"the boat did not confirm route {rid} within {2 * self.options.command_timeout_s:g} s"
        text = str(reply.get("error", "no answer from the planner"))
        if mission is not None:
            text = _name_items(text, waypoint_seqs(mission))
        return False, text

    async def _clear(self, link: Link, gcs: Gcs, kind: str) -> None:
        """MISSION_CLEAR_ALL (or a count of 0): a fence is removed (the route planned again without
        it); the mission and the harbour cannot be: the boat keeps a route to return along."""
        if kind == FENCE:
            self.pending_fence = self.pending_fence_items = None
        base = self._base_route()
        if kind == FENCE:
            if base is None or ("area" not in base and "obstacles" not in base):
                return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ACCEPTED)
            ok, text = await self._upload_route(gcs, {k: v for k, v in base.items() if k not in ("area", "obstacles")})
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_ERROR,
                                     "" if ok else f"fence clear refused: {text}")
        if base is None:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_ACCEPTED)
        self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_DENIED, f"{kind} clear refused: the boat keeps the "
                          "route it holds (it returns along it); upload a new mission to replace it")

    def _on_mission_clear_all(self, link: Link, gcs: Gcs, m: Any) -> None:
        if m.target_system not in (0, self.sysid):
            return
        kind = MISSION_TYPES.get(getattr(m, "mission_type", 0), MISSION)
        why = self._authorise(gcs, gcs.signed)
        if why:
            return self._mission_ack(link, gcs, kind, mavlink.MAV_MISSION_DENIED, f"{kind} clear refused: {why}")
        assert self.loop is not None
        self.loop.create_task(self._clear(link, gcs, kind))

    def _on_mission_set_current(self, link: Link, gcs: Gcs, m: Any) -> None:
        self._text(link, "warning", "set current waypoint refused: lotsen follows its planned path from the start")

    # -- telemetry (its own thread) ---------------------------------------------------------------------
    def _telemetry_loop(self) -> None:
        q = self._queue
        while not self._stop.is_set():
            item = q.get(timeout=0.02)
            for topic, msg in ([item] if item is not None else []) + q.get_all():
                self._update(topic, msg)
            now = time.monotonic()
            for link in self.links:
                for msgid, period in list(link.periods.items()):
                    due = link.due.get(msgid, 0.0)
                    if now >= due:
                        link.due[msgid] = max(due + period, now) if due else now + period
                        msg = self._build(msgid)
                        if msg is not None:
                            link.send(msg)

    def _update(self, topic: str, msg: Any, quiet: bool = False) -> None:
        self.latest[topic] = msg
        self.arrival[topic] = self.clock()
        if quiet:
            return
        if topic == Topic.ALERT and isinstance(msg, Alert):
            if msg.code.startswith("refused:") and msg.active:
                self.refusals.append((self.clock(), msg))
            self._text(None, msg.severity if msg.active else "info",
                       msg.text if msg.active else f"cleared: {msg.text}")
        elif topic == Topic.SUPERVISOR and isinstance(msg, SupervisorStatus):
            if msg.mode != self._last_mode:
                if self._last_mode == "AUTO" and "finished" in msg.reason:
                    self._reached(len(self._waypoints()) - 1)
                reported = M.REPORTED_MODE.get(msg.mode, "HOLD")
                note = f" (reported as {reported})" if msg.mode in M.WITHOUT_ROVER_NUMBER else ""
                self._text(None, "critical" if msg.mode == "ESTOP" else "info", f"mode {msg.mode}{note}: {msg.reason}")
                self._last_mode = msg.mode
        elif topic == Topic.PROGRESS and isinstance(msg, MissionProgress):
            if msg.mode == "AUTO" and msg.next_node > self._last_node >= 0:
                for k in range(self._last_node, msg.next_node):
                    self._reached(k)
            self._last_node = msg.next_node if msg.mode == "AUTO" else -1

    def _waypoints(self) -> list[int]:
        """Mission sequence numbers of the route's nodes, as a download numbers them."""
        return waypoint_seqs(self._plan_items(MISSION)[1:])  # item 0 is home (the harbour)

    def _reached(self, node: int) -> None:
        seqs = self._waypoints()
        if 0 <= node < len(seqs):
            msg = mavlink.MAVLink_mission_item_reached_message(seqs[node])
            for link in self.links:
                link.send(msg)
            self._text(None, "info", f"Reached waypoint #{seqs[node]}")  # as ArduPilot says it

    def _boot_ms(self) -> int:
        return int(max(self.clock(), 0.0) * 1000) & 0xFFFFFFFF

    def _latlon(self, north: float, east: float) -> tuple[int, int] | None:
        if self.frame is None:
            return None
        lat, lon, _ = self.frame.to_geodetic(north, east)
        return int(round(lat * 1e7)), int(round(lon * 1e7))

    def _build(self, msgid: int) -> Any:
        """The current value of telemetry message `msgid` (None when lotsen has nothing for it yet)."""
        L = self.latest
        status, state, fix = L.get(Topic.SUPERVISOR), L.get(Topic.STATE), L.get(Topic.GNSS)
        bat, prog, ctrl = L.get(Topic.BATTERY), L.get(Topic.PROGRESS), L.get(Topic.CONTROL_STATUS)
        sup = status if isinstance(status, SupervisorStatus) else None
        st = state if isinstance(state, VesselState) and all(map(math.isfinite, state.as_array_tuple())) else None
        if msgid == mavlink.MAVLINK_MSG_ID_HEARTBEAT:
            base, custom, sysstat = M.heartbeat_fields(sup.mode if sup else None, bool(sup and sup.armed),
                                                       sup.active_failsafes if sup else ())
            return mavlink.MAVLink_heartbeat_message(M.MAV_TYPE_SURFACE_BOAT, M.MAV_AUTOPILOT_ARDUPILOTMEGA, base,
                                                     custom, sysstat, 3)
        if msgid == mavlink.MAVLINK_MSG_ID_SYS_STATUS:
            present = (mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
                       | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG | mavlink.MAV_SYS_STATUS_SENSOR_GPS
                       | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | mavlink.MAV_SYS_STATUS_AHRS
                       | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY | mavlink.MAV_SYS_STATUS_PREARM_CHECK)
            health = present
            if sup is None or "arm" not in sup.available_actions and not sup.armed:
                health &= ~mavlink.MAV_SYS_STATUS_PREARM_CHECK  # QGroundControl's "not ready to arm"
            if not isinstance(fix, GnssFix) or not fix.usable:
                health &= ~mavlink.MAV_SYS_STATUS_SENSOR_GPS
            if sup is None or not sup.escs_armed:
                health &= ~mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
            b = bat if isinstance(bat, BatteryStatus) else None
            return mavlink.MAVLink_sys_status_message(present, present, health, 0, _mv(b), _ca(b), _pct(b),
                                                      0, 0, 0, 0, 0, 0)
        if msgid == mavlink.MAVLINK_MSG_ID_BATTERY_STATUS:
            if not isinstance(bat, BatteryStatus):
                return None
            return mavlink.MAVLink_battery_status_message(0, mavlink.MAV_BATTERY_FUNCTION_ALL,
                                                          mavlink.MAV_BATTERY_TYPE_LIPO, 32767,
                                                          [_mv(bat)] + [65535] * 9, _ca(bat), -1, -1, _pct(bat))
        if msgid == mavlink.MAVLINK_MSG_ID_GPS_RAW_INT:
            if not isinstance(fix, GnssFix):
                return None
            ft = _gps_fix_type(fix.fix_type)
            finite = math.isfinite(fix.lat_deg) and math.isfinite(fix.lon_deg)
            speed = math.hypot(fix.vel_n_mps, fix.vel_e_mps)
            cog = math.degrees(math.atan2(fix.vel_e_mps, fix.vel_n_mps)) % 360 if math.isfinite(speed) else math.nan
            return mavlink.MAVLink_gps_raw_int_message(
                int(fix.stamp_s * 1e6) if fix.stamp_s > 0 else 0, ft, int(round(fix.lat_deg * 1e7)) if finite else 0,
                int(round(fix.lon_deg * 1e7)) if finite else 0,
                int(fix.height_m * 1000) if math.isfinite(fix.height_m) else 0, 65535, 65535,
                int(speed * 100) if math.isfinite(speed) else 65535, int(cog * 100) if math.isfinite(cog) else 65535,
                min(int(fix.num_sv), 255), 0, _mm(fix.h_acc_m), _mm(fix.v_acc_m), 0, 0, 0)
        if msgid == mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            ll = self._latlon(st.north_m, st.east_m) if st is not None else None
            if ll is None or st is None:
                return None
            vn, ve = M.ground_velocity(st.u_mps, st.v_mps, st.heading_rad)
            return mavlink.MAVLink_global_position_int_message(self._boot_ms(), ll[0], ll[1], 0, 0, int(vn * 100),
                                                               int(ve * 100), 0,
                                                               int(math.degrees(st.heading_rad) % 360 * 100))
        if msgid == mavlink.MAVLINK_MSG_ID_ATTITUDE:
            if st is None:
                return None
            yaw = math.atan2(math.sin(st.heading_rad), math.cos(st.heading_rad))
            return mavlink.MAVLink_attitude_message(self._boot_ms(), 0.0, 0.0, yaw, 0.0, 0.0, st.r_radps)
        if msgid == mavlink.MAVLINK_MSG_ID_VFR_HUD:
            if st is None:
                return None
            cmd = L.get(Topic.SHIP_COMMAND)
            throttle = 0
            if isinstance(cmd, ThrustCommand):
                throttle = int(min(100.0, 100.0 * max(abs(cmd.n1_rps), abs(cmd.n2_rps)) / 120.0))
            return mavlink.MAVLink_vfr_hud_message(st.speed_mps, st.speed_mps, int(math.degrees(st.heading_rad) % 360),
                                                   throttle, 0.0, 0.0)
        if msgid == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            plan = self._route_plan()
            active = L.get(Topic.ACTIVE_ROUTE)
            if plan is None or plan.home is None or not isinstance(active, RouteMessage):
                return None
            h = active.route["harbour"]
            return mavlink.MAVLink_home_position_message(int(round(plan.home.lat_deg * 1e7)),
                                                         int(round(plan.home.lon_deg * 1e7)), 0, h["north"], h["east"],
                                                         0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0)
        if msgid == mavlink.MAVLINK_MSG_ID_MISSION_CURRENT:
            seqs = self._waypoints()
            if not seqs:
                return None
            current = seqs[0]
            if isinstance(prog, MissionProgress) and 0 <= prog.next_node < len(seqs) and sup and sup.mode == "AUTO":
                current = seqs[prog.next_node]
            state_ = mavlink.MISSION_STATE_ACTIVE if sup and sup.mode == "AUTO" else mavlink.MISSION_STATE_NOT_STARTED
            return mavlink.MAVLink_mission_current_message(current, seqs[-1] + 1, state_, 0)
        if msgid == mavlink.MAVLINK_MSG_ID_NAV_CONTROLLER_OUTPUT:
            if not isinstance(ctrl, ControllerStatus) or sup is None or sup.mode not in ("AUTO", "RETURN", "HOLD"):
                return None
            dist = prog.distance_to_next_node_m if isinstance(prog, MissionProgress) else math.nan
            hdg = math.degrees(st.heading_rad) if st is not None else 0.0
            herr = math.degrees(ctrl.heading_error_rad) if math.isfinite(ctrl.heading_error_rad) else 0.0
            return mavlink.MAVLink_nav_controller_output_message(
                0.0, 0.0, int(round(hdg - herr)) % 360, int(round(hdg - herr)) % 360,
                int(dist) if math.isfinite(dist) else 0, 0.0,
                _f(ctrl.speed_ref_mps - ctrl.speed_mps), _f(ctrl.cross_track_error_m))
        return None

    def _autopilot_version(self) -> Any:
        return mavlink.MAVLink_autopilot_version_message(CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, [0] * 8, [0] * 8,
                                                         [0] * 8, 0, 0, 0, [0] * 18)

    def stats(self) -> dict:
        return {"links": len(self.links), "in": self.messages_in, "out": sum(lk.sent for lk in self.links),
                "errors": sum(lk.errors for lk in self.links),
                "ground_stations": sum(len(lk.gcs) for lk in self.links)}


def _refusal_text(action: str, why: str) -> str:
    return f"PreArm: {why}" if action == "arm" else f"{action} refused: {why}"


def _name_items(text: str, seqs: list[int]) -> str:
    """The planner's "node K" (1-based, as on the page) as the mission item it came from."""
    import re

    def repl(m: re.Match) -> str:
        k = int(m.group(1)) - 1
        return f"mission item {seqs[k]} (node {k + 1})" if 0 <= k < len(seqs) else m.group(0)

    return re.sub(r"\bnode (\d+)\b", repl, text)


def _param_id(raw: Any) -> str:
    text = raw.decode("ascii", "replace") if isinstance(raw, (bytes, bytearray)) else str(raw)
    return text.split("\x00", 1)[0].strip()


def _f(x: float) -> float:
    return float(x) if math.isfinite(x) else 0.0


def _mm(x: float) -> int:
    return int(min(x * 1000, 4e9)) if math.isfinite(x) and x >= 0 else 0


def _mv(b: BatteryStatus | None) -> int:
    return int(b.voltage_v * 1000) if b is not None and math.isfinite(b.voltage_v) else 65535


def _ca(b: BatteryStatus | None) -> int:
    return int(b.current_a * 100) if b is not None and math.isfinite(b.current_a) else -1


def _pct(b: BatteryStatus | None) -> int:
    return int(round(b.remaining_frac * 100)) if b is not None and math.isfinite(b.remaining_frac) else -1


def _gps_fix_type(fix_type: int) -> int:
    """lotsen's GnssFixType (u-blox's, RTK folded in) as MAVLink's GPS_FIX_TYPE."""
    return {GnssFixType.NO_FIX: 1, GnssFixType.DEAD_RECKONING: 1, GnssFixType.FIX_2D: 2, GnssFixType.FIX_3D: 3,
            GnssFixType.RTK_FLOAT: 5, GnssFixType.RTK_FIXED: 6}.get(GnssFixType(fix_type), 0)
