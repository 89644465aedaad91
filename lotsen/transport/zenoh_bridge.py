"""Zenoh bridge: local bus topics <-> Zenoh key expressions `lotsen/<vessel>/<topic>`.

* Outbound: topics in `publish` are taken off the bus by a callback that only appends to a bounded
  queue (drop-oldest); a sender thread encodes them (`lotsen.transport.codec` envelope: ROS 2 CDR
  where a standard type fits, JSON otherwise) and puts them with congestion control DROP, so a
  slow or absent peer never blocks the control loop.
* Inbound: key expressions `lotsen/<pattern>` for each pattern in `subscribe` (e.g. `boat/**`,
  `*/operator/command`). Samples are decoded in Zenoh's thread into a bounded queue; the bridge
  node drains it on the executor thread and publishes on the local bus (topic = `local_prefix` +
  the topic part of the key), so node code is never entered from another thread.
* No echo loops: the subscriber ignores samples from this session (`allowed_origin=REMOTE`), from
  our own vessel name, or carrying our origin id; and a message the bridge injected is never
  forwarded again (bus delivery is synchronous, so while the bridge publishes (topic, message) it
  recognises that very object coming back; what nodes publish in reaction still goes out).
* Latched topics (`latched`, by default the planned path, the route read-back, the planned
  route and the model in use): state a late joiner needs. They are published with a cache of their last sample
  (Zenoh's advanced publisher: what rmw_zenoh does for ROS 2's transient-local durability), and
  every subscriber asks the publishers it detects, also those that appear later, for that sample.
  A recorder, a page or a shore station that starts after the route was set still gets it.
* Discovery: multicast and gossip scouting are OFF unless enabled explicitly; the session listens
  and connects only on the endpoints given (the library default would listen on every interface
  and scout by multicast).
"""

from __future__ import annotations

import json
import re
import threading
import uuid
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Literal

from lotsen.errors import ConfigError
from lotsen.messages import LATCHED_TOPICS
from lotsen.runtime.bus import BoundedQueue
from lotsen.runtime.executor import Node, NodeContext
from lotsen.settings import value_range as _r
from lotsen.transport import codec


