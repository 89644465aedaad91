"""The fault-injection suite (short version; `make bench` writes the table)."""

import pytest

from lotsen.runtime.fault_injection import SCENARIOS, FaultRun


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_fault_reaches_the_documented_safe_state(scenario, tmp_path):
    run = FaultRun(scenario, seed=1, log_dir=str(tmp_path))
    row = run.run()
    assert row["safe_state_reached"], row["detail"]
    assert row["max_outside_area_m"] <= scenario.margin_m, row
    assert row["logged"], f"the run's MCAP log {run.log_path} does not hold '{scenario.log_contains}'"
    assert row["pass"], row
