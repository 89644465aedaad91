"""The simulated boat is its own thing: not the model, with effects the model does not have."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.messages import GnssFix
from lotsen.model import DEFAULT_PARAMETERS, VesselModel
from lotsen.runtime.config import load_config
from lotsen.sim import DEFAULT_BOAT, SimConfig, SimulatedBoat, Simulator, parameter_mismatch
from lotsen.stack.stack import simulated_boat, vessel_model

ROOT = Path(__file__).resolve().parents[2]


def test_the_default_boat_is_not_the_default_model():
    d = parameter_mismatch(DEFAULT_BOAT.parameters, DEFAULT_PARAMETERS)
    assert sum(abs(v) >= 0.10 for v in d.values()) >= 8  # 10-20 % on several coefficients
    assert max(abs(v) for v in d.values()) <= 0.25
    assert not DEFAULT_BOAT.ideal and DEFAULT_BOAT.thrust_dead_band_rps > 0 and DEFAULT_BOAT.command_latency_s > 0
    assert Simulator().model.params == DEFAULT_BOAT.parameters  # the default simulator runs the lake boat


def test_the_make_run_config_runs_the_lake_boat_on_the_default_model():
    config = load_config(ROOT / "config" / "sim.yaml")
    assert simulated_boat(config) == DEFAULT_BOAT
    assert vessel_model(config).params == DEFAULT_PARAMETERS
    assert config.vessel.gnss_antenna_m == DEFAULT_BOAT.gnss_antenna_m  # measured on the hull


def _steps_until_moving(boat: SimulatedBoat, n_rps: float, max_steps: int = 50) -> int | None:
    sim = Simulator(boat, config=SimConfig(sensors=False))
    sim.command([0.0, 0.0, n_rps, n_rps, 0.0])
    for k in range(max_steps):
        sim.step()
        if sim.actuators.state[2] != 0.0:
            return k
    return None


def test_set_points_reach_the_actuators_after_the_latency():
    assert _steps_until_moving(SimulatedBoat.ideal_for(VesselModel()), 20.0) == 0
    lag = _steps_until_moving(DEFAULT_BOAT, 20.0)
    assert lag == round(DEFAULT_BOAT.command_latency_s / 0.01)


def _surge_after(boat: SimulatedBoat, n_rps: float, seconds: float = 20.0) -> float:
    sim = Simulator(boat, config=SimConfig(sensors=False))
    sim.command([0.0, 0.0, n_rps, n_rps, 0.0])
    sim.advance(seconds)
    return sim.x[3]


def test_no_thrust_inside_the_dead_band_and_thrust_outside_it():
    band = DEFAULT_BOAT.thrust_dead_band_rps
    assert _surge_after(DEFAULT_BOAT, 0.9 * band) == 0.0
    assert _surge_after(DEFAULT_BOAT, 2.0 * band) > 0.0
    assert _surge_after(SimulatedBoat.ideal_for(VesselModel()), 0.9 * band) > 0.0  # the model has no dead band


def test_astern_thrust_is_weaker_than_ahead():
    ahead, astern = _surge_after(DEFAULT_BOAT, 40.0), _surge_after(DEFAULT_BOAT, -40.0)
    assert ahead > 0.0 > astern and abs(astern) < 0.95 * ahead
    ideal = SimulatedBoat.ideal_for(VesselModel())
    assert _surge_after(ideal, -40.0) == pytest.approx(-_surge_after(ideal, 40.0), rel=0.05)  # X_uu symmetric


def test_the_receiver_locates_the_antenna_not_the_origin():
    boat = SimulatedBoat(gnss_antenna_m=(0.3, -0.2), command_latency_s=0.0)
    sim = Simulator(boat, config=SimConfig(seed=3), x0=(0.0, 0.0, math.radians(60.0), 0.0, 0.0, 0.0))
    fixes = [m for m in sim.advance(10.0) if isinstance(m, GnssFix)]
    lat0, lon0 = sim.config.gnss.origin_lat_deg, sim.config.gnss.origin_lon_deg
    n = np.mean([(f.lat_deg - lat0) * math.pi / 180 * 6378137.0 for f in fixes])
    e = np.mean([(f.lon_deg - lon0) * math.pi / 180 * 6378137.0 * math.cos(math.radians(lat0)) for f in fixes])
    c, s = math.cos(math.radians(60.0)), math.sin(math.radians(60.0))
    assert n == pytest.approx(c * 0.3 + s * 0.2, abs=0.02) and e == pytest.approx(s * 0.3 - c * 0.2, abs=0.02)


def test_sim_boat_section_changes_the_boat_and_ideal_is_the_model(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("sim:\n  boat: {thrust_dead_band_rps: 0, parameters: {m11: 20.0}, command_latency_s: 0.1}\n")
    boat = simulated_boat(load_config(cfg))
    assert boat.parameters.m11 == 20.0 and boat.parameters.m22 == DEFAULT_BOAT.parameters.m22
    assert boat.thrust_dead_band_rps == 0.0 and boat.command_latency_s == 0.1
    cfg.write_text("sim:\n  boat: {ideal: true}\n")
    ideal = simulated_boat(load_config(cfg))
    assert ideal.ideal and ideal.parameters == DEFAULT_PARAMETERS and ideal.describe().endswith("equals the model)")


@pytest.mark.parametrize("text, message", [
    ("sim:\n  boat: {ideal: true, command_latency_s: 0.1}\n", "remove command_latency_s"),
    ("sim:\n  boat: {thrust_dead_band_rps: -1}\n", "sim.boat.thrust_dead_band_rps"),
    ("sim:\n  boat: {gnss_antenna_m: [5, 0]}\n", "more than 2 m"),
    ("sim:\n  boat: {parameters: {m11: -3}}\n", "m11"),
    ("sim:\n  boat: {dead_band: 1}\n", "unknown key"),
])
def test_bad_sim_boat_sections_are_clear_errors(tmp_path, text, message):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(text)
    with pytest.raises(ConfigError, match=message):
        simulated_boat(load_config(cfg))
