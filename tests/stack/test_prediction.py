"""A mission's time and energy predicted before the boat leaves (lotsen.stack.prediction): on a boat
equal to the model the prediction is the flight (the same controller, the same energy measure), and
it answers to the current and wind it is given. A small survey (3 lines of 6 m), a few seconds."""

from __future__ import annotations

import math

import pytest

from lotsen.control import ControlConfig, make_path_follower
from lotsen.harness.mission import MissionConfig, run_mission
from lotsen.model import VesselModel
from lotsen.planning import plan_route
from lotsen.planning.io import route_from_dict
from lotsen.planning.survey.keeping import line_spans
from lotsen.stack.prediction import compare_with_flown, predict_mission


@pytest.fixture(scope="module")
def survey():
    route = route_from_dict({"harbour": {"north": -3.0, "east": -3.0, "heading_deg": 0.0},
                             "area": [[-10, -10], [16, -10], [16, 14], [-10, 14]],
                             "survey": {"polygon": [[0, 0], [6, 0], [6, 6], [0, 6]], "spacing_m": 2.0,
                                        "speed_mps": 0.6, "turnaround_m": 1.0}})
    path = plan_route(route)
    return path, line_spans(route, path)


def test_on_a_boat_equal_to_the_model_the_prediction_is_the_flight(survey):
    """Calm water ("ideal model"): the mission on the stack (supervisor, actuator guard, truth as the
    state) and the prediction on the truth (estimator="truth") fly the same controller on the same boat,
    so time, energy and time on lines agree to the tick (measured 0.0 % and 0.06 %). In a current they do
    not: the truth carries no current, so the flight's controller learns it through its disturbance
    observer where the prediction's is given it as the estimate carries it (+50 % energy, the bow
    thruster working against the drift; the 16 x 12 m survey in 0.1 m/s: 11.1 kJ against 9.7, and 9.73
    with the current given to the truth, 2026-11-29)."""
    path, spans = survey
    model = VesselModel()
    p = predict_mission(path, model, survey_lines=spans, estimator="truth")
    assert p.reached_end and 0.9 < p.duration_s / p.planned_duration_s < 1.1
    res = run_mission(path, make_path_follower(ControlConfig(), model), MissionConfig(hold_s=0.5),
                      model=model, sim_model=model, survey_lines=spans)
    assert res.completed
    cmp = compare_with_flown(p, res.metrics["duration_s"], res.metrics["energy_J"])
    assert abs(cmp["duration_error"]) < 0.01 and abs(cmp["energy_error"]) < 0.01, cmp
    assert p.time_on_lines_s == pytest.approx(res.metrics["survey"]["time_on_lines_s"], abs=1.0)


def test_the_prediction_answers_to_the_current_and_the_wind(survey):
    path, spans = survey
    calm = predict_mission(path, survey_lines=spans)
    windy = predict_mission(path, current_ne_mps=(0.0, 0.2), wind_mps=6.0, wind_from_deg=90.0, survey_lines=spans)
    assert windy.energy_J > 1.1 * calm.energy_J
    assert calm.current_ne_mps == (0.0, 0.0) and windy.wind_mps == 6.0
    assert math.isclose(calm.mean_power_W * calm.duration_s, calm.energy_J, rel_tol=1e-9)


def test_the_prediction_flies_in_the_sea_it_is_given(survey):
    """A wind sea (`lotsen mission --waves`, the estimator's sea state) costs energy: the prediction flies in
    it (measured 2026-11-28 on this survey at 0.6 m/s: Hs 5 cm, Tp 0.9 s, 2.5 x the energy of flat water)."""
    from lotsen.model.environment import Waves

    path, spans = survey
    calm = predict_mission(path, survey_lines=spans)
    sea = predict_mission(path, survey_lines=spans, waves=Waves(0.05, 0.9, 45.0))
    assert sea.reached_end and sea.waves is not None and calm.waves is None
    assert sea.energy_J > 1.5 * calm.energy_J, (sea.energy_J, calm.energy_J)
    assert sea.as_dict()["waves"] == {"hs_m": 0.05, "tp_s": 0.9, "from_deg": 45.0}
    flat = predict_mission(path, survey_lines=spans, waves=Waves(0.0, 0.9, 45.0))   # Hs 0: flat water
    assert flat.waves is None and flat.energy_J == pytest.approx(calm.energy_J)


