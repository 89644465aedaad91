"""A single-beam echosounder on a serial port (NMEA 0183 DPT/DBT; Blue Robotics' Ping2 through
its NMEA output): each ping becomes a `DepthSample` on depth/raw, stamped on arrival.

A sounder that sends both DPT and DBT for one ping is published once: DPT carries the transducer
offset and wins; a DBT counts only while no DPT came for `dbt_after_dpt_s` (`sentence: any`).
Pings without a bottom (empty depth field) are published with depth NaN: the map counts them as
dropouts and the minimum-depth fence does not take them for deep water.
"""

from __future__ import annotations

import math
from typing import Any

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import EchosounderSection
from lotsen.drivers.gnss import PortOpener
from lotsen.drivers.nmea_depth import DepthParser
from lotsen.messages import DepthSample, Topic

#: a DBT within this long after a DPT is the same ping said twice
DBT_AFTER_DPT_S = 2.0


class EchosounderNode(DriverNode):
    name = "echosounder"
    blocking_poll = True
    period_s = 0.05

    def __init__(self, cfg: EchosounderSection, open_port: PortOpener, threaded: bool = False) -> None:
        super().__init__(threaded)
        self.cfg = cfg
        self.device = f"echosounder {cfg.port}"
        self.health.device = self.device
        self.health.expected_hz = cfg.rate_hz
        self._open_port = open_port
        self.port: Any = None
        self.parser = DepthParser()
        self._last_dpt_s = -math.inf
        self.last: DepthSample | None = None

    def open(self, now: float) -> None:
        self.port = self._open_port()
        self.parser = DepthParser()

    def close(self) -> None:
        if self.port is not None:
            self.port.close()
            self.port = None

    def poll(self, now: float) -> Out:
        out: Out = []
        data = self.read_serial(out, now)
        if not data:
            return out
        for ping in self.parser.feed(data):
            if self.cfg.sentence not in ("any", ping.sentence):
                continue
            if ping.sentence == "DPT":
                self._last_dpt_s = now
            elif self.cfg.sentence == "any" and now - self._last_dpt_s < DBT_AFTER_DPT_S:
                continue
            msg = DepthSample(stamp_s=now, depth_m=ping.depth_m, offset_m=ping.offset_m,
                              sentence=ping.talker + ping.sentence)
            self.produced(now)
            self.last = msg
            out.append((Topic.DEPTH, msg))
        self.count_dropped(out, now, self.parser.counters, ("garbage_bytes", "bad_checksums", "overlong", "bad_fields"))
        return out

    def detail(self) -> str:
        m = self.last
        if m is None:
            return "no ping yet"
        return (f"{m.sentence} depth {m.depth_m:.2f} m below the transducer" if math.isfinite(m.depth_m)
                else f"{m.sentence}: no bottom")
