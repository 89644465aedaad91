"""Pieces shared by the seed filters and the EKF: GNSS noise, counters, checks (the local NED
frame of the fixes is `lotsen.model.geodetic`)."""

from __future__ import annotations

import math
from typing import Any
from dataclasses import dataclass, field

from lotsen.messages import GnssFix, GnssFixType
from lotsen.model.angles import all_finite as finite, wrap_angle  # the project's one wrap and finite check

TWO_PI = 2.0 * math.pi




@dataclass(frozen=True)
class GnssNoise:
    """Per-axis horizontal position standard deviation from a fix: max(h_acc / sqrt(2), floor) x
    inflation, floor and inflation by fix type (non-RTK fixes also wander, hence the inflation)."""

    floor_m: dict = field(default_factory=lambda: {
        GnssFixType.RTK_FIXED: 0.01, GnssFixType.RTK_FLOAT: 0.1, GnssFixType.FIX_3D: 1.0})
    inflation: dict = field(default_factory=lambda: {
        GnssFixType.RTK_FIXED: 1.0, GnssFixType.RTK_FLOAT: 1.5, GnssFixType.FIX_3D: 2.0})
    velocity_floor_mps: float = 0.03

    def position_sigma_m(self, fix: GnssFix) -> float:
        ft = GnssFixType(fix.fix_type)
        h = fix.h_acc_m if math.isfinite(fix.h_acc_m) and fix.h_acc_m > 0 else 5.0
        return max(h / math.sqrt(2.0), self.floor_m.get(ft, 2.0)) * self.inflation.get(ft, 3.0)


@dataclass
class Counters:
    """What happened to the measurements: used, rejected by a gate, skipped (NaN, stale, unusable),
    per sensor, and the stamp of the last used sample per sensor. Skipped messages are also
    counted by reason under the pseudo-sensors "stale" and "future_stamp". Model inputs
    (commands, achieved actuator values, tachometers) are counted apart, in `inputs`, so that
    `used` holds sensor samples only."""

    used: dict = field(default_factory=dict)
    inputs: dict = field(default_factory=dict)
    rejected: dict = field(default_factory=dict)
    skipped: dict = field(default_factory=dict)
    last_used_s: dict = field(default_factory=dict)

    def count(self, kind: str, sensor: str, stamp_s: float | None = None) -> None:
        d = getattr(self, kind)
        d[sensor] = d.get(sensor, 0) + 1
        if kind != "rejected" and kind != "skipped" and stamp_s is not None and math.isfinite(stamp_s):
            if stamp_s > self.last_used_s.get(sensor, -math.inf):
                self.last_used_s[sensor] = stamp_s

    def used_fraction(self, sensor: str) -> float:
        """used / (used + rejected + skipped) of one sensor; NaN if it never sent anything."""
        n = self.used.get(sensor, 0) + self.rejected.get(sensor, 0) + self.skipped.get(sensor, 0)
        return self.used.get(sensor, 0) / n if n else math.nan

    def as_dict(self) -> dict:
        return {"used": dict(self.used), "rejected": dict(self.rejected), "skipped": dict(self.skipped),
                "inputs": dict(self.inputs), "last_used_s": dict(self.last_used_s)}


def feed(estimator: Any, msg: Any) -> bool:
    """Hand one sensor message to an estimator with the on_imu / on_mag / on_gnss (/ on_rpm)
    interface. Returns False for a message it does not take (other types, GNSS to a heading-only
    AHRS, tachometer samples to an estimator without on_rpm)."""
    from lotsen.messages import GnssFix, ImuSample, MagSample, RpmSample

    if isinstance(msg, ImuSample):
        estimator.on_imu(msg)
    elif isinstance(msg, MagSample):
        estimator.on_mag(msg)
    elif isinstance(msg, GnssFix) and hasattr(estimator, "on_gnss"):
        estimator.on_gnss(msg)
    elif isinstance(msg, RpmSample) and hasattr(estimator, "on_rpm"):
        estimator.on_rpm(msg)  # measured propeller speeds (tachometers)
    else:
        return False
    return True
