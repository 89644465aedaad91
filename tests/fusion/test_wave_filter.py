"""The EKF's wave filter in a sea (issue 46): what the controllers get is the low-frequency motion.

lotsen's simulator (the lake boat, not the default model the EKF runs) in Hs 6 cm, Tp 1.0 s, open loop
in a steady turn, the EKF fed as the fusion node feeds it (the wave model at the encounter frequency
the running sea-state estimate gives)."""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from lotsen.fusion.common import feed
from lotsen.fusion.ekf import EkfConfig, ModelAidedEKF
from lotsen.fusion.seastate import SeaStateEstimator
from lotsen.harness.mission import sim_mag_calibration
from lotsen.messages import GnssFix, ImuSample, VesselState
from lotsen.model import Environment, VesselModel
from lotsen.model.environment import Waves
from lotsen.sim import SimConfig, Simulator


def _turn(wave_mean_periods: float, hs_m: float, duration_s: float = 60.0) -> np.ndarray:
    """Rows (t, true yaw rate, the estimate's yaw rate) at 10 Hz of a steady port turn, azimuths at
    -4 deg and 45 rev/s (about 0.5 m/s and 8 deg/s), waves from 250 deg."""
    return _fly_turn(hs_m, duration_s, wave_mean_periods=wave_mean_periods)[0]


def _fly_turn(hs_m: float, duration_s: float, gnss_gap_s: tuple[float, float] | None = None,
              **ekf_config: Any) -> tuple[np.ndarray, ModelAidedEKF]:
    """_turn's rows, with the filter's body-force states (X, Y, N) after them, and the EKF (its EkfConfig with
    `ekf_config`) at the end; no GNSS fix reaches the filter within `gnss_gap_s`."""
    sim = Simulator(config=SimConfig(environment=Environment(waves=Waves(hs_m, 1.0, 250.0) if hs_m else None), seed=3))
    gnss = sim.config.gnss
    ekf = ModelAidedEKF(VesselModel(), sim_mag_calibration(sim.config),
                        EkfConfig(origin=(gnss.origin_lat_deg, gnss.origin_lon_deg, gnss.origin_height_m),
                                  gnss_antenna_m=sim.boat.gnss_antenna_m, **ekf_config),
                        initial=VesselState(stamp_s=0.0, north_m=0.0, east_m=0.0, heading_rad=sim.x[2],
                                            u_mps=0.0, v_mps=0.0, r_radps=0.0))
    sea = SeaStateEstimator()
    alpha = math.radians(-4.0)
    rows = []
    for k in range(int(round(duration_s / sim.config.dt_s))):
        t = sim.t
        sim.command((alpha, alpha, 45.0, 45.0, 0.0))
        r_true = sim.x[5]
        msgs = sim.step()
        if k % 5 == 0:
            act = sim.actuator_state()
            act.stamp_s = t
            ekf.on_command(act)
        for m in msgs:
            if gnss_gap_s and isinstance(m, GnssFix) and gnss_gap_s[0] <= m.stamp_s < gnss_gap_s[1]:
                continue
            feed(ekf, m)
            if isinstance(m, ImuSample):
                sea.on_imu(m)
        if k % 10 == 0:
            est = ekf.estimate(t)
            sea.on_state(est)
            sea.estimate(t)
            ekf.set_wave_frequency(sea.encounter_frequency_radps())
            force = ekf.x[ekf.i_tau:ekf.i_tau + 3] if ekf.i_tau is not None else np.zeros(3)
            rows.append((t, r_true, est.r_radps, *force))
    return np.array(rows), ekf


def _slow_rate_error_deg_s(rows: np.ndarray) -> np.ndarray:
    """The yaw-rate error's 15-s means after the first 30 s (the sea-state estimate's start)."""
    late = rows[rows[:, 0] >= 30.0]
    n = len(late) // 150 * 150
    return np.degrees(late[:n, 2] - late[:n, 1]).reshape(-1, 150).mean(axis=1)


@pytest.mark.parametrize("hs_m", [0.06])
def test_slow_yaw_parked_in_the_wave_state_reaches_the_controllers(hs_m):
    """The gyro measures r + the wave state's yaw rate; in a sea the tightened yaw model sends the
    difference between its own turn rate and the hull's to the wave state, where it is no wave. The
    estimate the controllers get takes the wave states' slow part back (EkfConfig.wave_mean_periods):
    its yaw rate is right within 0.4 deg/s in every 15 s; without that, 1-2 deg/s off (the control case:
    this test fails when the wave states' mean is not returned)."""
    with_mean = _slow_rate_error_deg_s(_turn(EkfConfig().wave_mean_periods, hs_m))
    without = _slow_rate_error_deg_s(_turn(0.0, hs_m))
    assert np.max(np.abs(with_mean)) < 0.4, with_mean
    assert np.max(np.abs(without)) > 1.0, without


