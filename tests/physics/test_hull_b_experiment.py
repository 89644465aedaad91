"""The lab loop's designed experiment on hull B (the catamaran, not built like lotsen's model): the
estimator must stay consistent where the model is wrong at speed (docs/fusion.md, "The model's
velocity error"). In-process, as `lotsen experiment run designed.yaml --physics` flies it against
`hull_server.py --hull b` (bench_hull_b.py, table 3)."""

import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from hull_b_plant import run_experiment  # noqa: E402

from lotsen.sysid.experiment import load_experiment  # noqa: E402


def test_designed_experiment_on_hull_b_keeps_the_estimate_on_the_fixes():
    """Both propellers at 100 rev/s through turns at 1.5-2 m/s: the model's sway in the turn is 0.25 m/s
    off hull B's. Before GNSS velocity's covariance matching the EKF booked it as a 0.2-0.3 m/s current,
    left the fixes by 0.38 m and the supervisor held at 22.0 s (failsafe estimator, GNSS inconsistent).
    Now no estimator fault and the position within 4 cm until hull B itself leaves the design's 30 x 30 m
    area at 25.1 s (the design was checked on the model, which turns tighter: not the estimator's)."""
    node, errors = run_experiment(load_experiment(HERE / "designed_60s_30x30.yaml"), seed=0)
    assert "estimator" not in node.aborted, node.aborted
    assert node.rows and node.rows[-1][0] >= 22.5, f"ended at {node.rows[-1][0] if node.rows else 0:.1f} s: {node.aborted}"
    worst = max(e for t, e in errors if t >= 2.0)
    assert worst < 0.1, f"the estimate left the hull by {worst:.3f} m"


def test_the_lab_loops_answer_is_not_undone_by_a_current_the_estimator_invents():
    """Hull B on the lab loop's effective model (hull_b_lab_loop_answer.json: `predictive`, thrust and drag
    both well off hull B's), the fastest figure eight (1.5 m/s nominal, ~1.14 flown), current and wind,
    seed 1. Until the boat turns, a current and the model's force error look alike to the EKF; with a
    start uncertainty of 0.2 m/s for the current it booked 0.9-1.0 m/s of current within 5 s (true 0.08),
    the MPC, flying the velocity through the water, pushed harder, and the boat lost its first turn by
    57 cm (over the seam: HOLD on dead reckoning). At 0.15 m/s: within 4 cm all the way."""
    from hull_b import CatamaranEnvironment
    from hull_b_plant import figure_eight, fly_path

    from lotsen.model import VesselModel
    from lotsen.model.parameters import load_parameter_file

    model = VesselModel(load_parameter_file(str(HERE / "hull_b_lab_loop_answer.json")).parameters)
    env = CatamaranEnvironment(current_mps=0.08, current_to_deg=30.0, wind_mps=4.0, wind_from_deg=250.0,
                               gust_fraction=0.2, wind_wander_deg=15.0, seed=1)
    res = fly_path(figure_eight(1.5), model, environment=env, seed=1, gnss_antenna_m=(0.1, 0.0),
                   gnss_antenna_height_m=0.2)
    assert res.completed and not res.metrics.get("failsafes_triggered"), res.reason
    assert res.metrics["cross_track_max_m"] < 0.08, res.metrics["cross_track_max_m"]
