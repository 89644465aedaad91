import math

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.model import VesselModel
from lotsen.sysid.experiment import (
    InputGenerator, check_experiment, experiment_to_dict, load_experiment, parse_experiment, predict_trajectory,
)


def test_all_example_experiments_parse_and_pass_checks():
    from pathlib import Path

    files = sorted(Path(__file__).parents[2].joinpath("examples", "experiments").glob("*.yaml"))
    assert len(files) >= 6
    for f in files:
        exp = load_experiment(f)
        check_experiment(exp)
        assert exp.duration_s > 0


def test_piece_values_and_signs():
    exp = parse_experiment({"name": "x", "pieces": [
        {"type": "constant", "duration_s": 2, "alpha_deg": 10, "n1_rps": 30, "n2_rps": 40, "nt_rps": -5},
        {"type": "ramp", "duration_s": 2, "from": {"n_rps": 0}, "to": {"n_rps": 40}},
        {"type": "turning_circle", "duration_s": 2, "alpha_deg": 30, "n_rps": 50, "direction": "starboard"},
        {"type": "steps", "step_duration_s": 1, "levels": [{"n_rps": 10}, {"n_rps": 20}]},
    ]})
    g = InputGenerator(exp)
    assert g.command(0.5, None) == pytest.approx((math.radians(10), math.radians(10), 30, 40, -5))
    assert g.command(3.0, None)[2] == pytest.approx(20.0)
    assert g.command(4.5, None)[0] == pytest.approx(-math.radians(30))  # starboard turn: alpha < 0
    assert g.command(6.5, None)[2] == pytest.approx(10.0)
    assert g.command(7.5, None)[2] == pytest.approx(20.0)
    assert g.command(99.0, None) == (0.0, 0.0, 0.0, 0.0, 0.0)


def test_zigzag_switches_on_heading():
    exp = parse_experiment({"name": "z", "pieces": [
        {"type": "zigzag", "duration_s": 100, "alpha_deg": 20, "heading_deg": 10, "n_rps": 60}]})
    g = InputGenerator(exp)
    a0 = g.command(0.0, (0, 0, 0.0))[0]
    assert a0 < 0  # first turn to starboard
    assert g.command(1.0, (0, 0, math.radians(5)))[0] == a0
    assert g.command(2.0, (0, 0, math.radians(10.5)))[0] > 0
    assert g.command(3.0, (0, 0, math.radians(0)))[0] > 0
    assert g.command(4.0, (0, 0, math.radians(-10.5)))[0] < 0


def test_zigzag_against_the_model_oscillates():
    exp = parse_experiment({"name": "z", "area": {"size_m": [200, 200]}, "pieces": [
        {"type": "zigzag", "duration_s": 40, "alpha_deg": 10, "heading_deg": 10, "n_rps": 70}]})
    pred = predict_trajectory(exp, VesselModel())
    psi = np.degrees(pred.x[:, 2])
    # the course-unstable default vessel overshoots (about 45 deg) but the trigger keeps it bounded
    assert psi.max() > 10 and psi.min() < -10 and np.abs(psi).max() < 90
    assert np.sum(np.diff(np.sign(pred.u[:-1, 0])) != 0) >= 4


def test_limits_and_area_are_refused_with_clear_messages():
    too_fast = parse_experiment({"name": "x", "pieces": [{"type": "constant", "duration_s": 2, "n1_rps": 120}]})
    with pytest.raises(ConfigError, match=r"piece 1 \(constant\): n1 = 120.0 rev/s"):
        check_experiment(too_fast)
    runaway = parse_experiment({"name": "run", "area": {"size_m": [30, 30]},
                                "pieces": [{"type": "constant", "duration_s": 40, "n_rps": 90}]})
    with pytest.raises(ConfigError, match="predicted to leave its area"):
        check_experiment(runaway)
    with pytest.raises(ConfigError, match="piece 1.*unknown type"):
        parse_experiment({"name": "x", "pieces": [{"type": "wiggle", "duration_s": 1}]})
    with pytest.raises(ConfigError, match="needs 2 levels"):
        parse_experiment({"name": "x", "pieces": [{"type": "piecewise", "duration_s": 4, "segment_s": 2,
                                                   "values": {"n1_rps": [1, 2, 3]}}]})


def test_piecewise_round_trip_through_yaml_dict():
    src = {"name": "d", "pieces": [{"type": "piecewise", "duration_s": 4, "segment_s": 2,
                                    "values": {"alpha1_deg": [5, -5], "n1_rps": [30, 40], "nt_rps": [0, 20]}}]}
    exp = parse_experiment(src)
    again = parse_experiment(experiment_to_dict(exp))
    for t in (0.5, 2.5):
        assert InputGenerator(again).command(t, None) == pytest.approx(InputGenerator(exp).command(t, None))


def test_prbs_and_multisine_stay_within_base_plus_amplitude():
    exp = parse_experiment({"name": "p", "pieces": [
        {"type": "prbs", "duration_s": 10, "bit_s": 1, "base": {"n_rps": 50}, "amplitude": {"nt_rps": 30}},
        {"type": "multisine", "duration_s": 10, "f_min_hz": 0.1, "f_max_hz": 0.5, "n_freq": 5,
         "base": {"n_rps": 50}, "amplitude": {"n1_rps": 10}}]})
    g = InputGenerator(exp)
    u = np.array([g.command(t, None) for t in np.arange(0, 20, 0.05)])
    assert set(np.round(np.abs(u[:200, 4]), 6)) == {30.0}
    assert np.all(np.abs(u[200:, 2] - 50) <= 10 * 2.5) and np.std(u[200:, 2]) > 3