def test_flat_water_estimate_is_unchanged_by_the_wave_mean():
    """In flat water (no sea state, so no encounter frequency) nothing is returned: the estimate is
    the one without it, to the bit."""
    a, b = _turn(EkfConfig().wave_mean_periods, 0.0, 40.0), _turn(0.0, 0.0, 40.0)
    assert np.array_equal(a, b)


def _velocity_step_from_one_accelerometer_mean(ekf: ModelAidedEKF, correlated_samples: float) -> float:
    """How far one accelerometer mean 0.3 m/s^2 above the filter's own prediction (surge) moves its
    velocity (u, v, r; m/s and rad/s), with `wave_accel_correlated_samples` set to the value given (on
    copies of the filter)."""
    velocities = []
    for extra in (0.0, 0.3):  # the difference is the gain's: the rest of the innovation is the same in both
        probe = copy.deepcopy(ekf)
        probe.config = dataclasses.replace(ekf.config, wave_accel_correlated_samples=correlated_samples)
        ax, ay = probe._accel_pred
        if probe.i_ba is not None:
            ax, ay = ax + float(probe.x[probe.i_ba]), ay + float(probe.x[probe.i_ba + 1])
        probe._accel_update((ax + extra, ay))
        velocities.append(probe.x[3:6].copy())
    return float(np.linalg.norm(velocities[1] - velocities[0]))


@pytest.mark.parametrize("hs_m", [0.0, 0.06])
def test_one_waves_acceleration_is_not_taken_for_many_independent_samples(hs_m):
    """In a sea the accelerometer's wave-frequency acceleration is narrow-band noise that lasts a few
    tenths of a second, over several of its 20 Hz means: the update counts its variance that many times
    (EkfConfig.wave_accel_correlated_samples), so one mean's pull on the velocity is a fraction of the
    white-noise update's. In flat water (no sea state) the update is the white-noise one, to the bit."""
    _, ekf = _fly_turn(hs_m, 45.0)
    white = _velocity_step_from_one_accelerometer_mean(ekf, 1.0)
    coloured = _velocity_step_from_one_accelerometer_mean(ekf, EkfConfig().wave_accel_correlated_samples)
    assert white > 0.0
    if hs_m:
        assert ekf.wave_band.heave_accel_std_mps2 > 0.1  # the sea is there, and the sea state has found it
        assert coloured < 0.35 * white, (coloured, white)
    else:
        assert coloured == white


def test_in_flat_water_the_force_states_sleep_and_the_estimate_is_the_one_without_them():
    """EkfConfig.wave_disturbance_states: the body force's states are there, but in flat water they
    neither walk nor learn: the force stays exactly zero and the estimate is the one without the states
    (to round-off: the filter's matrices are three rows wider)."""
    a, ekf = _fly_turn(0.0, 30.0)
    b, _ = _fly_turn(0.0, 30.0, wave_disturbance_states=False)
    assert ekf.i_tau is not None
    assert np.all(a[:, 3:] == 0.0)
    np.testing.assert_allclose(a[:, :3], b[:, :3], rtol=0.0, atol=1e-9)


def test_in_a_sea_the_force_states_learn_while_gnss_vouches_and_hold_in_dead_reckoning():
    """In a sea the body force walks and takes up what the model lacks there (the waves' mean drift,
    which a current cannot stand for: it turns with the hull's heading to the waves). Without GNSS the
    accelerometer alone cannot part a force from its own bias and the waves': from
    EkfConfig.force_learning_gnss_age_s after the last fix the force is held, to the bit (the control
    case, learning on without GNSS, moves it)."""
    rows, ekf = _fly_turn(0.06, 60.0, gnss_gap_s=(45.0, 60.0))
    assert ekf.wave_band.heave_accel_std_mps2 > EkfConfig().wave_accel_sea_heave_mps2
    before = rows[rows[:, 0] < 45.0]
    assert np.max(np.abs(before[-1, 3:5])) > 0.1, before[-1]  # newtons learnt in the sea
    held = rows[rows[:, 0] >= 45.0 + EkfConfig().force_learning_gnss_age_s + 0.1, 3:]
    assert np.all(held == held[0]), held[[0, -1]]
    unheld = _fly_turn(0.06, 60.0, gnss_gap_s=(45.0, 60.0), force_learning_gnss_age_s=math.inf)[0]
    moved = unheld[unheld[:, 0] >= 46.1, 3:]
    assert np.max(np.abs(moved[-1] - moved[0])) > 0.05, moved[[0, -1]]
    # the filter's own: the state it reports carries no force (only `disturbance_states` reports one)
    assert ekf.estimate(ekf.t).disturbance_tau == (0.0, 0.0, 0.0)
