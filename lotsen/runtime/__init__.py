"""Runtime: messages, the bus, clocks, executors, nodes, configuration and launch."""

from lotsen.runtime.bus import BoundedQueue, Bus
from lotsen.runtime.clock import SimClock, WallClock
from lotsen.runtime.executor import Node, NodeContext, RealtimeExecutor, SimExecutor

__all__ = ["BoundedQueue", "Bus", "SimClock", "WallClock", "Node", "NodeContext", "RealtimeExecutor", "SimExecutor"]
