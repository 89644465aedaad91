"""The controller failsafe on the closed loop: the MPC is replaced by the LOS fallback mid-lap of
the closed figure eight (as when OSQP hits its time limit on a loaded computer) and the boat must
not notice, on the simulated lake boat, in the no_fault scenario's current and wind."""

from dataclasses import replace
from pathlib import Path

from lotsen.harness.fault_injection import FaultRun, load_scenarios
from lotsen.messages import Topic

SCENARIOS = {s.name: s for s in load_scenarios(
    Path(__file__).resolve().parents[1] / "stack" / "failsafe_scenarios.yaml")}


def test_fallback_takes_over_mid_lap_where_the_boat_is():
    """Simulated compute time makes the MPC overrun from 12 s on; the supervisor hands over to LOS
    about 0.5 s later, ~5 m along the path. The fallback must start at the MPC's progress (from 0
    it re-localised metres back along the path and reported metres of cross-track error, 12.75 m in
    the bench's run) and keep the cross-track error within the no_fault bound."""
    no_fault = SCENARIOS["no_fault"]
    sc = replace(no_fault, inject="controller_overrun", fault_at_s=12.0, run_after_s=4.0,
                 expect=({"outcome": "auto_continues", "max_cross_track_m": 0.3, "failsafes_allowed": ["controller"]},
                         {"outcome": "fallback", "within_s": 1.0}))
    run = FaultRun(sc, seed=1)
    statuses = []
    run.stack.bus.subscribe(Topic.CONTROL_STATUS, statuses.append)
    row = run.run()
    assert run.supervisor.fallback is not None and run.supervisor.fallback.name == "los"
    handover = next(i for i, s in enumerate(statuses) if s.controller == "los")
    before, after = statuses[handover - 1], statuses[handover]
    assert before.controller == "mpc" and before.progress_m > 3.0
    assert abs(after.progress_m - before.progress_m) < 0.2  # progress is continuous across the handover
    assert row["pass"], row["detail"]
