"""Failsafe monitors: each watches one condition with a threshold and a persistence time, and
names the action the supervisor takes (docs/failsafes.md has the table).

Monitors are pure: they get values and times, never read a clock. A condition must hold for
`persist_s` before the failsafe triggers, and be clear for `clear_s` before it releases
(hysteresis), so a single bad sample neither triggers nor releases one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from lotsen.messages import GnssFixType

Action = Literal["continue", "hold", "stop", "return", "fallback", "neutral"]


def _r(lo: float, hi: float) -> dict:
    return {"range": (lo, hi)}


@dataclass(frozen=True)
class FailsafeConfig:
    """Thresholds and actions of every failsafe (all times in seconds)."""

    # operator link (the web pilot): MANUAL always stops; AUTO/RETURN continue or hold
    link_timeout_s: float = field(default=1.5, metadata=_r(0.2, 60.0))
    link_lost_auto_action: Literal["continue", "hold"] = "continue"
    # manual driving: a ManualCommand older than this is treated as zero
    manual_timeout_s: float = field(default=0.5, metadata=_r(0.1, 5.0))
    # GNSS: no usable fix for gnss_lost_s -> hold on dead reckoning, then stop after gnss_stop_after_s
    gnss_lost_s: float = field(default=1.5, metadata=_r(0.2, 60.0))
    gnss_lost_action: Literal["hold", "stop"] = "hold"
    gnss_stop_after_s: float = field(default=20.0, metadata=_r(1.0, 600.0))
    # RTK degraded: fix type below gnss_min_fix for gnss_degraded_s
    gnss_min_fix: Literal["RTK_FIXED", "RTK_FLOAT", "FIX_3D"] = "RTK_FLOAT"
    gnss_degraded_s: float = field(default=2.0, metadata=_r(0.2, 60.0))
    gnss_degraded_action: Literal["hold", "stop", "continue"] = "hold"
    # geofence: estimated position outside the navigable area by more than geofence_margin_m
    geofence_margin_m: float = field(default=0.0, metadata=_r(0.0, 20.0))
    geofence_persist_s: float = field(default=0.3, metadata=_r(0.0, 10.0))
    geofence_inset_m: float = field(default=1.5, metadata=_r(0.1, 20.0))  # hold this far inside
    geofence_in_manual: bool = False
    # battery (3S LiPo): low -> return to harbour, critical -> stop
    battery_low_v: float = field(default=10.8, metadata=_r(0.0, 60.0))
    battery_critical_v: float = field(default=10.2, metadata=_r(0.0, 60.0))
    battery_persist_s: float = field(default=5.0, metadata=_r(0.0, 120.0))
    # controller: failure or overrun -> fallback controller, then stop
    controller_overrun_factor: float = field(default=0.8, metadata=_r(0.1, 10.0))  # x control period
    controller_overrun_count: int = field(default=5, metadata=_r(1, 1000))
    controller_failure_count: int = field(default=3, metadata=_r(1, 1000))
    fallback_controller: Literal["los", "pursuit", "lq"] = "los"
    # thruster: tachometer disagrees with the command by more than this fraction of the command
    # and by more than thruster_mismatch_min_rps (tachometer quantisation, motor lag)
    thruster_mismatch_frac: float = field(default=0.5, metadata=_r(0.05, 1.0))
    thruster_mismatch_min_rps: float = field(default=8.0, metadata=_r(0.0, 100.0))
    # 0.5 s: a commanded step is ramp- and lag-limited to ~0.35 s of mismatch at most
    thruster_persist_s: float = field(default=0.5, metadata=_r(0.1, 30.0))
    thruster_fault_action: Literal["hold", "stop", "continue"] = "hold"
    # state estimate: uncertainty above this (position std, m) counts as no position
    max_position_std_m: float = field(default=2.0, metadata=_r(0.01, 100.0))

    @property
    def min_fix_type(self) -> GnssFixType:
        return GnssFixType[self.gnss_min_fix]


class PersistentCondition:
    """True once `condition` has held for persist_s; false again after it is clear for clear_s."""

    def __init__(self, persist_s: float, clear_s: float | None = None) -> None:
        self.persist_s = persist_s
        self.clear_s = persist_s if clear_s is None else clear_s
        self.active = False
        self._since: float | None = None  # when the raw condition last changed towards the other state
        self.activations = 0

    def update(self, condition: bool, t: float) -> bool:
        if condition != self.active:
            if self._since is None:
                self._since = t
            if t - self._since >= (self.persist_s if condition else self.clear_s):
                self.active = condition
                self._since = None
                if condition:
                    self.activations += 1
        else:
            self._since = None
        return self.active


@dataclass
class FailsafeState:
    """The currently active failsafes with their reasons, for the status message and the log."""

    active: dict[str, str] = field(default_factory=dict)

    def set(self, name: str, on: bool, reason: str = "") -> tuple[bool, bool]:
        """Returns (became_active, became_inactive)."""
        was = name in self.active
        if on:
            self.active[name] = reason
        else:
            self.active.pop(name, None)
        return (on and not was, was and not on)
