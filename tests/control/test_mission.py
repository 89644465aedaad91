"""The closed-loop mission harness (lotsen.harness.mission) and the `lotsen mission` command."""

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from lotsen.cli import mission as mission_cli
from lotsen.control import ControlConfig, make_path_follower
from lotsen.errors import ConfigError, LotsenError
from lotsen.model import Environment
from lotsen.planning import plan_route
from lotsen.planning.io import load_route
from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission

from .conftest import straight_path

ROUTE = """harbour: {north: 0.0, east: 0.0, heading_deg: 0.0}
nodes:
  - {north: 8.0, east: 2.0, heading_deg: 30.0, speed_mps: 0.5}
  - {north: 14.0, east: 6.0, heading_deg: 60.0, speed_mps: 0.3}
area: [[-5, -5], [25, -5], [25, 20], [-5, 20]]
"""


def _parse(argv):
    p = argparse.ArgumentParser()
    mission_cli.register(p.add_subparsers())
    return p.parse_args(argv)


def test_mission_command_writes_report_and_plot(tmp_path):
    route = tmp_path / "route.yaml"
    route.write_text(ROUTE)
    report, plot = tmp_path / "report.json", tmp_path / "mission.png"
    args = _parse(["mission", str(route), "--sim", "--current", "0.1,90", "--wind", "3,45", "--hold", "3",
                   "--report", str(report), "--plot", str(plot)])
    assert args.func(args) == 0
    r = json.loads(report.read_text())
    for key in ("completed", "duration_s", "cross_track_rms_m", "cross_track_max_m", "heading_error_rms_deg",
                "speed_error_rms_mps", "solve_time_median_ms", "solve_time_max_ms"):
        assert key in r
    assert r["completed"] is True
    assert r["cross_track_rms_m"] < 0.05
    assert plot.stat().st_size > 10_000


def test_the_harbour_approach_in_a_beam_current_of_0_3_mps_completes(tmp_path):
    """`lotsen mission` as an operator runs it (EKF, lake boat): the harbour approach in a 0.3 m/s
    current setting east, across its first leg and its loop. Without the MPC's crab alignment the boat
    stalled on the southbound leg and was swept 5 m off the route at 82-106 s (seeds 0-2); with it the
    route completes with no failsafe (not even `no_progress`)."""
    route = Path(__file__).resolve().parents[2] / "examples" / "routes" / "harbour_approach.yaml"
    report = tmp_path / "report.json"
    args = _parse(["mission", str(route), "--sim", "--current", "0.3,90", "--seed", "0", "--report", str(report)])
    assert args.func(args) == 0
    r = json.loads(report.read_text())
    assert r["completed"] is True and r["failsafes_triggered"] == [], (r["reason"], r["failsafes_triggered"])
    assert r["cross_track_max_m"] < 1.0 and r["cross_track_rms_m"] < 0.1


@pytest.mark.parametrize("argv,match", [
    (["--current", "0.1"], "SPEED,DIR_DEG"),
    (["--wind", "fast,90"], "SPEED,DIR_DEG"),
    (["--current=-1,0"], "speed"),
])
def test_bad_options_are_reported(tmp_path, argv, match):
    route = tmp_path / "route.yaml"
    route.write_text(ROUTE)
    args = _parse(["mission", str(route), "--sim", "--report", str(tmp_path / "r.json"), *argv])
    with pytest.raises(ConfigError, match=match):
        args.func(args)


def test_mission_without_sim_is_refused(tmp_path):
    args = _parse(["mission", "x.yaml", "--report", str(tmp_path / "r.json")])
    with pytest.raises(LotsenError, match="--sim"):
        args.func(args)


def test_a_bare_route_name_is_the_example_route_of_that_name(tmp_path, monkeypatch):
    """`lotsen mission figure_eight ...` from any folder (the README's walkthrough); a file of that
    name, or any path with a suffix or a folder, is taken as given."""
    from lotsen.stack.stack import example_route

    monkeypatch.chdir(tmp_path)
    assert mission_cli.route_file("figure_eight") == example_route("figure_eight")
    assert mission_cli.route_file("mine.yaml") == "mine.yaml"  # load_route reports a missing file
    assert mission_cli.route_file("routes/figure_eight") == "routes/figure_eight"
    (tmp_path / "figure_eight").write_text(ROUTE)
    assert mission_cli.route_file("figure_eight") == "figure_eight"
    with pytest.raises(ConfigError, match=r"'figure_nine': no such file, nor an example route .*figure_eight"):
        mission_cli.route_file("figure_nine")


