"""Soundings as a node: each echosounder ping (depth/raw) placed where the transducer was at the
ping's time, from the state estimate (state/estimate), published on depth/sounding for the log,
the page's coverage layer and the depth map (lotsen.bathymetry.SoundingMaker does the work)."""

from __future__ import annotations

from lotsen.bathymetry import SoundingMaker
from lotsen.messages import DepthSample, Topic, VesselState
from lotsen.runtime.executor import Node, NodeContext


class SoundingNode(Node):
    name = "soundings"

    def __init__(self, transducer_m: tuple[float, float], draft_m: float) -> None:
        self.maker = SoundingMaker(transducer_m, draft_m)
        self._pending: list[DepthSample] = []

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.STATE, self._on_state)
        ctx.subscribe(Topic.DEPTH, self._on_depth)

    def _on_state(self, msg: VesselState) -> None:
        self.maker.on_state(msg)
        # a ping newer than the last estimate waits for the estimate after it (interpolation, not extrapolation)
        waiting, self._pending = self._pending, []
        for d in waiting:
            if d.stamp_s <= msg.stamp_s:
                self._emit(d)
            else:
                self._pending.append(d)

    def _on_depth(self, msg: DepthSample) -> None:
        if len(self._pending) < 50:
            self._pending.append(msg)

    def _emit(self, d: DepthSample) -> None:
        s = self.maker.on_depth(d)
        if s is not None:
            self.ctx.publish(Topic.SOUNDING, s)
