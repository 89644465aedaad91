"""Wind waves on lotsen's simulated boat (lotsen.sim.waves): properties the physics must have."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lotsen.model import Environment
from lotsen.model.environment import Waves
from lotsen.sim import BoatPlant, SimConfig, Simulator
from lotsen.sim.waves import LOADS, HullForm, WaveField, jonswap

HULL = HullForm()


def field(waves: Waves, seed: int = 1, n: int = 64) -> WaveField:
    return WaveField(waves, HULL, np.random.default_rng(seed), n)


def loads_series(f: WaveField, duration_s: float, u_mps: float = 0.0, psi: float = 0.0, dt: float = 0.02) -> np.ndarray:
    """The loads on a hull moving north-east at u_mps on heading psi, rows per LOADS."""
    out = np.empty(len(LOADS))
    rows = []
    for t in np.arange(0.0, duration_s, dt):
        rows.append(f.loads(t, u_mps * t * math.cos(psi), u_mps * t * math.sin(psi), psi, 14.0, 24.0, out).copy())
    return np.array(rows)


def peak_frequency(x: np.ndarray, dt: float) -> float:
    spec = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(len(x)))) ** 2
    freqs = 2.0 * math.pi * np.fft.rfftfreq(len(x), dt)
    smooth = np.convolve(spec, np.ones(15) / 15.0, mode="same")
    return float(freqs[int(np.argmax(smooth))])


def test_jonswap_holds_the_sea_state_energy():
    wp = 2 * math.pi / 1.0
    w = np.linspace(0.2 * wp, 10 * wp, 20000)
    s = jonswap(w, 0.06, 1.0)
    assert 4.0 * math.sqrt(np.trapezoid(s, w)) == pytest.approx(0.06, rel=1e-3)
    assert w[np.argmax(s)] == pytest.approx(wp, rel=0.01)


@pytest.mark.parametrize("hs, tp", [(0.03, 0.8), (0.06, 1.0), (0.10, 1.2)])
def test_the_realised_sea_has_the_asked_significant_height(hs, tp):
    f = field(Waves(hs, tp, 250.0))
    assert f.significant_height_m == pytest.approx(hs, rel=0.05)  # the band 0.6-3 wp holds ~97 % of m0
    t = np.arange(0.0, 900.0, 0.05)
    elevation = np.array([f.elevation(ti, 3.0, -2.0) for ti in t])
    assert 4.0 * elevation.std() == pytest.approx(hs, rel=0.10)
    assert peak_frequency(elevation, 0.05) == pytest.approx(2 * math.pi / tp, rel=0.15)


def test_long_crested_head_seas_push_a_symmetric_hull_neither_sideways_nor_round():
    """Waves from dead ahead on a hull symmetric about its centreline: sway, yaw and roll loads are zero."""
    f = field(Waves(0.06, 1.0, from_deg=0.0, spreading=0.0))
    r = loads_series(f, 60.0, psi=0.0)
    assert np.max(np.abs(r[:, [1, 2, 4, 5, 8]])) < 1e-9
    assert r[:, 0].std() > 0.3  # surge is excited
    assert r[:, 7].std() > math.radians(0.3)  # and pitch


def test_mean_drift_pushes_along_the_waves_travel_and_grows_with_the_square_of_their_height():
    drift = {}
    for hs in (0.03, 0.06):
        f = field(Waves(hs, 1.0, from_deg=270.0, spreading=0.0))  # from the west, travelling east
        psi = 0.0  # bow north: a beam sea from port
        d = f.loads(0.0, 0.0, 0.0, psi, 14.0, 24.0)[3:6]
        drift[hs] = d
        assert d[1] > 0.0 and abs(d[0]) < 0.2 * d[1]  # to starboard = east, the waves' travel
    assert drift[0.06][1] / drift[0.03][1] == pytest.approx(4.0, rel=1e-6)
    # a fraction of a newton in Hs 6 cm on this hull, not newtons (Faltinsen's asymptote, reduced)
    assert 0.05 < drift[0.06][1] < 1.0
    # head seas push astern, and much less (the fine bow meets them)
    head = field(Waves(0.06, 1.0, from_deg=0.0, spreading=0.0)).loads(0.0, 0.0, 0.0, 0.0, 14.0, 24.0)[3:6]
    assert head[0] < 0.0 and abs(head[0]) < 0.3 * drift[0.06][1]


def test_a_boat_under_way_meets_the_waves_at_the_encounter_frequency():
    """Into head seas the surge load's peak moves up by k U, in following seas down (w_e = w + k U)."""
    waves = Waves(0.06, 1.5, from_deg=0.0, spreading=0.0)
    f = field(waves)
    wp = waves.peak_frequency_radps
    k = wp * wp / 9.81
    U = 0.8
    at_rest = peak_frequency(loads_series(f, 400.0)[:, 0], 0.02)
    head = peak_frequency(loads_series(f, 400.0, u_mps=U, psi=0.0)[:, 0], 0.02)
    following = peak_frequency(loads_series(f, 400.0, u_mps=U, psi=math.pi)[:, 0], 0.02)
    assert at_rest == pytest.approx(wp, rel=0.15)
    assert head - at_rest == pytest.approx(k * U, rel=0.35)
    assert at_rest - following == pytest.approx(k * U, rel=0.35)