@pytest.mark.parametrize("controller", ["pursuit", "los", "lq"])
def test_run_mission_with_each_fallback(controller):
    path = straight_path(10.0)
    res = run_mission(path, make_path_follower(ControlConfig(controller=controller)),
                      MissionConfig(hold_s=3.0, environment=Environment(current_speed_mps=0.05, current_to_deg=90)))
    assert res.completed, res.reason
    assert res.metrics["cross_track_max_m"] < 0.3  # harness test; tracking quality is in the bench
    assert set(res.mode) == {"follow", "hold"}


def test_mission_on_the_fusion_estimate():
    """The switch to the estimator: the controller runs on the EKF, errors are measured on the truth."""
    path = straight_path(8.0)
    cfg = MissionConfig(hold_s=1.0, sensors=True)
    res = run_mission(path, make_path_follower(ControlConfig()), cfg, estimator=make_sim_ekf(cfg, path))
    assert res.completed, res.reason
    assert "estimate_position_error_rms_m" in res.metrics
    assert res.metrics["estimate_position_error_rms_m"] < 0.1
    assert res.metrics["cross_track_rms_m"] < 0.05
    assert res.cross_track_estimated_m is not None


FIGURE_EIGHT_LOOP = Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight_loop.yaml"
DISTURBED = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)


@pytest.mark.parametrize("seed", [1, 2])
def test_auto_on_the_ekf_in_current_and_wind_triggers_no_failsafe(seed):
    """Issue 14 item 3, test-sized (the 10 runs x 10 min bar is in bench/bench_control.py): AUTO on the
    figure eight with current, wind and the EKF in the loop stays in AUTO without any failsafe, and
    the achieved propeller speeds change sign at most 0.1 times per second, all three together
    (without a reversal guard ~1.3 per second)."""
    path = plan_route(load_route(FIGURE_EIGHT_LOOP))
    cfg = MissionConfig(environment=DISTURBED, seed=seed, sensors=True, max_duration_s=90.0)
    follower = make_path_follower(ControlConfig())
    res = run_mission(path, follower, cfg, estimator=make_sim_ekf(cfg, path))
    assert res.reason == "timeout", res.reason  # still following the route when the time is up
    assert res.metrics["failsafes_triggered"] == []
    assert set(res.mode) == {"follow"}
    assert res.metrics["reversals_counted_on"] == "achieved speeds"
    assert res.metrics["reversals_per_s"] <= 0.1
    assert res.metrics["cross_track_max_m"] < 0.15


def test_issue_19_done_when_figure_eight_on_the_ekf_in_current_and_wind(tmp_path):
    """Issue 19's "done when", as the operator types it: `lotsen mission figure_eight.yaml --sim
    --current 0.1,90 --wind 3,45 --report r.json` (EKF by default) tracks within 1.5 cm RMS and holds
    the end point within the issue's 5 cm after the 10 s hold. On the lake boat (the default simulated
    boat, not the model) seeds 0-2 give 0.69-0.75 cm and 1.8-2.6 cm after 10 s with the 1.0 rad/s
    station-keeping loop (4.3-5.4 cm with the 0.6 rad/s loop before 2026-11-27: it overshot the end
    point by 13-17 cm when HOLD took over the arriving boat)."""
    route = Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight.yaml"
    report = tmp_path / "r.json"
    args = _parse(["mission", str(route), "--sim", "--current", "0.1,90", "--wind", "3,45",
                   "--report", str(report)])
    assert args.func(args) == 0
    r = json.loads(report.read_text())
    assert r["estimator"] == "ekf" and r["completed"]
    assert r["cross_track_rms_m"] <= 0.015, r
    assert r["hold_position_error_final_m"] <= 0.05, r


def test_actuator_activity_splits_the_energy_by_propeller_and_counts_an_azimuth_astern():
    """The report's per-propeller energy adds up to its total (each motor draws its own power), and
    an azimuth held astern against the other (the couple that wastes a mission's energy) shows in the
    azimuths' astern share."""
    from lotsen.sim.activity import actuator_activity

    t = np.arange(0.0, 10.0, 0.1)
    a = np.zeros((len(t), 5))
    a[:, 2] = 60.0                      # azimuth 1 ahead the whole time
    a[:, 3] = np.where(t < 4.0, -50.0, 30.0)  # azimuth 2 astern for the first 4 s (rows t < 4.0)
    a[:, 4] = 20.0 * np.sin(t)          # the bow thruster both ways
    m = actuator_activity(t, a)
    assert np.isclose(sum(m["energy_J_by_propeller"]), m["energy_J"], rtol=1e-3)
    assert m["energy_J_by_propeller"][0] > m["energy_J_by_propeller"][1] > 0.0
    assert m["azimuth_astern_share"] == [0.0, 0.4]
