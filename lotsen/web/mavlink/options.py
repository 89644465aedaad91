"""`extra.mavlink` and `lotsen run --mavlink URL`: where the MAVLink endpoint listens or sends."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from lotsen.errors import ConfigError

#: pymavlink's connection strings lotsen accepts (a serial device is a path, with ",BAUD")
_NET = re.compile(r"(udpin|udpout|udp|tcpin|tcp):([^:\s]+):(\d{1,5})")
_SERIAL = re.compile(r"(/dev/[\w./-]+|COM\d+)(?:,(\d{3,7}))?")


def check_endpoint(url: str, where: str = "extra.mavlink.endpoints") -> str:
    """`url` if it is a connection string the endpoint can open, else ConfigError naming it."""
    m = _NET.fullmatch(url)
    if m:
        port = int(m.group(3))
        if not 1 <= port <= 65535:
            raise ConfigError(f"{where}: {url!r}: port {port} outside 1..65535")
        return url
    m = _SERIAL.fullmatch(url)
    if m:
        if m.group(2) is not None and not 1200 <= int(m.group(2)) <= 4_000_000:
            raise ConfigError(f"{where}: {url!r}: baud rate {m.group(2)} outside 1200..4000000")
        return url
    raise ConfigError(f"{where}: {url[:80]!r} is not a MAVLink connection: udpout:HOST:PORT (send to a ground "
                      "station, as ArduPilot SITL sends to 14550), udpin:HOST:PORT, tcpin:HOST:PORT, tcp:HOST:PORT, "
                      "or a serial device /dev/ttyUSB0[,57600] (a telemetry radio)")


@dataclass(frozen=True)
class MavlinkExtra:
    """`extra: {mavlink: {...}}` in the launch YAML; `lotsen run --mavlink URL` adds endpoints."""

    endpoints: tuple[str, ...] = ()  # empty: no MAVLink endpoint
    system_id: int = field(default=1, metadata={"range": (1, 254)})
    component_id: int = field(default=1, metadata={"range": (1, 254)})
    # a ground station that sends nothing signed for this long counts as gone (the link failsafe,
    # as the page's link_timeout_s): they heartbeat at 1 Hz, so 1.5 s would trip on one lost packet
    gcs_timeout_s: float = field(default=3.0, metadata={"range": (1.0, 60.0)})
    # node speed of an uploaded mission's waypoints before its first DO_CHANGE_SPEED (param WP_SPEED)
    default_speed_mps: float = field(default=0.5, metadata={"range": (0.05, 5.0)})
    # how long a command waits for the supervisor's answer before COMMAND_ACK says FAILED
    command_timeout_s: float = field(default=1.5, metadata={"range": (0.2, 10.0)})

    def __post_init__(self) -> None:
        for i, url in enumerate(self.endpoints):
            check_endpoint(url, f"extra.mavlink.endpoints[{i}]")
        if len(set(self.endpoints)) != len(self.endpoints):
            raise ConfigError("extra.mavlink.endpoints: an endpoint is given twice")
