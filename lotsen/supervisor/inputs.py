"""What the supervisor listens to: the latest of every input with its arrival time.

The bottom of the supervisor's modules: the failsafe monitors read these inputs, the pre-arm
checks and the modes are judged on them, the node fills them in. It imports nothing of the
supervisor (the four modules point one way: inputs, modes <- failsafes <- prearm <- node).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from lotsen.messages import ActuatorState, BatteryStatus, DepthSample, GnssFix, LinkStatus, ManualCommand, \
    RcOverride, RecorderStatus, ThrustCommand, VesselState
from lotsen.model.angles import all_finite


def finite_state(s: VesselState) -> bool:
    return all_finite(*s.as_array_tuple())


@dataclass
class SupervisorInputs:
    """The latest of everything the supervisor listens to, with arrival times (runtime clock)."""

    state: VesselState | None = None
    manual: ManualCommand | None = None
    manual_arrival_s: float = -math.inf
    experiment: ThrustCommand | None = None  # the running identification experiment's command
    experiment_arrival_s: float = -math.inf
    link: LinkStatus | None = None
    link_arrival_s: float = -math.inf
    rc: RcOverride | None = None
    rc_arrival_s: float = -math.inf
    rc_takeover: bool = False  # the takeover switch as last seen over a good link
    fix: GnssFix | None = None
    last_usable_fix_s: float | None = None
    battery: BatteryStatus | None = None
    depth: DepthSample | None = None  # the echosounder's last ping that found a bottom
    depth_arrival_s: float = -math.inf
    actuators: ActuatorState | None = None
    health: Any = None  # EstimatorHealth (lotsen.fusion) when the estimator publishes one
    route: Any = None  # the route in use (its navigable area and obstacles), None without one
    # the boat's own navigable area: the launch config's route area (None: not configured). No
    # route received from the page may leave it, and the geofence acts on it with or without a route
    fence: Any = None
    recorder: RecorderStatus | None = None  # the recorder's disk (lotsen run's recorder process)
    recorder_arrival_s: float = -math.inf

    def fence_regions(self) -> tuple[Any, ...]:
        """The routes whose free water the boat must stay in: the route in use and the fence."""
        return tuple(r for r in (self.route, self.fence) if r is not None)

    @property
    def escs_armed(self) -> bool:
        return self.actuators is not None and bool(self.actuators.escs_armed)

    def position_trusted(self, max_position_std_m: float) -> bool:
        """A finite state estimate whose position std is within the bound and whose integrity
        monitor (when there is one) trusts the position."""
        s = self.state
        if s is None or not finite_state(s):
            return False
        if len(s.std) >= 2 and max(s.std[0], s.std[1]) > max_position_std_m:
            return False
        return self.health is None or bool(self.health.position_ok)
