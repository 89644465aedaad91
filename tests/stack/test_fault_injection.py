"""The fault-injection suite (short version; `make bench` runs the long one and writes the table).

The scenarios and their pass criteria are in failsafe_scenarios.yaml beside this file."""

from pathlib import Path

import pytest

from lotsen.harness.fault_injection import FaultRun, in_waves, load_scenarios
from lotsen.messages import ThrustCommand

SCENARIOS = load_scenarios(Path(__file__).with_name("failsafe_scenarios.yaml"))
# the estimation faults again in a wind sea (Hs 6 cm, Tp 1 s): caught by the same deadlines, no false
# alarm (the whole table in waves, three seeds: bench failsafes); and the beam current toward the fence,
# whose seed 1 in waves stalled at the route's start for ~100 s before the MPC's crab alignment
IN_WAVES = tuple(in_waves(s) for s in SCENARIOS
                 if s.name in ("gnss_offset_20m_10s", "mag_disturbance", "imu_stuck", "gyro_bias_large",
                               "current_toward_geofence"))


@pytest.mark.parametrize("scenario", SCENARIOS + IN_WAVES, ids=[s.name for s in SCENARIOS + IN_WAVES])
def test_fault_reaches_the_documented_safe_state(scenario, tmp_path):
    run = FaultRun(scenario, seed=1, log_dir=str(tmp_path))
    row = run.run()
    assert row["safe_state_reached"], row["detail"] + " | failsafes: " + row["failsafes"]
    assert row["max_outside_area_m"] <= scenario.margin_m, row
    assert row["logged"], f"the run's MCAP log {run.log_path} does not hold '{scenario.log_contains}'"
    assert row["pass"], row


def _ignore(field):
    """A supervisor that does not see one of the RC switches."""
    from dataclasses import replace

    from lotsen.supervisor.node import SupervisorNode

    original = SupervisorNode._on_rc
    return SupervisorNode, "_on_rc", lambda self, msg: original(self, replace(msg, **{field: False}))


def _holds_last_rc_command():
    """An RC mode that keeps the last command it had when the link goes (a receiver 'hold' bug)."""
    from lotsen.supervisor.modes import Rc

    def update(self, sup, t):
        rc = sup.inputs.rc
        if rc is not None and rc.command is not None:
            self.last = rc.command
        last = getattr(self, "last", None)
        return (last if last is not None else ThrustCommand.neutral(t)), None

    return Rc, "update", update


@pytest.mark.parametrize("name, sabotage", [
    ("rc_takeover", lambda: _ignore("active")),
    ("rc_estop", lambda: _ignore("estop")),
    ("rc_transmitter_lost", _holds_last_rc_command),
    ("rc_receiver_silent", _holds_last_rc_command),
])
def test_rc_scenarios_fail_when_the_supervisor_does_not_act(name, sabotage, monkeypatch):
    """The RC checks can fail: with the safety behaviour broken, the scenario does not pass."""
    monkeypatch.setattr(*sabotage())
    scenario = next(s for s in SCENARIOS if s.name == name)
    row = FaultRun(scenario, seed=1).run()
    assert not row["safe_state_reached"] and not row["pass"], row


def test_the_shoal_scenario_fails_without_the_minimum_depth_fence(monkeypatch):
    """The minimum-depth check can fail: a fence that never trips leaves the boat running onto the shoal."""
    from lotsen.supervisor.failsafes import MinDepthMonitor

    monkeypatch.setattr(MinDepthMonitor, "check", lambda self, inputs, t: (False, ""))
    scenario = next(s for s in SCENARIOS if s.name == "shoal_ahead")
    row = FaultRun(scenario, seed=1).run()
    assert not row["safe_state_reached"] and not row["pass"], row
