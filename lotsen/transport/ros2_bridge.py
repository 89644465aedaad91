"""ROS 2 mode of the Zenoh transport: the boat as a ROS 2 node on Zenoh, wire-compatible with
`rmw_zenoh_cpp` (see `rmw_zenoh` for the format and why this standard).

    bridge = Ros2Bridge(Ros2BridgeConfig(namespace="/boat", connect=("tcp/127.0.0.1:7447",),
                                         publish=("imu/data_raw", "gps_chatter", "state/estimate"),
                                         subscribe=("operator/command",), pilot_token=token))
    executor.add_node(bridge)

* Outbound: each lotsen topic in `publish` becomes the ROS 2 topic `<namespace>/<topic>` with the
  type of `ros2_map` (sensor_msgs/Imu for imu/data_raw, ...), published with rmw_zenoh's key
  expression, CDR payload and attachment, and announced by liveliness tokens (node
  `<namespace>/<node_name>`, one publisher token per topic), so `ros2 topic list / echo` on a
  ROS 2 machine using rmw_zenoh sees the boat. As in `ZenohBridge`, the bus callback only appends
  to a bounded queue (drop-oldest) and a sender thread encodes and puts (congestion control DROP):
  a slow or absent ROS 2 peer never blocks the control loop.
* Inbound: each lotsen topic in `subscribe` is subscribed as `<namespace>/<topic>` (any type hash
  of the expected type, so Humble's "TypeHashNotSupported" peers work too); samples are decoded in
  Zenoh's thread into a bounded queue that the node drains on the executor thread.
* `operator/command` from ROS 2 (lotsen_msgs/OperatorCommand) reaches the bus only through
  `CommandGate`: the message must carry the boat's pilot token (constant-time comparison, the
  web page's token), the action must be one of OPERATOR_ACTIONS, each sender (publisher GID) is
  rate-limited, and `max_auth_failures` wrong tokens within `failure_window_s` lock every ROS 2
  command out for `lockout_s`. Accepted commands are published as
  `OperatorCommand(source="ros2:<client>")`; refusals are counted and reported on `log`.
* Discovery: as `ZenohBridge`, multicast and gossip scouting OFF unless enabled; only the given
  endpoints. A ROS 2 system runs `rmw_zenohd` (a Zenoh router, tcp/7447): connect the bridge to
  it, or let ROS 2 peers connect to the bridge's listen endpoint.
"""

from __future__ import annotations

import hmac
import itertools
import re
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Literal

from lotsen import messages as M
from lotsen.errors import ConfigError
from lotsen.runtime.bus import BoundedQueue
from lotsen.runtime.executor import Node, NodeContext
from lotsen.transport import rmw_zenoh as W
from lotsen.transport import ros2_map, ros2_types
from lotsen.transport.zenoh_bridge import open_session
from lotsen.settings import value_range as _r

SOURCE_PREFIX = "ros2:"
_CLIENT_RE = re.compile(r"[^A-Za-z0-9_-]")
SENSOR_TOPICS = (M.Topic.IMU_RAW, M.Topic.IMU_MAG, M.Topic.GNSS, M.Topic.RPM)
# topics that move the boat: never taken from ROS 2 onto the topics the actuators and supervisor use
DRIVING_TOPICS = (M.Topic.SHIP_COMMAND, M.Topic.VELOCITY_COMMAND, M.Topic.ANGLE_COMMAND, M.Topic.MANUAL, M.Topic.RC,
                  M.Topic.EXPERIMENT_COMMAND)


@dataclass(frozen=True)
class Ros2BridgeConfig:
    namespace: str = "/boat"  # ROS namespace of the boat's topics and node
    node_name: str = "lotsen"
    domain_id: int = field(default=0, metadata=_r(0, 232))  # ROS_DOMAIN_ID (ROS 2 allows 0-232)
    mode: Literal["peer", "client", "router"] = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()  # e.g. ("tcp/127.0.0.1:7447",): the rmw_zenohd router
    publish: tuple[str, ...] = ()  # lotsen topics sent to ROS 2 as <namespace>/<topic>
    subscribe: tuple[str, ...] = ()  # lotsen topics taken from ROS 2 (operator/command: authorised)
    local_prefix: str = ""  # inbound topics appear locally as local_prefix + topic (not operator/command)
    pilot_token: str | None = None  # operator/command from ROS 2 needs it; None or "": every command refused
    best_effort_topics: tuple[str, ...] = SENSOR_TOPICS  # published with SensorDataQoS (best effort, depth 5)
    # header.stamp = stamp_s + offset; None: the clock's Unix epoch at start
    stamp_offset_s: float | None = field(default=None, metadata=_r(-1e10, 1e10))
    command_rate_hz: float = field(default=2.0, metadata=_r(0.01, 100.0))  # accepted commands per sender (token bucket) ...
    command_burst: int = field(default=5, metadata=_r(1, 1000))  # ... with this burst
    # wrong tokens within failure_window_s before the lockout
    max_auth_failures: int = field(default=5, metadata=_r(1, 1000))
    failure_window_s: float = field(default=60.0, metadata=_r(1.0, 86400.0))
    lockout_s: float = field(default=30.0, metadata=_r(0.0, 86400.0))
    multicast_scouting: bool = False
    gossip_scouting: bool = False
    queue_maxlen: int = field(default=2000, metadata=_r(1, 10_000_000))
    drain_period_s: float = field(default=0.005, metadata=_r(0.0001, 1.0))


