"""The sea state from the boat's IMU (lotsen.fusion.seastate), against the simulated seas' truth: on
lotsen's simulator and on the independent 6-DOF hull (its own waves and heave, which the estimator's
transfer function does not describe exactly), and published by the stack on fusion/sea_state."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

from lotsen.fusion.attitude import TiltFilter
from lotsen.fusion.seastate import SeaStateEstimator, true_frequency
from lotsen.messages import ImuSample, SeaState, Topic
from lotsen.model import Environment
from lotsen.model.environment import Waves
from lotsen.sim import SimConfig, Simulator

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "physics"))


def estimate(sim: Simulator, duration_s: float) -> SeaState:
    est, tilt = SeaStateEstimator(), TiltFilter()
    for k in range(int(round(duration_s / sim.config.dt_s))):
        for m in sim.step():
            if isinstance(m, ImuSample):
                tilt.update(m.stamp_s, m.gyro_radps, m.accel_mps2)
                est.on_imu(m, tilt.level(m.accel_mps2))
        if k % 10 == 0:
            est.on_state(sim.truth())
    return est.compute(sim.t)


def angle_error_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("hs, tp, from_deg, n_rps, heading", [
    (0.06, 1.0, 250.0, 0.0, 0.0),  # drifting: the hull turns in the waves during the window
    (0.10, 1.2, 90.0, 0.0, 0.0),
    (0.06, 1.0, 250.0, 45.0, 4.36),  # under way into the waves at ~0.6 m/s: encounter period 0.75 s
])
def test_the_imu_reads_the_sea_on_lotsens_boat(hs, tp, from_deg, n_rps, heading):
    sim = Simulator(config=SimConfig(environment=Environment(waves=Waves(hs, tp, from_deg)), seed=2),
                    x0=[0, 0, heading, 0, 0, 0])
    sim.command((0.0, 0.0, n_rps, n_rps, 0.0))
    s = estimate(sim, 100.0)
    true_hs = sim.plant.sea.significant_height_m
    assert s.valid and s.hs_m == pytest.approx(true_hs, rel=0.15)
    assert s.tp_s == pytest.approx(tp, rel=0.1)
    assert angle_error_deg(s.from_deg, from_deg) < 35.0
    if n_rps:
        assert s.tp_encounter_s < 0.85 * tp  # heading into the waves, they come faster


def test_the_imu_reads_the_sea_on_the_independent_hull():
    """The 6-DOF hull's waves and heave are its own (tests/physics/hull6dof.py): direction and period
    as on lotsen's boat, the height within 60 % (it reads high: its heave resonance amplifies waves
    of about its length, which the estimator's transfer function does not know)."""
    from hull6dof import HullEnvironment
    from hull_plant import HullPlant

    plant = HullPlant(environment=HullEnvironment(wave_hs_m=0.06, wave_tp_s=1.0, wave_from_deg=90.0, wave_spreading=10.0,
                                                  seed=2))
    sim = Simulator(plant, config=SimConfig(seed=2), x0=[0, 0, 0, 0, 0, 0])
    s = estimate(sim, 90.0)
    assert s.valid
    assert s.hs_m == pytest.approx(plant.hull.waves.realised_hs_m, rel=0.6)
    assert s.tp_s == pytest.approx(1.0, rel=0.15)
    assert angle_error_deg(s.from_deg, 90.0) < 30.0


@pytest.mark.parametrize("tp", [0.8, 1.0, 1.2])
def test_a_boat_adrift_in_the_wind_that_raised_the_sea_reads_its_period(tp):
    """Adrift, the hull lies beam-on and the 4 m/s wind and the current carry it sideways down the waves
    at ~0.15 m/s: it meets them less often. With the speed along the heading (none) the period read
    11-16 % long (1.11-1.16 s for 1.0 s, seeds 0-1); with the velocity over ground within 5 %."""
    env = Environment(current_speed_mps=0.08, current_to_deg=30.0, wind_speed_mps=4.0, wind_from_deg=250.0,
                      waves=Waves(0.06, tp, 250.0))
    sim = Simulator(config=SimConfig(environment=env, seed=0), x0=[0, 0, 0, 0, 0, 0])
    s = estimate(sim, 90.0)
    v = sim.truth()
    assert math.hypot(v.u_mps, v.v_mps) > 0.08 and abs(v.v_mps) > abs(v.u_mps)  # adrift, sideways
    assert s.valid and s.tp_s == pytest.approx(tp, rel=0.07)


