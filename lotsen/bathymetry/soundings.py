"""A ping's depth placed where the transducer was when it pinged.

The boat's estimate (state/estimate) is of the hull's origin; the transducer sits at body (x, y)
`transducer_m` from it (the antenna's offset plus the measured antenna-to-transducer offset), its
face `draft_m` below the surface. A ping stamped t takes the estimate interpolated at t (the two
estimates around it, heading through the shorter way round), moved by the lever arm; its depth
below the surface is the sounder's depth below the transducer plus the draft. A ping with no
estimate within `max_gap_s` of it, or without a bottom, makes no sounding.
"""

from __future__ import annotations

import bisect
import math
from collections import deque

from lotsen.messages import DepthSample, Sounding, VesselState
from lotsen.model.angles import lever_arm_ne, wrap_angle


class SoundingMaker:
    def __init__(self, transducer_m: tuple[float, float] = (0.0, 0.0), draft_m: float = 0.1,
                 history_s: float = 3.0, max_gap_s: float = 0.5) -> None:
        self.transducer_m = transducer_m
        self.draft_m = draft_m
        self.history_s = history_s
        self.max_gap_s = max_gap_s
        self._states: deque[VesselState] = deque()
        self.pings = 0
        self.no_bottom = 0
        self.no_position = 0

    def on_state(self, s: VesselState) -> None:
        if self._states and s.stamp_s <= self._states[-1].stamp_s:
            return  # out of order: the estimator's own order is kept
        self._states.append(s)
        while self._states and s.stamp_s - self._states[0].stamp_s > self.history_s:
            self._states.popleft()

    def _pose_at(self, t: float) -> tuple[float, float, float, float] | None:
        st = self._states
        if not st:
            return None
        stamps = [s.stamp_s for s in st]
        k = bisect.bisect_left(stamps, t)
        if k < len(st) and stamps[k] == t:
            a = b = st[k]
        elif 0 < k < len(st):
            a, b = st[k - 1], st[k]
        else:
            near = st[0] if k == 0 else st[-1]
            if abs(near.stamp_s - t) > self.max_gap_s:
                return None
            a = b = near
        if b.stamp_s - a.stamp_s > 2 * self.max_gap_s:
            return None
        f = 0.0 if b is a else (t - a.stamp_s) / (b.stamp_s - a.stamp_s)
        n = a.north_m + f * (b.north_m - a.north_m)
        e = a.east_m + f * (b.east_m - a.east_m)
        psi = a.heading_rad + f * wrap_angle(b.heading_rad - a.heading_rad)
        std = math.hypot(*a.std[:2]) if len(a.std) >= 2 else math.nan
        return n, e, psi, std

    def on_depth(self, d: DepthSample) -> Sounding | None:
        self.pings += 1
        if not math.isfinite(d.depth_m):
            self.no_bottom += 1
            return None
        pose = self._pose_at(d.stamp_s)
        if pose is None:
            self.no_position += 1
            return None
        n, e, psi, std = pose
        dn, de = lever_arm_ne(psi, self.transducer_m)
        return Sounding(stamp_s=d.stamp_s, north_m=n + dn, east_m=e + de, depth_m=d.depth_m + self.draft_m,
                        position_std_m=std)