@dataclass(frozen=True)
class BridgeConfig:
    vessel: str = "boat"  # our name in the key expressions lotsen/<vessel>/<topic>
    mode: Literal["peer", "client", "router"] = "peer"
    listen: tuple[str, ...] = ()  # e.g. ("tcp/127.0.0.1:7447",) or ("tcp/192.168.4.1:7447",) on the boat's Wi-Fi
    connect: tuple[str, ...] = ()  # e.g. ("tcp/192.168.4.1:7447",) on the shore laptop
    publish: tuple[str, ...] = ()  # local topics sent out; ("*",) = every topic
    subscribe: tuple[str, ...] = ()  # key patterns under lotsen/, e.g. ("boat/**",) or ("*/operator/command",)
    local_prefix: str = ""  # remote topics appear locally as local_prefix + topic (e.g. "boat/")
    encoding: Literal["auto", "json"] = "auto"  # auto: ROS 2 CDR where a standard type fits
    key_prefix: str = "lotsen"
    multicast_scouting: bool = False  # never scout by multicast unless explicitly enabled
    gossip_scouting: bool = False
    queue_maxlen: int = field(default=2000, metadata=_r(1, 10_000_000))
    # received messages reach the bus at once (the receiving thread wakes the executor); this
    # timer is only a backstop. A 5 ms poll woke every process of a run 200 times a second.
    drain_period_s: float = field(default=0.1, metadata=_r(0.0001, 1.0))
    # the sender takes what arrives within this long after a first message in one go: one
    # wake-up per burst (a sensor tick publishes several topics), not one per message
    send_batch_s: float = field(default=0.01, metadata=_r(0.0, 1.0))
    # topics that end the gathering at once: a batch goes out with the newest estimate, not up to
    # send_batch_s after it. Batches on their own 50-ms cycle (plus the wait for its first message)
    # drifted against the 20 Hz estimate: two estimates in one batch, none in the next, and the
    # page showed one pose in five less (16.7 Hz, not 20)
    flush_on: tuple[str, ...] = ()
    # topics sent at Zenoh's DATA_LOW priority: large messages (a survey's planned route, 5 MB) queue
    # behind the stream on every link they cross. At the default priority the route filled the
    # router's queue to the recorder for ~0.1 s and Zenoh dropped the core's messages behind it
    # (congestion control DROP): a ship_command missing from the log (1 of 3 runs of
    # test_live_route_arrival; 5 of 5 once the core's batches went out with the estimate)
    bulk: tuple[str, ...] = ()
    latched: tuple[str, ...] = LATCHED_TOPICS  # kept for late joiners (transient-local)
    # a client that starts before its router (the processes of a run start side by side): keep
    # trying to connect (opening the session waits for the router) instead of failing at once
    wait_for_router: bool = False
    # how received samples reach the bus: "callback" (Zenoh's thread decodes each one and wakes
    # the executor: the lowest latency, for the core's few operator commands) or "poll" (samples
    # wait in a drop-oldest ring of queue_maxlen and the executor takes them every
    # drain_period_s: no thread switch per sample, for a process that receives the core's
    # whole stream, e.g. the recorder)
    receive: Literal["callback", "poll"] = "callback"
    # with receive="poll": subscribe patterns whose samples ask for a drain as they arrive (the
    # web process: the page's pose, one frame per estimate). A drain on its timer alone, on the
    # same 10-ms grid as the publisher's timer, takes an estimate that arrives just after it with
    # the next one: a pose lost for the page
    wake_on: tuple[str, ...] = ()
    # Zenoh's shared-memory transport: off, lotsen's payloads are small byte strings and never
    # use it, while its watchdog threads and the 20 Hz timer it adds to every connected session
    # woke each process of a run ~70 times a second for nothing
    shared_memory: bool = False

    def __post_init__(self) -> None:
        # names become Zenoh key expressions: refused here with the setting, not as a ZError
        # from the sender's thread after the bridge has started
        for name in ("vessel", "key_prefix"):
            value = getattr(self, name)
            if not _NAME.fullmatch(value or ""):
                raise ConfigError(f"zenoh bridge: {name} {value[:40]!r}: letters, digits, '_', '-' and '.' only")
        if self.local_prefix and not _PREFIX.fullmatch(self.local_prefix):
            raise ConfigError(f"zenoh bridge: local_prefix {self.local_prefix[:40]!r}: letters, digits, '_', '-', "
                              "'.' and '/' only")
        for pattern in self.subscribe:
            check_key_expression(f"{self.key_prefix}/{pattern.strip('/')}", f"subscribe pattern {pattern[:40]!r}")
        for pattern in self.wake_on:
            if pattern not in self.subscribe:
                raise ConfigError(f"zenoh bridge: wake_on {pattern[:40]!r} is not one of the subscribe patterns")


_NAME = re.compile(r"[A-Za-z0-9_.\-]{1,64}")
_PREFIX = re.compile(r"[A-Za-z0-9_.\-/]{1,128}")


def check_key_expression(key: str, what: str) -> None:
    """ConfigError unless `key` is a Zenoh key expression (wildcards `*` and `**` allowed)."""
    import zenoh

    try:
        zenoh.KeyExpr(key)
    except (zenoh.ZError, ValueError, TypeError) as exc:
        raise ConfigError(f"zenoh bridge: {what} is not a key expression: {str(exc).split(' at /')[0]}") from None


def zenoh_config(cfg: BridgeConfig) -> Any:
    """A zenoh.Config overriding every default that would reach beyond the given endpoints."""
    import zenoh

    if cfg.mode == "client" and not cfg.connect:
        raise ConfigError("zenoh bridge: mode client needs at least one connect endpoint")
    for ep in (*cfg.listen, *cfg.connect):
        if "/" not in ep:
            raise ConfigError(f"zenoh bridge: endpoint {ep!r} must look like tcp/127.0.0.1:7447")
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(cfg.mode))
    c.insert_json5("scouting/multicast/enabled", json.dumps(bool(cfg.multicast_scouting)))
    c.insert_json5("scouting/gossip/enabled", json.dumps(bool(cfg.gossip_scouting)))
    c.insert_json5("listen/endpoints", json.dumps(list(cfg.listen)))
    c.insert_json5("connect/endpoints", json.dumps(list(cfg.connect)))
    if getattr(cfg, "wait_for_router", False):  # BridgeConfig; the ROS 2 bridge shares this function
        c.insert_json5("connect/timeout_ms", "-1")
        c.insert_json5("connect/exit_on_failure", "false")
    if not getattr(cfg, "shared_memory", True):  # BridgeConfig; the ROS 2 bridge keeps Zenoh's default
        c.insert_json5("transport/shared_memory/enabled", "false")
    # the latched topics' cache orders its samples by timestamp
    c.insert_json5("timestamping/enabled", json.dumps({"router": True, "peer": True, "client": True}))
    return c


