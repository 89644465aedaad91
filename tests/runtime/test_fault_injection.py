"""The fault-injection suite (short version; `make bench` writes the table)."""

import pytest

from lotsen.runtime.fault_injection import SCENARIOS, FaultRun


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s.name for s in SCENARIOS])
def test_fault_reaches_the_documented_safe_state(scenario):
    row = FaultRun(scenario, seed=1).run()
    assert row["safe_state_reached"], row["detail"]
    assert row["max_outside_area_m"] <= scenario.margin_m, row
    assert row["logged"], f"the log does not hold '{scenario.log_contains}'"
    assert row["pass"], row
