"""Gusty wind: a seeded Ornstein-Uhlenbeck process on the wind speed (and direction) feeding wind_force."""

import math

import numpy as np

from lotsen.model import Environment
from lotsen.sim import SimConfig, Simulator


def _run(env, seed=3, seconds=20.0):
    sim = Simulator(config=SimConfig(seed=seed, sensors=False, environment=env))
    sim.command((0.2, 0.2, 60, 60, 0))
    winds = []
    for _ in range(int(round(seconds / sim.config.dt_s))):
        sim.step()
        winds.append(sim.wind_now)
    return sim, np.array(winds)


def test_gusts_off_by_default_leave_the_steady_wind_unchanged():
    assert not Environment().gusty
    steady = Environment(wind_speed_mps=4.0, wind_from_deg=30.0)
    a, wa = _run(steady, seed=1, seconds=5.0)
    b, _ = _run(steady, seed=2, seconds=5.0)
    assert a.x == b.x  # no randomness without gusts
    assert np.all(wa == (4.0, 30.0))


def test_gusts_are_seeded_and_change_the_motion():
    env = Environment(wind_speed_mps=4.0, wind_from_deg=30.0, wind_gust_std_mps=1.0, wind_gust_time_constant_s=2.0,
                      wind_direction_std_deg=10.0)
    a, wa = _run(env, seed=5, seconds=5.0)
    b, wb = _run(env, seed=5, seconds=5.0)
    c, wc = _run(env, seed=6, seconds=5.0)
    steady, _ = _run(Environment(wind_speed_mps=4.0, wind_from_deg=30.0), seconds=5.0)
    assert a.x == b.x and np.array_equal(wa, wb)
    assert a.x != c.x and not np.array_equal(wa, wc)
    assert a.x != steady.x


def test_gust_statistics_match_the_configuration():
    T, std = 1.0, 1.2
    env = Environment(wind_speed_mps=5.0, wind_from_deg=0.0, wind_gust_std_mps=std, wind_gust_time_constant_s=T)
    _, w = _run(env, seed=11, seconds=400.0)
    g = w[100:, 0] - 5.0  # skip the first second (the process starts at zero deviation)
    assert abs(np.std(g) / std - 1.0) < 0.15
    # lag-T autocorrelation of a first-order process: exp(-1)
    k = int(round(T / 0.01))
    rho = np.corrcoef(g[:-k], g[k:])[0, 1]
    assert abs(rho - math.exp(-1.0)) < 0.12
    assert np.all(w[:, 1] == 0.0)  # no direction wander configured