def test_heave_follows_long_waves_and_averages_out_short_ones():
    def heave_ratio(tp: float) -> float:
        plant = BoatPlant(environment=Environment(waves=Waves(0.04, tp, 0.0, spreading=0.0)), seed=3)
        z, eta = [], []
        for _ in range(6000):
            s = plant.step()
            z.append(s.motion.heave_m)
            eta.append(plant.sea.elevation(plant.t - plant.dt_s, s.x[0], s.x[1]))
        return float(np.std(z[1000:]) / np.std(eta[1000:]))

    assert heave_ratio(3.0) == pytest.approx(1.0, abs=0.15)  # lambda 14 m against a 1 m hull
    assert heave_ratio(0.45) < 0.3  # lambda 0.3 m: the hull spans several crests


def test_drifting_in_a_beam_sea_the_imu_feels_roll_and_heave_and_the_antenna_swings():
    env = Environment(waves=Waves(0.03, 0.8, from_deg=270.0, spreading=0.0))
    sim = Simulator(config=SimConfig(environment=env, seed=2), x0=[0, 0, 0, 0, 0, 0])
    gyro, accel, rolls, fixes, truth = [], [], [], [], []
    for _ in range(3000):
        for m in sim.step():
            name = type(m).__name__
            if name == "ImuSample":
                gyro.append(m.gyro_radps)
                accel.append(m.accel_mps2)
            elif name == "GnssFix":
                fixes.append(sim.gnss.frame.to_ne(m.lat_deg, m.lon_deg))
                truth.append(sim.x[:2])
        rolls.append(sim.plant._seakeeping.position[2])
    gyro, accel = np.array(gyro)[500:], np.array(accel)[500:]
    roll_std = float(np.std(rolls[1000:]))
    assert math.radians(0.3) < roll_std < math.radians(8.0)
    assert gyro[:, 0].std() > 5 * 0.003  # roll rate, far above the gyro's noise
    assert accel[:, 1].std() > 0.1  # gravity's share on the heeled y axis and the sway acceleration
    assert accel[:, 2].std() > 0.1 and accel[:, 2].mean() == pytest.approx(-9.81, abs=0.05)  # heave
    # the antenna 0.25 m above the roll centre swings sideways (east, the beam) by h * roll
    d = np.array(fixes)[50:] - np.array(truth)[50:]
    assert d[:, 1].std() == pytest.approx(0.25 * roll_std, rel=0.5)


def test_flat_water_is_unchanged_and_the_sea_is_seeded():
    def run(env: Environment, seed: int = 4) -> np.ndarray:
        plant = BoatPlant(environment=env, seed=seed)
        plant.command((0.1, 0.1, 40.0, 40.0, 0.0))
        return np.array([plant.step().x for _ in range(300)])

    calm = run(Environment())
    assert np.array_equal(calm, run(Environment(waves=Waves(0.0, 1.0))))  # Hs 0: flat water
    wavy = Environment(waves=Waves(0.06, 1.0, 100.0))
    a, b = run(wavy), run(wavy)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, run(wavy, seed=5))
    # the gusts' stream does not move when the sea is switched on
    windy = Environment(wind_speed_mps=4.0, wind_gust_std_mps=1.0)
    p1, p2 = BoatPlant(environment=windy, seed=4), BoatPlant(environment=Environment(
        wind_speed_mps=4.0, wind_gust_std_mps=1.0, waves=Waves(0.06, 1.0)), seed=4)
    for _ in range(200):
        p1.step()
        p2.step()
    assert p1.wind_now == p2.wind_now
