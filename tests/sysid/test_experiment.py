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


def _fly(exp, model, keeper=None, max_s=600.0, dt_s=0.05):
    """The experiment flown on `model` (set-points at once), with the keeper's returns as the
    stack's ExperimentNode applies them: the signal's time pauses while the boat is brought back."""
    from lotsen.model import rk4_step

    gen = InputGenerator(exp)
    x, t, track, returning = (0.0, 0.0, exp.start_heading_rad, exp.start_speed_mps, 0.0, 0.0), 0.0, [], []
    while t < max_s:
        back = keeper.update(t, x[0], x[1], x[2], x[3], x[4]) if keeper is not None else None
        signal_s = t - (keeper.paused_s if keeper is not None else 0.0)
        if signal_s >= exp.duration_s:
            break
        u = back if back is not None else gen.command(signal_s, x)
        x, _ = rk4_step(x, u, model.arrays.packed, 0.0, 0.0, 0.0, 0.0, 0.0, dt_s)
        t += dt_s
        track.append(x)
        returning.append(back is not None)
    return np.array(track), np.array(returning), t


def test_a_boat_about_to_leave_the_area_is_brought_back_and_the_signal_resumes():
    """A straight run of 90 s at ~0.6 m/s in a 20 x 20 m area: without the keeper the boat leaves
    after ~15 s; with it the boat turns back before the edge (several times), every second of the
    signal is flown, and the returns' time is what the run took longer."""
    from lotsen.sysid.experiment import AreaKeeper

    exp = parse_experiment({"name": "straight", "area": {"size_m": [20, 20]},
                            "pieces": [{"type": "constant", "duration_s": 90, "n_rps": 40}]})
    model = VesselModel()
    free, _, _ = _fly(exp, model)
    assert np.max(np.abs(free[:, :2])) > 30.0  # it would leave
    keeper = AreaKeeper(exp.area)
    track, returning, t_end = _fly(exp, model, keeper)
    assert keeper.returns >= 2 and not keeper.returning
    assert all(exp.area.contains(n, e) for n, e in track[:, :2])  # never outside
    assert t_end == pytest.approx(90.0 + keeper.paused_s, abs=0.06)  # the whole signal, after the returns
    assert returning.sum() * 0.05 == pytest.approx(keeper.paused_s, abs=0.06)
    assert not keeper.overdue(t_end)


def test_a_boat_equal_to_its_model_never_returns_on_a_checked_design():
    """Every example experiment passes its check on the model (its predicted track inside the area):
    flown on that model, none of them triggers a return."""
    from pathlib import Path

    from lotsen.sysid.experiment import AreaKeeper

    model = VesselModel()
    for f in sorted(Path(__file__).parents[2].joinpath("examples", "experiments").glob("*.yaml")):
        exp = load_experiment(f)
        keeper = AreaKeeper(exp.area)
        _fly(exp, model, keeper)
        assert keeper.returns == 0, f.name


def test_the_return_turns_the_bow_towards_the_centre_and_a_stuck_return_is_overdue():
    from lotsen.sysid.experiment import Area, AreaKeeper, ReturnConfig

    keeper = AreaKeeper(Area.centred(20, 20), ReturnConfig(max_return_s=10.0))
    # east of the centre, heading east at 0.6 m/s, 1 m from the edge: the centre is to the west
    back = keeper.update(0.0, 0.0, 9.0, math.pi / 2, 0.6, 0.0)
    assert back is not None and keeper.returns == 1
    # the centre is behind: either way round; north of it heading east, it lies to starboard
    back = keeper.update(0.1, 0.0, 9.0, math.pi / 2 - 0.5, 0.6, 0.0)  # heading a little north of east
    assert back[0] > 0 and back[1] > 0 and back[4] < 0  # bow to port (alpha > 0, nt < 0): the short way
    assert not keeper.overdue(5.0) and keeper.overdue(10.2)
    assert keeper.failure(5.0, 60.0) == "" and "within 10 s" in keeper.failure(10.2, 60.0)
    back = keeper.update(10.3, 0.0, 1.0, -math.pi / 2, 0.5, 0.0)  # central, heading for the centre: back
    assert back is None and not keeper.returning and keeper.paused_s == pytest.approx(10.3)
    assert keeper.failure(189.0, 60.0) == ""  # within 3 x 60 s + 10 s
    assert keeper.failure(190.1, 60.0) == "the returns to the area took 10 s of the run"
    with pytest.raises(ConfigError, match="resume_fraction"):
        ReturnConfig(resume_fraction=1.0)
