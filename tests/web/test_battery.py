"""The HUD's battery time left (lotsen.web.telemetry.BatteryEstimator): from a configured
capacity, else from the capacity implied by the charge drawn while the remaining fraction fell."""

from __future__ import annotations

import pytest

from lotsen.messages import BatteryStatus
from lotsen.web.telemetry import BatteryEstimator


def discharge(est: BatteryEstimator, capacity_ah: float, current_a: float, seconds: int) -> float:
    frac = 0.9
    for t in range(seconds + 1):
        est.update(BatteryStatus(stamp_s=float(t), voltage_v=12.0, current_a=current_a, remaining_frac=frac))
        frac -= current_a / 3600.0 / capacity_ah
    return frac + current_a / 3600.0 / capacity_ah  # the last fraction sent


def test_time_left_from_the_configured_capacity():
    est = BatteryEstimator(capacity_ah=5.0)
    last = discharge(est, 5.0, 2.0, 20)
    left, basis = est.time_left_s(last)
    assert basis == "capacity" and left == pytest.approx(last * 5.0 * 3600 / 2.0)


def test_time_left_from_the_observed_discharge_once_the_fraction_has_fallen():
    est = BatteryEstimator()  # no capacity: 1 A for 2 s barely moves a 2 Ah pack (< min_drop)
    last = discharge(est, 2.0, 1.0, 2)
    assert est.time_left_s(last) == (None, "")
    est = BatteryEstimator()
    last = discharge(est, 2.0, 10.0, 120)  # 0.33 Ah drawn: a drop of 0.17 reveals 2 Ah
    left, basis = est.time_left_s(last)
    assert basis == "discharge"
    assert left == pytest.approx(last * 2.0 * 3600 / 10.0, rel=1e-3)


def test_no_estimate_without_current():
    est = BatteryEstimator(capacity_ah=5.0)
    discharge(est, 5.0, 0.0, 5)
    assert est.time_left_s(0.5) == (None, "")
