"""Sensor fusion in simulation: seed filters vs model-aided EKF vs imufusion (x-io Fusion AHRS).

One run = magnetometer calibration from a simulated turn on the spot, then a ~4 min open-loop
manoeuvre (speed changes, turns, bow thruster, astern) with the simulator's default sensor errors
(gyro bias 0.01 rad/s + walk, accelerometer bias, soft/hard-iron distorted magnetometer, RTK GNSS
1 cm), a 0.05 m/s current and 2 m/s wind unknown to the filters' calm-water model, and a 10 s
GNSS outage at t = 175 s. All estimators see the same messages. Targets from issue 4: heading RMS
<= 1 deg, velocity RMS <= 3 cm/s (norm of the body (u, v) error). The outage drift has no target
in the issue; 1 m is used as the "usable" bound.
"""

from __future__ import annotations

import time
from dataclasses import replace

HEADING_TARGET_DEG = 1.0
VELOCITY_TARGET_MPS = 0.03
OUTAGE_TARGET_M = 1.0


def _rows(label: str, res: dict, cfg) -> list[dict]:  # type: ignore[no-untyped-def]
    rows = []
    for name, r in res["filters"].items():
        heading_ok = r["heading_rms_deg"] <= HEADING_TARGET_DEG
        row = {
            "case": label, "estimator": name,
            "heading_rms_deg": round(r["heading_rms_deg"], 3),
            "heading_max_deg": round(r["heading_max_deg"], 2),
            "heading_target_deg": HEADING_TARGET_DEG,
        }
        if name == "imufusion":
            row.update(pass_=heading_ok)
        else:
            vel_ok = r["velocity_rms_mps"] <= VELOCITY_TARGET_MPS
            out_ok = r["outage_position_err_max_m"] <= OUTAGE_TARGET_M
            row.update(
                velocity_rms_mps=round(r["velocity_rms_mps"], 4), velocity_target_mps=VELOCITY_TARGET_MPS,
                position_rms_m=round(r["position_rms_m"], 4),
                outage_drift_end_m=round(r["outage_position_err_end_m"], 3),
                outage_drift_max_m=round(r["outage_position_err_max_m"], 3), outage_target_m=OUTAGE_TARGET_M,
                rejected=sum(r["counters"]["rejected"].values()), skipped=sum(r["counters"]["skipped"].values()),
                pass_=heading_ok and vel_ok and out_ok)
        row["cpu_us_per_msg"] = round(r["cpu_us_per_msg"], 1)
        row["duration_s"] = cfg.duration_s
        row["pass"] = row.pop("pass_")
        rows.append(row)
    return rows


def run(quick: bool = False) -> list[dict]:
    from lotsen.fusion.ekf import EkfConfig
    from lotsen.fusion.evaluation import EvaluationConfig, evaluate

    base = EvaluationConfig()
    if quick:
        base = replace(base, duration_s=100.0, outage_start_s=80.0, calibration_turn_s=40.0)
    cases = [("default", base)]
    if not quick:
        cases += [
            ("seed + standstill gyro bias", replace(base, filters=("seed_kf",), compare_imufusion=False,
                                                     seed_gyro_bias_from_standstill=True)),
            ("EKF model 20 % wrong", replace(base, filters=("ekf",), compare_imufusion=False, model_error=0.2)),
            ("EKF without accel-bias states", replace(base, filters=("ekf",), compare_imufusion=False,
                                                      ekf=EkfConfig(accel_bias_states=False))),
            ("EKF without GNSS velocity", replace(base, filters=("ekf",), compare_imufusion=False,
                                                  ekf=EkfConfig(use_gnss_velocity=False))),
            ("start 170 deg off", replace(base, initial_heading_error_deg=170.0, compare_imufusion=False)),
        ]
    rows: list[dict] = []
    for label, cfg in cases:
        res = evaluate(cfg, clock=time.perf_counter)
        if label == "default":
            c = res["calibration"]
            rows.append({"case": "calibration", "estimator": "ellipse fit",
                         "center_err_uT": round(c["center_err_uT"], 4),
                         "matrix_rel_err": round(c["matrix_rel_err"], 5),
                         "residual_rms": round(c["residual_rms"], 4), "coverage_deg": round(c["coverage_deg"], 1)})
        rows += _rows(label, res, cfg)
    # ratios against the peer in the same run
    d = {r["estimator"]: r for r in rows if r["case"] == "default"}
    if "imufusion" in d and "ekf" in d:
        rows.append({"case": "default", "estimator": "ratio imufusion / ekf heading RMS",
                     "heading_rms_deg": round(d["imufusion"]["heading_rms_deg"] / d["ekf"]["heading_rms_deg"], 2)})
        rows.append({"case": "default", "estimator": "ratio seed_kf / ekf heading RMS",
                     "heading_rms_deg": round(d["seed_kf"]["heading_rms_deg"] / d["ekf"]["heading_rms_deg"], 2)})
    return rows
