"""Fault-injection suite, long version: every scenario on several seeds of the simulated stack
(sensor noise, EKF, supervisor with MPC), on simulated time, in calm water and again in a wind sea
(Hs 6 cm, Tp 1 s, from 250 deg: `lotsen.harness.fault_injection.in_waves`; issue 46). A row per
scenario, sea and seed: whether the documented outcome (tests/stack/failsafe_scenarios.yaml) happened
and when, the largest excursion outside the navigable area against its margin, and whether the
run's log holds the event (docs/failsafes.md).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from lotsen.harness.fault_injection import SUITE_WAVES, FaultRun, in_waves, load_scenarios

# the table and its pass criteria live with the tests, not beside the code they judge
SCENARIOS = load_scenarios(Path(__file__).resolve().parents[1] / "tests" / "stack" / "failsafe_scenarios.yaml")


def run(quick: bool = False) -> list[dict]:
    seeds = (0,) if quick else (0, 1, 2)
    rows = []
    seas = (("calm water", None), (f"Hs {SUITE_WAVES.hs_m * 100:g} cm", SUITE_WAVES))
    for sea, waves in seas:
        for base in SCENARIOS:
            sc = in_waves(base, waves) if waves is not None else base
            for seed in seeds:
                with tempfile.TemporaryDirectory() as logs:
                    r = FaultRun(sc, seed=seed, log_dir=logs).run()
                rows.append({"table": f"fault suite, {sea}", "scenario": base.name, "seed": seed, "expected": r["expected"],
                             "time_to_outcome_s": r["time_to_safe_s"],
                             "max_outside_area_m": r["max_outside_area_m"], "margin_m": r["margin_m"],
                             "logged_in_mcap": r["logged"], "failsafes": r["failsafes"][:120],
                             "pass": r["pass"], "detail": r["detail"][:200]})
    return rows
