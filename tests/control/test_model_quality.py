"""Control that is monotone in model quality (issue 25 item 3), test-sized: the figure eight on the
EKF in 0.1 m/s current and 3 m/s wind on the lake boat (a boat that is not the default model).
The bench (`bench/bench_model_chain.py`, `model_quality_rows`, `defaults_vs_exact_rows`) runs the
whole sweep (0, 5, 10, 15, 25 % model error, three seeds; boats 10-40 % from the defaults)."""

import statistics
from pathlib import Path

import numpy as np
import pytest

from lotsen.control import ControlConfig, make_path_follower
from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
from lotsen.model import DEFAULT_PARAMETERS, Environment, VesselModel
from lotsen.planning import plan_route
from lotsen.planning.io import load_route
from lotsen.sim import DEFAULT_BOAT, random_boat
from lotsen.sim.boat import scaled_parameters

ROUTE = Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight.yaml"
ENV = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)


def _mission(boat, params, seed):
    model = VesselModel(params)
    path = plan_route(load_route(ROUTE))
    cfg = MissionConfig(environment=ENV, sensors=True, seed=seed)
    res = run_mission(path, make_path_follower(ControlConfig(), model), cfg, model=model, boat=boat,
                      estimator=make_sim_ekf(cfg, path, model, boat=boat))
    assert res.completed, res.reason
    assert res.metrics["failsafes_triggered"] == []
    return res.metrics


@pytest.mark.slow
def test_exact_model_tracks_best_and_a_25_percent_error_within_1_5x():
    """Model = the lake boat's coefficients, each scaled by (1 +- e) with random signs per seed.
    Measured (seeds 0-2, the bench's; yaw-rate weight 4): e = 0 0.66-0.68 cm at <= 0.05 reversals/s,
    e = 25 % 0.71-0.99 cm (1.23x); over seeds 0-8 1.28x, worst seed 1.66x (docs/control.md; with
    yaw-rate weight 1 it was 1.52x there, worst 2.67x). The design before tracked better with the wrong model than
    with the exact one (1.7-1.8 vs 1.1-1.2 cm); the 10 % tolerance on "exact <= wrong" is the
    seed-to-seed spread of these missions (~0.05 cm), far below that inversion. Seeds 0 and 1 here
    (0.68/0.66 cm against 0.99/0.78: seed 0 is the worst of the three); all of 0-8 in bench model_chain."""
    exact, wrong = [], []
    for seed in (0, 1):
        m = _mission(DEFAULT_BOAT, DEFAULT_BOAT.parameters, seed)
        exact.append(m["cross_track_rms_m"])
        assert m["reversals_counted_on"] == "achieved speeds"
        assert m["reversals_per_s"] <= 0.1
        assert m["cross_track_rms_m"] <= 0.008
        w = scaled_parameters(DEFAULT_BOAT.parameters, 0.25, np.random.default_rng(1000 + seed))
        wrong.append(_mission(DEFAULT_BOAT, w, seed)["cross_track_rms_m"])
    e, w = statistics.mean(exact), statistics.mean(wrong)
    assert e <= 1.1 * w, (exact, wrong)
    assert w <= 1.5 * e, (exact, wrong)


@pytest.mark.slow
@pytest.mark.parametrize("boat_seed", [21, 30])  # 22 (and 23) in bench model_chain's table of randomised boats
def test_exact_model_tracks_no_worse_than_the_defaults_on_a_randomised_boat(boat_seed):
    """Issue 25's done-when on boats 10-40 % from the defaults (with the lake boat's unmodelled
    effects): the boat's exact coefficients track no worse than the default ones. Measured (seed =
    boat): 21 0.63 vs 0.94 cm, 22 0.67 vs 1.05, 30 0.65 vs 1.15. Of boats 30-37, 32 ties (0.73 both) and
    37 is 0.02 cm worse with its exact model on seed 37 (0.84 vs 0.82; on seeds 0-2 no worse): the
    missions' seed-to-seed spread, ~0.05 cm, which a single mission on such a boat cannot beat."""
    boat = random_boat(boat_seed)
    exact = _mission(boat, boat.parameters, boat_seed)["cross_track_rms_m"]
    defaults = _mission(boat, DEFAULT_PARAMETERS, boat_seed)["cross_track_rms_m"]
    assert exact <= defaults, (exact, defaults)
