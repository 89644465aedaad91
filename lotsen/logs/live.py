"""Live view in Foxglove: a Foxglove WebSocket server (foxglove-sdk) streaming the same channels
as the MCAP recorder (lotsen JSON channels + the well-known views), so Foxglove connected to
`ws://HOST:PORT` shows the running boat like a recorded log.

The control loop only appends to a bounded queue (drop-oldest); a sender thread encodes and hands
the messages to the server, whose per-client backlog also drops the oldest for a slow client.
"""

from __future__ import annotations

import json
import threading
import time
from typing import Any, Iterable

from lotsen.logs import foxglove_views
from lotsen.runtime.bus import Bus
from lotsen.transport import codec


class FoxgloveLive:
    def __init__(self, bus: Bus, host: str = "127.0.0.1", port: int = 8765, topics: Iterable[str] | None = None,
                 views: bool = True, queue_maxlen: int = 2000, name: str = "lotsen",
                 geo_origin: tuple[float, float, float] | None = None) -> None:
        import foxglove

        self._fg = foxglove
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name=name, host=host, port=port, context=self.context)
        self.host = host
        self.port = self.server.port
        self._channels: dict[tuple[str, str], Any] = {}
        self._views = foxglove_views.ViewMaker(geo_origin) if views and foxglove_views.available() else None
        self._queue = bus.queue(topics, maxlen=queue_maxlen)
        self._bus = bus
        self._stop = threading.Event()
        self.sent = 0
        self.errors = 0
        self._thread = threading.Thread(target=self._run, name="foxglove-live", daemon=True)
        self._thread.start()

    @property
    def dropped(self) -> int:
        return self._queue.dropped

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def _channel(self, topic: str, schema: str, schema_encoding: str, schema_data: bytes, encoding: str) -> Any:
        key = (topic, schema)
        ch = self._channels.get(key)
        if ch is None:
            ch = self._channels[key] = self._fg.Channel(
                topic, schema=self._fg.Schema(name=schema, encoding=schema_encoding, data=schema_data),
                message_encoding=encoding, context=self.context)
        return ch

    def _send(self, topic: str, msg: Any) -> None:
        cls = type(msg)
        if cls.__name__ not in codec.MESSAGE_TYPES:
            return
        t_ns = time.time_ns()
        ch = self._channel(topic, codec.schema_name(cls), "jsonschema", json.dumps(codec.json_schema(cls)).encode(), "json")
        ch.log(codec.encode_json(msg), log_time=t_ns)
        self.sent += 1
        if self._views is not None:
            for v in self._views.views(topic, msg, t_ns):
                enc, data = foxglove_views.schema_of(v.schema_name)
                self._channel(v.topic, v.schema_name, enc, data, v.encoding).log(v.data, log_time=t_ns)

    def _run(self) -> None:
        while not self._stop.is_set():
            item = self._queue.get(timeout=0.1)
            if item is None:
                continue
            for topic, msg in [item, *self._queue.get_all()]:
                try:
                    self._send(topic, msg)
                except Exception:  # noqa: BLE001 - a viewer problem must never stop the stream
                    self.errors += 1

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self._bus.remove_queue(self._queue)
        self.server.stop()