def test_the_prediction_flies_with_the_estimators_error(survey):
    """The flown energy on the EKF is above the flight on the truth: the MPC answers the estimate's error
    (position, heading, velocities) with the bow thruster and an azimuth astern. The prediction flies
    with that error (`EstimateNoise`, the default: three draws) and comes within 10 % of the mean of the
    flights on the EKF on a boat equal to the model; on the truth it is a quarter short. Measured
    2026-11-29 on this survey in 0.1 m/s current and 3 m/s wind: flown on the EKF 5106 / 4789 / 4393 J
    (seeds 0-2, mean 4763), predicted with the error 4347 J (-8.7 %; with the EKF itself in the
    prediction's loop, tried, 3 seeds: 4716 J), on the truth 3505 J (-26 %)."""
    from lotsen.harness.mission import make_sim_ekf
    from lotsen.model import Environment
    from lotsen.sim import SimulatedBoat

    path, spans = survey
    model = VesselModel()
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    kw = dict(current_ne_mps=(0.0, 0.1), wind_mps=3.0, wind_from_deg=45.0, survey_lines=spans)
    noisy = predict_mission(path, model, **kw)
    truth = predict_mission(path, model, estimator="truth", **kw)
    flown = []
    for seed in (0, 1, 2):
        cfg = MissionConfig(environment=env, seed=seed, sensors=True, hold_s=0.5)
        res = run_mission(path, make_path_follower(ControlConfig(), model), cfg, model=model, sim_model=model,
                          estimator=make_sim_ekf(cfg, path, model, boat=SimulatedBoat.ideal_for(model)))
        assert res.completed
        flown.append(res.metrics["energy_J"])
    mean = sum(flown) / len(flown)
    assert noisy.draws == 3 and noisy.energy_range_J[0] <= noisy.energy_J <= noisy.energy_range_J[1]
    assert abs(noisy.energy_J - mean) / mean < 0.10, (noisy.energy_J, flown)
    assert truth.energy_J < 0.8 * mean, (truth.energy_J, flown)   # the cause: without the error, a quarter short
    assert abs(noisy.duration_s - truth.duration_s) / truth.duration_s < 0.02


def test_lotsen_plan_predicts_an_example_route_by_name_from_any_folder(tmp_path):
    """The operator's way in: `lotsen plan NAME --predict` from a folder without the examples, as `lotsen
    mission NAME` is; the line says the energy and its spread over the flights on the estimate's error."""
    import re
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "lotsen", "plan", "figure_eight", "--out", "path.json", "--predict",
                          "--current", "0.1,90", "--wind", "3,45"], capture_output=True, text=True, timeout=300,
                         cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    m = re.search(r"predicted: (\d+) s .*?, ([\d.]+) Wh \(([\d.]+)-([\d.]+) over 3 flights on the estimate's error\)",
                  res.stdout)
    assert m, res.stdout
    low, mid, high = float(m.group(3)), float(m.group(2)), float(m.group(4))
    assert int(m.group(1)) > 0 and 0.0 < low <= mid <= high, res.stdout
    assert "current 0.10 m/s, wind 3 m/s" in res.stdout and (tmp_path / "path.json").is_file()
    bad = subprocess.run([sys.executable, "-m", "lotsen", "plan", "no_such_route", "--out", "p.json"],
                         capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert bad.returncode != 0 and "no such file, nor an example route" in bad.stderr and "figure_eight" in bad.stderr
