"""The last gate before the actuators, shared by the simulated boat and the hardware driver.

Whatever happens upstream, the thrusters get a finite, limited command, and neutral when the
newest command is older than the deadline (a crashed or stalled autonomy process must not leave
the thrusters running; ArduPilot's equivalent is the main-loop stall failsafe).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lotsen.messages import ThrustCommand
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits


@dataclass
class GuardCounters:
    accepted: int = 0
    non_finite: int = 0
    stale_events: int = 0


class ActuatorGuard:
    def __init__(self, limits: ActuatorLimits = DEFAULT_LIMITS, deadline_s: float = 0.5) -> None:
        self.limits = limits
        self.deadline_s = deadline_s
        self._last: ThrustCommand | None = None
        self._last_arrival_s = -math.inf
        self._stale = True
        self.counters = GuardCounters()

    def accept(self, cmd: ThrustCommand, now_s: float) -> None:
        if not cmd.is_finite():
            # a NaN anywhere on the path to the actuators: neutral, now (not the last good command)
            self.counters.non_finite += 1
            self._last = ThrustCommand.neutral(now_s, source="guard:non-finite")
        else:
            self.counters.accepted += 1
            self._last = cmd
        self._last_arrival_s = now_s

    @property
    def stale(self) -> bool:
        return self._stale

    def output(self, now_s: float) -> tuple[float, float, float, float, float]:
        """The set-point to apply now: the last command, clipped, or neutral when stale."""
        stale = self._last is None or now_s - self._last_arrival_s > self.deadline_s
        if stale and not self._stale:
            self.counters.stale_events += 1
        self._stale = stale
        if stale or self._last is None:
            return (0.0, 0.0, 0.0, 0.0, 0.0)
        return self.limits.clip(*self._last.as_tuple())
