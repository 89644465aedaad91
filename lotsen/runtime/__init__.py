"""Runtime: messages, the bus, clocks, executors, nodes, configuration and launch.

The names below load their module on first use: a command that reads only the configuration's
sections (`lotsen identify`: `config.VesselSection`) does not import the bus and the executors with it."""

from __future__ import annotations

from typing import Any

__all__ = ["BoundedQueue", "Bus", "SimClock", "WallClock", "Node", "NodeContext", "RealtimeExecutor", "SimExecutor"]


def __getattr__(name: str) -> Any:
    if name in ("BoundedQueue", "Bus"):
        from lotsen.runtime import bus as module
    elif name in ("SimClock", "WallClock"):
        from lotsen.runtime import clock as module
    elif name in ("Node", "NodeContext", "RealtimeExecutor", "SimExecutor"):
        from lotsen.runtime import executor as module
    else:
        raise AttributeError(f"module 'lotsen.runtime' has no attribute {name!r}")
    return getattr(module, name)