def open_session(config: Any) -> Any:
    """zenoh.open with its refusals (an endpoint it cannot parse or bind, a router it cannot reach)
    as a ConfigError naming the endpoints, not a zenoh traceback."""
    import zenoh

    conf = zenoh_config(config)
    try:
        return zenoh.open(conf)
    except zenoh.ZError as exc:
        where = ", ".join((*config.listen, *config.connect)) or "no endpoint"
        raise ConfigError(f"zenoh: cannot open a session ({where}): {str(exc).split(' at /')[0]}") from None


@dataclass
class BridgeStats:
    sent: int = 0
    received: int = 0
    published_locally: int = 0
    decode_errors: int = 0
    encode_errors: int = 0
    send_errors: int = 0
    echoes_ignored: int = 0
    dropped_out: int = 0
    dropped_in: int = 0
    last_error: str = ""
    per_topic_in: dict[str, int] = field(default_factory=dict)


class ZenohBridge(Node):
    """Add to an executor (`executor.add_node(bridge)`) or use `part.add_bridge(stack, cfg)`."""

    name = "zenoh_bridge"

    def __init__(self, config: BridgeConfig) -> None:
        import zenoh

        self._z = zenoh
        self.config = config
        self.origin = f"{config.vessel}:{uuid.uuid4().hex[:8]}"
        self.stats = BridgeStats()
        self._out = BoundedQueue(config.queue_maxlen)
        self._in = BoundedQueue(config.queue_maxlen)
        self._publish_all = "*" in config.publish
        self._publish = frozenset(config.publish)
        self._injecting: tuple[str, Any] | None = None
        self._publishers: dict[str, Any] = {}
        self._stop = threading.Event()
        self._unsubscribe: Any = None
        self._wake: Any = None  # the executor's call_soon_threadsafe, once started
        self._drain_pending = threading.Event()
        self._flush = threading.Event()  # a flush_on topic was queued: the sender stops gathering
        self._flush_topics = frozenset(config.flush_on)
        self._encoded_sink: Callable[[list[tuple[str, codec.Envelope]]], None] | None = None
        self._decoded_topics: frozenset[str] = frozenset()
        self._held_topics: frozenset[str] = frozenset()
        self._wanted: Callable[[], bool] = lambda: True
        self._held: dict[str, tuple[str, codec.Envelope]] = {}  # topic -> (key, newest envelope)
        self.session = open_session(config)
        self._subs: list[Any] = []  # every subscriber (kept open) ...
        self._polled: list[Any] = []  # ... and those whose ring the drain empties (receive="poll")
        # samples of the wake_on patterns: Zenoh's thread appends, the drain takes (drop-oldest)
        self._woken: deque[Any] = deque(maxlen=config.queue_maxlen)
        from zenoh import ext

        for pattern in config.subscribe:
            key = f"{config.key_prefix}/{pattern.strip('/')}"
            polled = config.receive == "poll" and pattern not in config.wake_on
            handler: Any = (zenoh.handlers.RingChannel(config.queue_maxlen) if polled
                            else self._on_sample if config.receive == "callback" else self._on_waking_sample)
            # an advanced subscriber: live samples, plus the cached last sample of every latched
            # publisher it detects (now or when that publisher appears)
            sub = ext.declare_advanced_subscriber(
                self.session, key, handler, allowed_origin=zenoh.Locality.REMOTE,
                history=ext.HistoryConfig(detect_late_publishers=True, max_samples=1),
                recovery=ext.RecoveryConfig(heartbeat=True, periodic_queries=None))
            self._subs.append(sub)
            if polled:
                self._polled.append(sub)
        self._sender = threading.Thread(target=self._send_loop, name="zenoh-bridge-send", daemon=True)
        self._sender.start()

    def forward_encoded(self, sink: Callable[[list[tuple[str, codec.Envelope]]], None],
                        decoded: Iterable[str] = ()) -> None:
        """Received messages go to `sink([(topic, envelope), ...])` as they came, not decoded and
        not on the local bus (a recorder writes the JSON payload as it is); those of the `decoded`
        topics (what a node of this process subscribes to) still reach the local bus, and only
        it. The sink is called where received samples are handled: on the executor thread once
        per drain with what it took (`receive="poll"`), or on Zenoh's thread per sample."""
        self._decoded_topics = frozenset(decoded)
        self._encoded_sink = sink

    def hold_latest(self, topics: Iterable[str], wanted: Callable[[], bool]) -> None:
        """Samples of `topics` are decoded only while `wanted()` (the web process: while a page is
        connected); meanwhile the newest envelope of each is kept as it came, and reaches the bus
        at the first drain once they are wanted again, so a page that connects has the current
        values within one drain. For topics whose newest value is all a reader needs (the page's
        live view); with `receive="poll"` only (the held samples live on the executor thread)."""
        if self.config.receive != "poll":
            raise ValueError("hold_latest needs receive='poll'")
        self._held_topics = frozenset(topics)
        self._wanted = wanted

    # ---------------------------------------------------------------- node side (executor thread)
    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        self._unsubscribe = ctx.bus.subscribe_all(self._on_local)
        for topic in self.config.latched:  # published before this node started: latch it now
            msg = ctx.bus.latest.get(topic)
            if msg is not None:
                self._on_local(topic, msg)
        if self.config.receive == "callback" or self.config.wake_on:
            self._wake = getattr(ctx.executor, "call_soon_threadsafe", None)
        ctx.add_timer(self.config.drain_period_s, self.drain)
        self._request_drain()  # what arrived before the start

    def _on_local(self, topic: str, msg: Any) -> None:
        inj = self._injecting
        if inj is not None and inj[1] is msg and inj[0] == topic:
            return  # the message this bridge is bringing in: never send it back out
        if self._publish_all or topic in self._publish:
            self._out.put(topic, msg)
            if topic in self._flush_topics:
                self._flush.set()

    def _request_drain(self) -> None:
        """From the receiving thread: one drain on the executor thread, unless one is pending."""
        if self._wake is not None and not self._drain_pending.is_set():
            self._drain_pending.set()
            self._wake(self.drain)

    def drain(self) -> int:
        """Publish received messages on the local bus (executor thread)."""
        self._drain_pending.clear()  # before taking: a message arriving now asks for another drain
        if self._held and self._wanted():  # wanted again: the newest held values first
            held, self._held = self._held, {}
            for topic, (key, env) in held.items():
                self._decode_in(topic, key, env)
        if self.config.receive == "poll":
            forwarded: list[tuple[str, codec.Envelope]] = []
            for sub in self._polled:
                while (sample := sub.try_recv()) is not None:
                    self._on_sample(sample, forwarded)
            while self._woken:
                self._on_sample(self._woken.popleft(), forwarded)
            if forwarded and self._encoded_sink is not None:
                self._encoded_sink(forwarded)
        items = self._in.get_all()
        self.stats.dropped_in = self._in.dropped
        if not items:
            return 0
        try:
            for topic, msg in items:
                self._injecting = (topic, msg)
                self.ctx.publish(topic, msg)
                self.stats.published_locally += 1
        finally:
            self._injecting = None
        return len(items)

    def stop(self) -> None:
        self.close()

    # ---------------------------------------------------------------- zenoh side (other threads)
    def _key(self, topic: str) -> str:
        return f"{self.config.key_prefix}/{self.config.vessel}/{topic.strip('/')}"

    def _send_loop(self) -> None:
        cc = self._z.CongestionControl.DROP
        while not self._stop.is_set():
            item = self._out.get(timeout=0.1)
            if item is None:
                continue
            if self.config.send_batch_s > 0 and item[0] not in self._flush_topics:
                self._flush.wait(self.config.send_batch_s)
            # cleared before taking: a flush_on message queued from now on ends the next gathering
            self._flush.clear()
            for topic, msg in [item, *self._out.get_all()]:
                try:
                    data = codec.encode(msg, self.config.encoding, origin=self.origin)
                except Exception as exc:  # noqa: BLE001 - e.g. a non-lotsen object on a forwarded topic
                    self.stats.encode_errors += 1
                    self.stats.last_error = f"{topic}: {exc!r}"
                    continue
                try:
                    pub = self._publishers.get(topic)
                    if pub is None:
                        pub = self._publishers[topic] = self._declare_publisher(topic, cc)
                    pub.put(data)
                except Exception as exc:  # noqa: BLE001 - the session closed under a slow sender, or the link
                    if self._stop.is_set():  # closing: close() waited 2 s for this thread and went on
                        return
                    self.stats.send_errors += 1
                    self.stats.last_error = f"{topic}: {exc!r}"
                    continue
                self.stats.sent += 1
            self.stats.dropped_out = self._out.dropped

    def _declare_publisher(self, topic: str, cc: Any) -> Any:
        if topic in self.config.latched:
            from zenoh import ext

            try:
                # the late joiner's copy is sent blocking and ahead of the stream: one rare sample
                # that must not be dropped behind the 1.5 k msg/s of telemetry on the same link
                replies = ext.RepliesConfig(congestion_control=self._z.CongestionControl.BLOCK,
                                            priority=self._z.Priority.DATA_HIGH)
                # a heartbeat (the last sequence number, 1/s) lets a subscriber that joined while this
                # sample was on its way notice the miss and fetch it from the cache
                return ext.declare_advanced_publisher(
                    self.session, self._key(topic), congestion_control=cc, priority=self._priority(topic),
                    publisher_detection=True,
                    cache=ext.CacheConfig(max_samples=1, replies_config=replies),
                    sample_miss_detection=ext.MissDetectionConfig(heartbeat=1.0, sporadic_heartbeat=None))
            except Exception as exc:  # noqa: BLE001 - still publish it live; say why it is not latched
                self.stats.last_error = f"{topic}: not latched: {exc}"
        return self.session.declare_publisher(self._key(topic), congestion_control=cc, priority=self._priority(topic))

    def _priority(self, topic: str) -> Any:
        return self._z.Priority.DATA_LOW if topic in self.config.bulk else self._z.Priority.DATA

    def _on_waking_sample(self, sample: Any) -> None:
        """Zenoh's thread, a sample of a `wake_on` pattern: kept for the drain, which it asks for at
        once unless its topic is held and nobody reads it now (then the timer's drain keeps it)."""
        self._woken.append(sample)
        split = self._split_key(str(sample.key_expr))
        if split is None or not self._unread(split[1]):
            self._request_drain()

    def _split_key(self, key: str) -> tuple[str, str] | None:
        """(vessel, local topic) of a key lotsen/<vessel>/<topic>; None for a key of another shape."""
        parts = key.split("/", 2)
        return (parts[1], self.config.local_prefix + parts[2]) if len(parts) == 3 else None

    def _unread(self, topic: str) -> bool:
        """A held topic while nobody reads it (`hold_latest`): its newest envelope is kept, not decoded."""
        return topic in self._held_topics and not self._wanted()

    def _on_sample(self, sample: Any, forwarded: list[tuple[str, codec.Envelope]] | None = None) -> None:
        """A received sample: decoded into the queue the executor drains, or its envelope to the
        encoded sink (collected in `forwarded` when given)."""
        self.stats.received += 1
        key = str(sample.key_expr)
        split = self._split_key(key)
        if split is None or split[0] == self.config.vessel:
            self.stats.echoes_ignored += 1
            return
        try:
            env = codec.parse_envelope(sample.payload.to_bytes())
        except Exception as exc:  # noqa: BLE001 - bad data from the network is counted, not raised
            self.stats.decode_errors += 1
            self.stats.last_error = f"{key}: {exc}"
            return
        if env.origin == self.origin:
            self.stats.echoes_ignored += 1
            return
        topic = split[1]
        sink = self._encoded_sink
        if sink is not None and topic not in self._decoded_topics:
            self.stats.per_topic_in[topic] = self.stats.per_topic_in.get(topic, 0) + 1
            if forwarded is not None:
                forwarded.append((topic, env))
            else:
                sink([(topic, env)])
            return
        if self._unread(topic):
            self._held[topic] = (key, env)
            return
        self._decode_in(topic, key, env)

    def _decode_in(self, topic: str, key: str, env: codec.Envelope) -> None:
        try:
            msg = codec.decode_envelope(env)
        except Exception as exc:  # noqa: BLE001
            self.stats.decode_errors += 1
            self.stats.last_error = f"{key}: {exc}"
            return
        self.stats.per_topic_in[topic] = self.stats.per_topic_in.get(topic, 0) + 1
        self._in.put(topic, msg)
        self._request_drain()

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        self._flush.set()  # the sender: no more gathering
        if self._unsubscribe is not None:
            self._unsubscribe()
        self._sender.join(2.0)
        try:
            self.session.close()
        except Exception:  # noqa: BLE001 - closing twice or after the peer left
            pass