@dataclass
class Ros2BridgeStats:
    sent: int = 0
    received: int = 0
    published_locally: int = 0
    decode_errors: int = 0
    encode_errors: int = 0
    commands_accepted: int = 0
    commands_refused: int = 0
    dropped_out: int = 0
    dropped_in: int = 0
    last_error: str = ""
    last_refusal: str = ""
    per_topic_in: dict[str, int] = field(default_factory=dict)


# ---------------------------------------------------------------------------- authorisation
class CommandGate:
    """Who may command the boat over ROS 2 (pure: time passed in, no I/O).

    Order of checks: lockout -> known action -> per-sender rate (token bucket) -> pilot token.
    A wrong token counts towards the lockout; the lockout refuses every sender (a guesser can
    forge any number of GIDs, so a per-sender lockout would not stop it)."""

    def __init__(self, token: str | None, rate_hz: float = 2.0, burst: int = 5, max_failures: int = 5,
                 failure_window_s: float = 60.0, lockout_s: float = 30.0) -> None:
        self._token = (token or "").encode("utf-8")
        self.rate_hz, self.burst = float(rate_hz), int(burst)
        self.max_failures, self.failure_window_s, self.lockout_s = int(max_failures), failure_window_s, lockout_s
        self._buckets: dict[str, tuple[float, float]] = {}  # sender -> (tokens, last time)
        self._failures: deque[float] = deque()
        self.locked_until = float("-inf")

    def check(self, now: float, sender: str, token: str, action: str) -> str | None:
        """None when accepted, else why not."""
        if not self._token:
            return "no pilot token is configured on the boat: ROS 2 commands are disabled"
        if now < self.locked_until:
            return f"locked out after {self.max_failures} wrong tokens (for {self.locked_until - now:.0f} s more)"
        if action not in M.OPERATOR_ACTIONS:
            return f"unknown action {action[:40]!r}"
        if len(self._buckets) > 1000:  # forged GIDs must not grow memory without bound
            self._buckets.clear()
        tokens, last = self._buckets.get(sender, (float(self.burst), now))
        tokens = min(float(self.burst), tokens + (now - last) * self.rate_hz)
        if tokens < 1.0:
            self._buckets[sender] = (tokens, now)
            return f"rate limited ({self.rate_hz:g} commands/s)"
        self._buckets[sender] = (tokens - 1.0, now)
        if not hmac.compare_digest(token.encode("utf-8"), self._token):
            while self._failures and self._failures[0] < now - self.failure_window_s:
                self._failures.popleft()
            self._failures.append(now)
            if len(self._failures) >= self.max_failures:
                self.locked_until = now + self.lockout_s
                self._failures.clear()
            return "wrong pilot token"
        return None


def source_name(client: str, gid: bytes | None) -> str:
    """"ros2:<client>" (sanitised, <= 32 chars) or "ros2:<first 8 hex of the GID>"."""
    name = _CLIENT_RE.sub("", client or "")[:32]
    if not name:
        name = gid[:4].hex() if gid else "unknown"
    return SOURCE_PREFIX + name


@dataclass(frozen=True)
class _PendingCommand:
    ros: Any = field(repr=False)  # lotsen_msgs/msg/OperatorCommand (carries the token: never printed)
    sender: str  # GID hex (rate-limit key)
    gid: bytes | None


