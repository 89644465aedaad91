"""Attach the Zenoh bridge to a `lotsen.stack.launch.Stack`.

    from lotsen.stack.zenoh import add_bridge
    register_part("zenoh", add_bridge)   # active when the config's extra.zenoh is present and enabled

Configured as `extra: {zenoh: {enabled: true, vessel: boat, listen: [tcp/192.168.4.1:7447],
publish: [state/estimate, gps_chatter, ...], subscribe: ["shore/**"]}}` (keys of `BridgeConfig`,
plus `enabled`), typed with the rest of the config (`lotsen.stack.config.ExtraConfig.zenoh`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge


def add_bridge(stack: Any, config: BridgeConfig | None = None) -> ZenohBridge | None:
    """Bridge `stack`'s bus to Zenoh; with no `config`, read `extra.zenoh` (absent: nothing added)."""
    cfg = config or stack.config.extra.zenoh
    if cfg is None:
        return None
    bridge = ZenohBridge(cfg)
    stack.add(bridge)
    stack.services["zenoh"] = bridge
    stack.services.setdefault("on_shutdown", []).append(bridge.close)
    eps = ", ".join([*(f"listen {e}" for e in cfg.listen), *(f"connect {e}" for e in cfg.connect)]) or "no endpoints"
    stack.services.setdefault("banner", []).append(
        f"zenoh: {cfg.mode} '{cfg.vessel}' ({eps}; multicast scouting {'ON' if cfg.multicast_scouting else 'off'}); "
        f"publishing {', '.join(cfg.publish) or 'nothing'}; subscribed to {', '.join(cfg.subscribe) or 'nothing'}")
    return bridge


def config_as_dict(cfg: BridgeConfig) -> dict:
    return dataclasses.asdict(cfg)