def test_a_boat_that_drifts_runs_and_turns_into_following_seas_reads_one_sea():
    """The live test's first minute (tests/stack/test_live_waves.py): 15 s adrift, 25 s north at ~0.5 m/s,
    then 60 deg, with the waves (from 250 deg) running along the bow. Each Welch segment is mapped from
    encounter to true frequencies at its own speed along the waves: one speed for the window (the boat's
    now) read this sea as Hs 8-12 cm, Tp 0.6-0.75 s once the boat ran with the waves."""
    from lotsen.model.angles import wrap_angle

    env = Environment(current_speed_mps=0.08, current_to_deg=30.0, wind_speed_mps=4.0, wind_from_deg=250.0,
                      waves=Waves(0.06, 1.0, 250.0))
    sim = Simulator(config=SimConfig(environment=env, seed=0), x0=[4, 20, 0, 0, 0, 0])
    est, tilt = SeaStateEstimator(), TiltFilter()
    readings = []
    for k in range(7500):
        s = sim.truth()
        if k % 10 == 0:
            target = 0.0 if sim.t < 40.0 else math.radians(60.0)
            alpha = max(-0.5, min(0.5, -1.5 * wrap_angle(target - s.heading_rad)))
            sim.command((0, 0, 0, 0, 0) if sim.t < 15.0 else (alpha, alpha, 40.0, 40.0, 0.0))
            est.on_state(s)
        for m in sim.step():
            if isinstance(m, ImuSample):
                tilt.update(m.stamp_s, m.gyro_radps, m.accel_mps2)
                est.on_imu(m, tilt.level(m.accel_mps2))
        if k >= 4500 and k % 500 == 0:  # under way with the waves, 45-75 s
            assert math.degrees(abs(wrap_angle(s.heading_rad - math.radians(70.0)))) < 35.0
            readings.append(est.compute(sim.t))
    true_hs = sim.plant.sea.significant_height_m
    for r in readings:
        assert r.valid and r.hs_m == pytest.approx(true_hs, rel=0.25), r
        assert r.tp_s == pytest.approx(1.0, rel=0.2), r
        assert angle_error_deg(r.from_deg, 250.0) < 20.0, r


def test_flat_water_reads_flat_and_too_little_data_is_not_an_estimate():
    sim = Simulator(config=SimConfig(seed=1), x0=[0, 0, 0, 0, 0, 0])
    sim.command((0.1, 0.1, 45.0, 45.0, 0.0))
    s = estimate(sim, 60.0)
    assert s.valid and s.hs_m == 0.0 and math.isnan(s.from_deg)
    short = estimate(Simulator(config=SimConfig(seed=1), x0=[0, 0, 0, 0, 0, 0]), 10.0)
    assert not short.valid and math.isnan(short.hs_m)


def test_encounter_frequency_back_to_the_waves_own():
    w, U = 2 * math.pi, 0.5
    k = w * w / 9.81
    assert true_frequency(w + k * U, -U) == pytest.approx(w)  # head seas
    # following seas slower than the waves' group speed (g / 2w = 0.78 m/s here): the smaller root
    assert true_frequency(w - k * U, U) == pytest.approx(w)
    assert true_frequency(w, 0.0) == w


def test_the_stack_publishes_the_sea_state():
    """The fusion node feeds the IMU to the estimator and publishes on fusion/sea_state."""
    from lotsen.runtime.config import EnvironmentConfig, LaunchConfig, SimSection, WavesConfig, WebSection
    from lotsen.stack.launch import build_stack

    env = EnvironmentConfig(waves=WavesConfig(hs_m=0.06, tp_s=1.0, from_deg=250.0))
    cfg = LaunchConfig(sim=SimSection(environment=env), web=WebSection(enabled=False))
    stack = build_stack(cfg, realtime=False, parts=("state",))
    seen: list[SeaState] = []
    stack.bus.subscribe(Topic.SEA_STATE, seen.append)
    stack.executor.run_until(70.0)
    valid = [s for s in seen if s.valid]
    assert valid and 0.04 < valid[-1].hs_m < 0.08
