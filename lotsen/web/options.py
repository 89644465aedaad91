"""Web server options: `LaunchConfig.web` plus the optional `extra: {web: {...}}` keys (`WebExtra`,
typed with the rest of the launch config by `lotsen.stack.config`)."""

from __future__ import annotations

import os
import re
import secrets
from dataclasses import dataclass, field

from lotsen.errors import ConfigError
from lotsen.runtime.config import LaunchConfig
from lotsen.web.auth import check_token_strength

OSM_TILE_URL = "https://tile.openstreetmap.org/{z}/{x}/{y}.png"
OSM_ATTRIBUTION = "© OpenStreetMap contributors"


_HOST_NAME = re.compile(r"(?=.{1,253}$)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*\.?")


@dataclass(frozen=True)
class WebExtra:
    """Settings not (yet) in `LaunchConfig.web`; given as `extra: {web: {...}}` in the launch YAML."""

    # a pilot silent for longer counts as gone (LinkStatus.pilot_connected false, takeover allowed);
    # default: the supervisor's extra.failsafes.link_timeout_s, so both sides agree
    link_timeout_s: float | None = field(default=None, metadata={"range": (0.2, 60.0)})
    max_viewers: int = field(default=16, metadata={"range": (1, 256)})
    # connections per address (IPv4 address or IPv6 /64) besides the pilot's seat
    max_per_address: int = field(default=4, metadata={"range": (1, 64)})
    # offline map tiles: the cache the page's background comes from (served at /tiles/z/x/y.png)
    tile_dir: str = "~/.cache/lotsen/tiles"
    tile_url: str = OSM_TILE_URL  # {z}/{x}/{y} template for the pre-load (pilot, while online)
    tile_attribution: str = OSM_ATTRIBUTION
    tile_max_count: int = field(default=1000, metadata={"range": (1, 20000)})  # per pre-load
    tile_max_zoom: int = field(default=19, metadata={"range": (0, 22)})
    # battery: time left from the capacity when given, else from the observed discharge
    battery_capacity_ah: float | None = field(default=None, metadata={"range": (0.01, 1000.0)})
    # any page that reaches the server may press the emergency stop (not only the pilot): a second
    # person on the jetty can stop the boat; off by default, where a viewer only watches
    viewer_may_estop: bool = False
    # the boat's pilot credential (lotsen.web.pairing), used when web.pilot_token is not set; None:
    # $LOTSEN_CONFIG_DIR/pairing/<boat>.credential (~/.config/lotsen by default)
    credential_file: str | None = None
    # TLS: `lotsen run --tls` creates a self-signed pair in tls_dir once (lotsen.web.tls), or serves
    # the given certificate and key; setting both files turns TLS on without the flag
    tls_dir: str = "~/.config/lotsen/tls"
    tls_certfile: str | None = None
    tls_keyfile: str | None = None
    # further names the boat is reached by (a LAN DNS name, a reverse proxy's name), served
    # besides HostGuard's own list; a bare host name each: no scheme, port, path or wildcard
    allowed_hosts: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for i, name in enumerate(self.allowed_hosts):
            if not _HOST_NAME.fullmatch(name):
                raise ConfigError(f"extra.web.allowed_hosts[{i}]: {name[:80]!r} is not a bare host name "
                                  "(letters, digits, '-' and '.'; no scheme, port, path or '*')")
        if not all(k in self.tile_url for k in ("{z}", "{x}", "{y}")) or not self.tile_url.startswith(
                ("http://", "https://")):
            raise ConfigError(f"extra.web.tile_url: {self.tile_url[:80]!r} must be an http(s) URL with "
                              "{z}, {x} and {y}")
        if (self.tls_certfile is None) != (self.tls_keyfile is None):
            raise ConfigError("extra.web: tls_certfile and tls_keyfile go together")


@dataclass(frozen=True)
class WebOptions:
    host: str = "127.0.0.1"
    port: int = 8080
    pilot_token: str = ""
    token_generated: bool = False
    telemetry_rate_hz: float = 20.0
    link_timeout_s: float = 1.5
    max_viewers: int = 16
    max_per_address: int = 4
    log_dir: str = ""  # MCAP files listed and served at /logs/ ("" = none)
    tile_dir: str = ""  # "" = no tile cache
    tile_url: str = OSM_TILE_URL
    tile_attribution: str = OSM_ATTRIBUTION
    tile_max_count: int = 1000
    tile_max_zoom: int = 19
    battery_capacity_ah: float | None = None
    viewer_may_estop: bool = False
    credential_file: str = ""  # the boat's credential file (re-read when it changes); "" = a fixed token
    tls_dir: str = ""
    tls_certfile: str | None = None
    tls_keyfile: str | None = None
    allowed_hosts: tuple[str, ...] = ()

    @classmethod
    def from_config(cls, config: LaunchConfig, extra: WebExtra | None = None,
                    failsafe_link_timeout_s: float = 1.5) -> "WebOptions":
        """`config.web` with `extra` (`extra.web` of the launch config); `failsafe_link_timeout_s`:
        the supervisor's link timeout, the default of ours so both agree. A configured
        `web.pilot_token` weaker than 128 bits is refused here (ConfigError)."""
        extra = extra or WebExtra()
        web = config.web
        token = web.pilot_token
        paired = bool(extra.credential_file)
        if paired:  # the boat's own credential (lotsen.web.pairing): read here, re-read by the seat
            from lotsen.web.pairing import PilotCredential

            token = PilotCredential(os.path.expanduser(extra.credential_file)).current()
        generated = not token
        if generated:
            token = secrets.token_urlsafe(16)  # 128 random bits, 22 characters
        else:
            check_token_strength(token)
        return cls(host=web.host, port=web.port, pilot_token=token, token_generated=generated,
                   telemetry_rate_hz=web.telemetry_rate_hz,
                   link_timeout_s=extra.link_timeout_s or failsafe_link_timeout_s,
                   max_viewers=extra.max_viewers, max_per_address=extra.max_per_address,
                   log_dir=config.logging.directory or "",
                   tile_dir=os.path.expanduser(extra.tile_dir) if extra.tile_dir else "",
                   tile_url=extra.tile_url, tile_attribution=extra.tile_attribution,
                   tile_max_count=extra.tile_max_count, tile_max_zoom=extra.tile_max_zoom,
                   battery_capacity_ah=extra.battery_capacity_ah, viewer_may_estop=extra.viewer_may_estop,
                   credential_file=os.path.expanduser(extra.credential_file) if paired else "",
                   tls_dir=os.path.expanduser(extra.tls_dir) if extra.tls_dir else "",
                   tls_certfile=extra.tls_certfile and os.path.expanduser(extra.tls_certfile),
                   tls_keyfile=extra.tls_keyfile and os.path.expanduser(extra.tls_keyfile),
                   allowed_hosts=extra.allowed_hosts)