# ---------------------------------------------------------------------------- the node
class Ros2Bridge(Node):
    """Add to an executor (`executor.add_node(bridge)`); `close()` when done."""

    name = "ros2_bridge"

    def __init__(self, config: Ros2BridgeConfig) -> None:
        import zenoh

        self._z = zenoh
        self.config = config
        ns = "/" + config.namespace.strip("/") if config.namespace.strip("/") else "/"
        self.namespace = ns
        overlap = set(config.publish) & set(config.subscribe)
        if overlap:
            raise ConfigError(f"ros2 bridge: topics both published and subscribed: {sorted(overlap)}")
        for t in config.subscribe:
            if t in DRIVING_TOPICS and not config.local_prefix:
                raise ConfigError(f"ros2 bridge: subscribing to {t!r} without a local_prefix would let any ROS 2 "
                                  "node drive the boat; set local_prefix (e.g. 'ros2/') and let the supervisor "
                                  "decide what to do with ros2/" + t)
            if t not in ros2_map.TOPIC_CLASSES:
                raise ConfigError(f"ros2 bridge: cannot subscribe to {t!r}: its message type is not known "
                                  f"(known: {', '.join(sorted(ros2_map.TOPIC_CLASSES))})")
        ros2_types.lotsen_msg_files()  # fail here, not in a thread, if the .msg files are missing
        self.stats = Ros2BridgeStats()
        self.gate = CommandGate(config.pilot_token, config.command_rate_hz, config.command_burst,
                                config.max_auth_failures, config.failure_window_s, config.lockout_s)
        self._offset = config.stamp_offset_s if config.stamp_offset_s is not None else 0.0
        self._out = BoundedQueue(config.queue_maxlen)
        self._in = BoundedQueue(config.queue_maxlen)
        self._publish = frozenset(config.publish)
        self._injecting: tuple[str, Any] | None = None
        self._publishers: dict[tuple[str, str], tuple[Any, bytes, itertools.count]] = {}
        self._tokens: list[Any] = []
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._unsubscribe: Any = None
        self._last_refusal_log = float("-inf")
        self.session = open_session(config)
        self.session_id = str(self.session.info.zid())
        self._declare_token(W.node_token(config.domain_id, self.session_id, 0, ns, config.node_name))
        for topic in config.publish:  # announce known topics at once (ros2 topic list), others on first use
            cls = ros2_map.TOPIC_CLASSES.get(topic)
            if cls is not None:
                self._publisher(topic, ros2_map.ros_type_for(cls))
        self._subs = [self._subscribe(t) for t in config.subscribe]
        self._sender = threading.Thread(target=self._send_loop, name="ros2-bridge-send", daemon=True)
        self._sender.start()

    # ---------------------------------------------------------------- names
    def ros_topic(self, topic: str) -> str:
        return W.fully_qualified(self.namespace, topic)

    def _qos(self, topic: str) -> W.Qos:
        if topic in M.LATCHED_TOPICS:
            return W.LATCHED_QOS
        return W.SENSOR_QOS if topic in self.config.best_effort_topics else W.DEFAULT_QOS

    def _declare_token(self, key: str) -> None:
        self._tokens.append(self.session.liveliness().declare_token(key))

    # ---------------------------------------------------------------- node side (executor thread)
    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        if self.config.stamp_offset_s is None:
            self._offset = float(getattr(ctx.clock, "epoch_at_start", 0.0) or 0.0)
        self._unsubscribe = ctx.bus.subscribe_all(self._on_local)
        ctx.add_timer(self.config.drain_period_s, self.drain)

    def _on_local(self, topic: str, msg: Any) -> None:
        inj = self._injecting
        if inj is not None and inj[1] is msg and inj[0] == topic:
            return  # what this bridge brings in is never sent back out
        if topic in self._publish:
            self._out.put(topic, msg)

    def drain(self) -> int:
        """Publish received messages on the local bus (executor thread); authorise commands."""
        items = self._in.get_all()
        self.stats.dropped_in = self._in.dropped
        n = 0
        try:
            for topic, msg in items:
                if isinstance(msg, _PendingCommand):
                    msg = self._authorise(msg)
                    if msg is None:
                        continue
                self._injecting = (topic, msg)
                self.ctx.publish(topic, msg)
                self.stats.published_locally += 1
                n += 1
        finally:
            self._injecting = None
        return n

    def _authorise(self, cmd: _PendingCommand) -> M.OperatorCommand | None:
        now = self.ctx.now()
        ros = cmd.ros
        source = source_name(ros.client, cmd.gid)
        why = self.gate.check(now, cmd.sender, ros.pilot_token, ros.action)
        if why is None:
            self.stats.commands_accepted += 1
            return M.OperatorCommand(stamp_s=now, action=ros.action, source=source)
        self.stats.commands_refused += 1
        self.stats.last_refusal = f"{source} {ros.action[:40]!r}: {why}"
        if now - self._last_refusal_log >= 1.0:  # at most one log line a second (a flood stays a count)
            self._last_refusal_log = now
            self.ctx.log("warning", f"ROS 2 command refused: {self.stats.last_refusal}",
                         refused_total=self.stats.commands_refused)
        return None

    def stop(self) -> None:
        self.close()

    # ---------------------------------------------------------------- zenoh side (other threads)
    def _publisher(self, topic: str, ros_type: str) -> tuple[Any, bytes, itertools.count]:
        with self._lock:
            pub = self._publishers.get((topic, ros_type))
            if pub is None:
                fq = self.ros_topic(topic)
                qos = self._qos(topic)
                z = self._z
                token = W.entity_token(self.config.domain_id, self.session_id, 0, next(self._ids), "MP",
                                       self.namespace, self.config.node_name, fq, ros_type, qos)
                key = W.topic_key(self.config.domain_id, fq, ros_type)
                if qos.durability == 1:  # transient local: as rmw_zenoh, an advanced publisher with a cache
                    from zenoh import ext

                    zpub = ext.declare_advanced_publisher(
                        self.session, key, congestion_control=z.CongestionControl.DROP, publisher_detection=True,
                        cache=ext.CacheConfig(max_samples=qos.depth, replies_config=ext.RepliesConfig(
                            congestion_control=z.CongestionControl.BLOCK, priority=z.Priority.DATA_HIGH)))
                else:
                    zpub = self.session.declare_publisher(
                        key, congestion_control=z.CongestionControl.DROP,
                        reliability=z.Reliability.BEST_EFFORT if qos.reliability == 2 else z.Reliability.RELIABLE)
                self._declare_token(token)
                pub = self._publishers[(topic, ros_type)] = (zpub, W.gid_for(token), itertools.count(1))
            return pub

    def _subscribe(self, topic: str) -> Any:
        cls = ros2_map.TOPIC_CLASSES[topic]
        ros_type = ros2_map.ros_type_for(cls)
        fq = self.ros_topic(topic)
        self._declare_token(W.entity_token(self.config.domain_id, self.session_id, 0, next(self._ids), "MS",
                                           self.namespace, self.config.node_name, fq, ros_type, self._qos(topic)))
        key = W.topic_key(self.config.domain_id, fq, ros_type, hash_="*")
        local = topic if topic == M.Topic.OPERATOR else self.config.local_prefix + topic
        is_command = topic == M.Topic.OPERATOR

        def on_sample(sample: Any) -> None:
            self.stats.received += 1
            try:
                data = sample.payload.to_bytes()
                att = W.decode_attachment(sample.attachment.to_bytes() if sample.attachment is not None else None)
                if is_command:
                    ros = ros2_types.deserialize(data, ros_type)
                    gid = att.gid if att else None
                    msg: Any = _PendingCommand(ros, gid.hex() if gid else "unknown", gid)
                else:
                    msg = ros2_map.decode(ros_type, data, self._offset)
            except Exception as exc:  # noqa: BLE001 - bad data from the network is counted, not raised
                self.stats.decode_errors += 1
                self.stats.last_error = f"{sample.key_expr}: {exc}"
                return
            self.stats.per_topic_in[local] = self.stats.per_topic_in.get(local, 0) + 1
            self._in.put(local, msg)

        return self.session.declare_subscriber(key, on_sample, allowed_origin=self._z.Locality.REMOTE)

    def _send_loop(self) -> None:
        while not self._stop.is_set():
            item = self._out.get(timeout=0.1)
            if item is None:
                continue
            for topic, msg in [item, *self._out.get_all()]:
                try:
                    ros_type, payload = ros2_map.encode(msg, self._offset)
                    zpub, gid, seq = self._publisher(topic, ros_type)
                    zpub.put(payload, attachment=W.encode_attachment(next(seq), time.time_ns(), gid))
                except Exception as exc:  # noqa: BLE001 - e.g. a non-lotsen object on a forwarded topic
                    self.stats.encode_errors += 1
                    self.stats.last_error = f"{topic}: {exc!r}"
                    continue
                self.stats.sent += 1
            self.stats.dropped_out = self._out.dropped

    def graph(self, timeout_s: float = 1.0) -> list[W.TokenInfo]:
        """The ROS 2 graph as seen now (liveliness tokens of every rmw_zenoh entity, ours included)."""
        out = []
        for reply in self.session.liveliness().get(f"{W.ADMIN_SPACE}/{self.config.domain_id}/**", timeout=timeout_s):
            try:
                out.append(W.parse_token(str(reply.ok.key_expr)))
            except (ValueError, AttributeError):
                continue
        return out

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        if self._unsubscribe is not None:
            self._unsubscribe()
        self._sender.join(2.0)
        try:
            self.session.close()  # undeclares publishers, subscribers and liveliness tokens
        except Exception:  # noqa: BLE001 - closing twice or after the peer left
            pass
