"""The fault-injection suite (short version; `make bench` runs the long one and writes the table).

The scenarios and their pass criteria are in failsafe_scenarios.yaml beside this file."""

from pathlib import Path

import pytest

from lotsen.harness.fault_injection import FaultRun, load_scenarios

SCENARIOS = load_scenarios(Path(__file__).with_name("failsafe_scenarios.yaml"))


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_fault_reaches_the_documented_safe_state(scenario, tmp_path):
    run = FaultRun(scenario, seed=1, log_dir=str(tmp_path))
    row = run.run()
    assert row["safe_state_reached"], row["detail"] + " | failsafes: " + row["failsafes"]
    assert row["max_outside_area_m"] <= scenario.margin_m, row
    assert row["logged"], f"the run's MCAP log {run.log_path} does not hold '{scenario.log_contains}'"
    assert row["pass"], row
