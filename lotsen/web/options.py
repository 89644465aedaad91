"""Web server options: `LaunchConfig.web` plus the optional `extra: {web: {...}}` keys."""

from __future__ import annotations

import secrets
from dataclasses import dataclass, field

from lotsen.runtime.config import LaunchConfig, from_mapping


@dataclass(frozen=True)
class WebExtra:
    """Settings not (yet) in `LaunchConfig.web`; given as `extra: {web: {...}}` in the launch YAML."""

    # a pilot silent for longer counts as gone (LinkStatus.pilot_connected false, takeover allowed);
    # default: the supervisor's extra.failsafes.link_timeout_s, so both sides agree
    link_timeout_s: float | None = field(default=None, metadata={"range": (0.2, 60.0)})
    max_viewers: int = field(default=16, metadata={"range": (1, 256)})


@dataclass(frozen=True)
class WebOptions:
    host: str = "127.0.0.1"
    port: int = 8080
    pilot_token: str = ""
    token_generated: bool = False
    telemetry_rate_hz: float = 20.0
    link_timeout_s: float = 1.5
    max_viewers: int = 16

    @classmethod
    def from_config(cls, config: LaunchConfig) -> "WebOptions":
        extra = from_mapping(WebExtra, config.extra.get("web"), "extra.web")
        web = config.web
        token = web.pilot_token
        generated = not token
        if generated:
            token = secrets.token_urlsafe(16)
        return cls(host=web.host, port=web.port, pilot_token=token, token_generated=generated,
                   telemetry_rate_hz=web.telemetry_rate_hz,
                   link_timeout_s=extra.link_timeout_s or _failsafe_link_timeout(config),
                   max_viewers=extra.max_viewers)


def _failsafe_link_timeout(config: LaunchConfig) -> float:
    fs = config.extra.get("failsafes")
    value = fs.get("link_timeout_s") if isinstance(fs, dict) else None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0:
        return float(value)
    try:
        from lotsen.runtime.failsafes import FailsafeConfig
    except ImportError:  # pragma: no cover - runtime without the supervisor
        return 1.5
    return FailsafeConfig().link_timeout_s
