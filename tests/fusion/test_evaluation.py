"""End to end: calibration from a simulated turn, then all estimators on one short manoeuvre."""

from __future__ import annotations

import math

from lotsen.harness.estimator import EvaluationConfig, evaluate


def test_short_evaluation_meets_targets() -> None:
    cfg = EvaluationConfig(duration_s=70.0, outage_start_s=50.0, calibration_turn_s=40.0, seed=5)
    res = evaluate(cfg)
    cal = res["calibration"]
    assert cal["center_err_uT"] < 0.2 and cal["matrix_rel_err"] < 0.02 and cal["coverage_deg"] > 300
    ekf, seed, peer = res["filters"]["ekf"], res["filters"]["seed_kf"], res["filters"]["imufusion"]
    assert ekf["heading_rms_deg"] < 1.0 and ekf["velocity_rms_mps"] < 0.03
    assert ekf["outage_position_err_max_m"] < 1.0
    assert ekf["fault_codes_seen"] == []  # no integrity false alarm in a run without faults
    assert seed["heading_rms_deg"] < 1.0
    assert math.isfinite(peer["heading_rms_deg"]) and peer["heading_rms_deg"] < 10.0
    # the EKF, which also uses the model and GNSS, beats the seed's dead reckoning in the outage
    assert ekf["outage_position_err_max_m"] < seed["outage_position_err_max_m"]
