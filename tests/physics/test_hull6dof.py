"""Properties of the independent 6-DOF hull (tests/physics/hull6dof.py), the plant the seam and the
identification benches fly: physics that must hold, its 3-DOF behaviour near (not at) lotsen's
defaults, its environment, and the identification record it writes."""

import ast
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from hull6dof import (  # noqa: E402
    GRAVITY, Hull6DOF, HullEnvironment, HullParameters, WaveField, prbs_multisine, record, steady_speed,
    turning_circle,
)

DEG = math.pi / 180


def total_energy(h: Hull6DOF) -> float:
    """Kinetic energy (rigid body + added mass) plus the hydrostatic potential of heave, roll, pitch."""
    z, phi, th = h.eta[2], h.eta[3], h.eta[4]
    return h.kinetic_energy() + 0.5 * h._k_heave * z * z + h._k_roll * (1 - math.cos(phi)) \
        + h._k_pitch * (1 - math.cos(th))


def test_energy_dissipates_with_zero_thrust():
    h = Hull6DOF()
    h.state[6:12] = [1.2, 0.25, 0.05, 0.3, 0.1, 0.6]  # moving, drifting, rolling, turning
    h.state[3] = 8 * DEG
    energies = [total_energy(h)]
    for _ in range(60):
        h.advance(0.25)
        energies.append(total_energy(h))
    e = np.array(energies)
    assert np.all(np.diff(e) < 0.0), "energy grew in some 0.25 s with the thrusters off"
    assert e[-1] < 0.05 * e[0]


def test_symmetric_input_gives_no_yaw_sway_or_roll():
    h = Hull6DOF()
    h.command(0.1, -0.1, 70.0, 70.0, 0.0)  # toe-in, both propellers alike: mirror-symmetric
    h.advance(20.0)
    N, E, psi, u, v, r = h.x3
    assert u > 1.0
    assert max(abs(E), abs(psi), abs(v), abs(r), abs(h.eta[3]), abs(h.nu[3])) < 1e-9


def test_mirrored_input_mirrors_the_motion():
    a, b = Hull6DOF(), Hull6DOF()
    a.command(0.3, 0.2, 60.0, 40.0, 30.0)
    b.command(-0.2, -0.3, 40.0, 60.0, -30.0)  # the port/starboard mirror image
    a.advance(8.0)
    b.advance(8.0)
    xa, xb = np.array(a.x3), np.array(b.x3)
    np.testing.assert_allclose(xa[[0, 3]], xb[[0, 3]], atol=1e-9)
    np.testing.assert_allclose(xa[[1, 2, 4, 5]], -xb[[1, 2, 4, 5]], atol=1e-9)
    assert abs(a.eta[3] + b.eta[3]) < 1e-9 and abs(a.eta[3]) > 1e-4  # heels, mirrored


def test_turning_to_port_for_positive_alpha():
    """lotsen's sign convention: alpha > 0 turns the thrust to starboard, which yaws the bow to port."""
    h = Hull6DOF()
    h.command(20 * DEG, 20 * DEG, 50.0, 50.0, 0.0)
    h.advance(10.0)
    assert h.nu[5] < -0.3 and h.x3[1] < 0.0
    b = Hull6DOF()
    b.command(0.0, 0.0, 0.0, 0.0, 60.0)  # bow thruster pushes the bow to starboard
    b.advance(3.0)
    assert b.nu[5] > 0.05


def test_roll_returns_to_upright():
    h = Hull6DOF()
    h.state[3] = 10 * DEG
    crossings, last, peak_late = 0, h.eta[3], 0.0
    for k in range(200):
        h.advance(0.05)
        phi = h.eta[3]
        crossings += (phi > 0) != (last > 0)
        last = phi
        if k >= 160:
            peak_late = max(peak_late, abs(phi))
    assert crossings >= 6, "a stable hull rolls back through upright, not creeping"
    assert peak_late < 0.5 * DEG


def test_steady_speed_and_turning_circle_near_but_not_the_defaults():
    """docs/model.md's defaults give 1.74 m/s at n = 100 and a 2.2 m circle at n = 50, 20 deg; this
    hull is meant to be close to that, not equal."""
    u = steady_speed(100.0)
    assert 1.5 <= u <= 1.6
    assert abs(u - 1.74) > 0.1
    turn = turning_circle(50.0, 20.0)
    assert 1.8 <= turn["diameter_m"] <= 2.2
    assert abs(turn["diameter_m"] - turn["kinematic_diameter_m"]) < 0.05  # a steady circle


def thruster_force(h: Hull6DOF, u: float, act: tuple) -> list:
    """The thrusters' share of the forces at surge speed u: forces with and without them."""
    s = [0.0] * 12
    s[6] = u
    with_t, _ = h.forces(s, act)
    without, _ = h.forces(s, (act[0], act[1], 0.0, 0.0, 0.0))
    return [a - b for a, b in zip(with_t, without)]


def test_thrust_falls_with_advance_speed_and_astern_is_weaker():
    h = Hull6DOF()
    X0 = thruster_force(h, 0.0, (0.0, 0.0, 100.0, 100.0, 0.0))[0]
    X15 = thruster_force(h, 1.5, (0.0, 0.0, 100.0, 100.0, 0.0))[0]
    assert 20.0 < X0 < 24.0  # two units at full speed, bollard pull
    assert 0.6 * X0 < X15 < 0.85 * X0
    Xa = thruster_force(h, 0.0, (0.0, 0.0, -80.0, -80.0, 0.0))[0]
    assert -0.8 * X0 * 0.64 < Xa < -0.7 * X0 * 0.64  # 0.75 of ahead at the same |n|
    assert thruster_force(h, 0.0, (0.0, 0.0, 2.0, 2.0, 0.0))[0] == 0.0  # dead band


def test_bow_thruster_fades_with_forward_speed():
    h = Hull6DOF()
    Y0 = thruster_force(h, 0.0, (0.0, 0.0, 0.0, 0.0, 60.0))[1]
    Y5 = thruster_force(h, 0.5, (0.0, 0.0, 0.0, 0.0, 60.0))[1]
    Y10 = thruster_force(h, 1.0, (0.0, 0.0, 0.0, 0.0, 60.0))[1]
    assert Y0 > 1.0
    assert Y10 < Y5 < 0.6 * Y0 and Y10 < 0.25 * Y0


def test_pods_act_like_rudders():
    """Moving ahead with the units turned to starboard and the propellers idle, the pods push the
    stern to starboard (bow to port)."""
    h = Hull6DOF()
    f = thruster_force(h, 1.0, (20 * DEG, 20 * DEG, 0.0, 0.0, 0.0))
    s = [0.0] * 12
    s[6] = 1.0
    with_pods, _ = h.forces(s, (20 * DEG, 20 * DEG, 0.0, 0.0, 0.0))
    straight, _ = h.forces(s, (0.0, 0.0, 0.0, 0.0, 0.0))
    assert f == [0.0] * 6  # no thrust in the dead band ...
    assert with_pods[1] - straight[1] > 0.01 and with_pods[5] - straight[5] < 0.0  # ... but pod lift


def test_actuator_lag_and_servo_rate():
    p = HullParameters()
    h = Hull6DOF(p)
    h.command(math.radians(40), -math.radians(40), 80.0, 80.0, 0.0)
    h.advance(p.latency_s + 0.1)
    a1, a2, n1, _, _ = h.actuators
    assert abs(a1 - p.alpha_rate_radps * 0.1) < 0.01 and a2 == pytest.approx(-a1)  # slewing, not there
    h.advance(p.motor_time_constant_s - 0.1)
    n_tau = h.actuators[2]
    assert 0.55 * 80 < n_tau < 0.7 * 80  # first order: 63 % after one time constant (ramp-limited start)
    h.advance(1.0)
    assert h.actuators[0] == pytest.approx(math.radians(40)) and h.actuators[2] == pytest.approx(80.0, abs=0.1)


def test_drifts_with_the_current_and_before_the_wind():
    c = Hull6DOF(environment=HullEnvironment(current_mps=0.1, current_to_deg=90.0))
    c.advance(60.0)
    vel, _ = c.measure()
    assert vel[0] == pytest.approx(0.0, abs=2e-3) and vel[1] == pytest.approx(0.1, abs=2e-3)
    w = Hull6DOF(environment=HullEnvironment(wind_mps=5.0, wind_from_deg=0.0))
    w.advance(30.0)
    vel, _ = w.measure()
    assert vel[0] < -0.05 and abs(vel[1]) < 1e-9  # wind from the north, from ahead: blown south, straight
    b = Hull6DOF(environment=HullEnvironment(wind_mps=5.0, wind_from_deg=90.0))  # on the starboard beam
    b.advance(2.0)
    vel, _ = b.measure()
    # pushed to port (west), heeled to port (its lateral area is above the waterline), bow falling off
    # to port (the centre of pressure is ahead of the origin)
    assert vel[1] < 0.0 and b.eta[3] < -0.05 * DEG and b.nu[5] < 0.0


def test_gusts_are_seeded():
    env = HullEnvironment(wind_mps=4.0, wind_from_deg=250.0, gust_fraction=0.25, wind_wander_deg=15.0, seed=3)
    runs = []
    for e in (env, env, HullEnvironment(**{**env.__dict__, "seed": 4})):
        h = Hull6DOF(environment=e)
        winds = []
        for _ in range(50):
            h.advance(0.2)
            winds.append(h.wind_now)
        runs.append(np.array(winds))
    np.testing.assert_array_equal(runs[0], runs[1])
    assert np.abs(runs[0] - runs[2]).max() > 0.1
    assert np.ptp(runs[0][:, 0]) > 0.3 and np.ptp(runs[0][:, 1]) > 1.0  # the speed gusts, the direction wanders


def test_current_varies_slowly_when_asked():
    h = Hull6DOF(environment=HullEnvironment(current_mps=0.08, current_to_deg=30.0, current_variation=0.3,
                                             current_wander_deg=20.0, current_period_s=60.0))
    seen = []
    for _ in range(60):
        h.advance(1.0)
        seen.append(h.current_ne)
    speeds = np.hypot(*np.array(seen).T)
    assert 0.08 * 0.6 < speeds.min() < speeds.max() < 0.08 * 1.4 and np.ptp(speeds) > 0.02


def test_record_is_a_lake_record():
    """The record generator writes what lotsen's lake records write (docs/sysid.md, "Data")."""
    from lotsen.sysid.data import load_csv, save_csv, split_segments

    rec = record(duration_s=12.0, seed=2, wind_mps=3.0, gust_fraction=0.2, current_mps=0.05)
    r = rec.record
    assert r.input_kind == "mean"
    has_u = np.isfinite(r.inputs).all(axis=1)
    has_y = np.isfinite(r.outputs).all(axis=1)
    np.testing.assert_allclose(np.diff(r.t[has_u]), 0.02, atol=1e-9)  # 50 Hz interval means
    np.testing.assert_allclose(np.diff(r.t[has_y]), 0.125, atol=1e-9)  # 8 Hz fixes
    assert np.all(has_u | has_y)
    # noise: measured minus truth at the fixes
    err = r.outputs[has_y] - rec.truth_x[:, [0, 1, 2, 5]]
    assert 0.006 < err[:, 0].std() < 0.014 and 0.006 < err[:, 2].std() < 0.014 and 0.0018 < err[:, 3].std() < 0.0042
    assert len(split_segments(r)) == 1


def test_record_saves_and_loads(tmp_path):
    from lotsen.sysid.data import load_csv

    rec = record(duration_s=3.0, seed=1)
    path = tmp_path / "hull.csv"
    rec.save_csv(path)
    back = load_csv(path)
    assert back.input_kind == "mean"
    np.testing.assert_allclose(back.t, rec.record.t)
    np.testing.assert_allclose(back.inputs, rec.record.inputs, rtol=1e-8, atol=1e-9, equal_nan=True)
    np.testing.assert_allclose(back.outputs, rec.record.outputs, rtol=1e-8, atol=1e-9, equal_nan=True)


def test_record_runs_a_lotsen_experiment():
    from lotsen.sysid.experiment import parse_experiment

    exp = parse_experiment({"name": "zz", "start": {"heading_deg": 90}, "pieces": [
        {"type": "zigzag", "duration_s": 20, "alpha_deg": 20, "heading_deg": 20, "n_rps": 60}]}, "test")
    rec = record(exp, duration_s=20.0)
    psi = rec.truth_x[:, 2]
    assert abs(psi[0] - math.pi / 2) < 1e-9
    # a zigzag swings the heading both ways around the start
    assert psi.max() > math.pi / 2 + 15 * DEG and psi.min() < math.pi / 2 - 15 * DEG


def test_inputs_default_to_a_prbs_on_all_channels():
    cmd = prbs_multisine(0, 60.0)
    U = np.array([cmd(t) for t in np.arange(0, 60, 0.05)])
    assert np.all(U.std(axis=0) > [0.1, 0.1, 5, 5, 20])


def test_independent_of_lotsens_model():
    """The hull imports nothing of lotsen but the record format (and the experiment's generator when
    given one), and stepping it loads no lotsen module at all."""
    tree = ast.parse((HERE / "hull6dof.py").read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module} | {
        a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert {m for m in imported if m.startswith("lotsen")} == {"lotsen.sysid.data", "lotsen.sysid.experiment"}
    code = ("import sys; sys.path.insert(0, %r); import hull6dof; h = hull6dof.Hull6DOF(); h.command(0.1, 0.1, 50, 50, 9);"
            " h.advance(1.0); print(sorted(m for m in sys.modules if m.startswith('lotsen')))") % str(HERE)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


# ----------------------------------------------------------------------------------------------
# waves

def highpass(x: np.ndarray, n: int) -> np.ndarray:
    """x less its centred moving mean over n samples (the wave-frequency part), the ends dropped."""
    return (x - np.convolve(x, np.ones(n) / n, mode="same"))[n:-n]


def test_wave_field_realises_its_sea_state():
    """The elevation at a fixed point over 10 minutes has 4 std within 10 % of Hs, and the spectrum
    the components carry is the one asked for (Hs exactly, Tp within a band's width)."""
    t = np.arange(0.0, 600.0, 0.05)
    for hs, tp, spread in [(0.03, 0.8, None), (0.06, 1.2, 2.0), (0.10, 1.0, 0.0)]:
        w = WaveField(hs, tp, 30.0, spread, seed=5)
        z = w.elevation(t, 1.0, -2.0)
        assert abs(4.0 * z.std() / hs - 1.0) < 0.10
        assert abs(z.mean()) < 0.05 * hs
        assert w.realised_hs_m == pytest.approx(hs, rel=1e-9)
        assert abs(w.realised_tp_s / tp - 1.0) < 0.08
    # long-crested: every component travels to 210 deg; spread: around it, none against it
    assert np.allclose(np.degrees(WaveField(0.03, 0.8, 30.0).to_rad), 210.0)
    to = np.degrees(WaveField(0.03, 0.8, 30.0, 2.0).to_rad)
    assert np.all(np.abs(to - 210.0) < 90.0) and 10.0 < np.std(to) < 40.0


def test_wave_kinematics_are_airy_waves():
    """Deep-water linear waves: the surface moves with the water (d zeta / dt = -w_down at z = 0),
    the orbital motion decays as e^{-kz}, and the acceleration is the velocity's rate."""
    w = WaveField(0.05, 1.0, 120.0, 1.0, seed=2)
    dt = 1e-5
    for t, n, e in [(3.0, 0.4, -1.0), (17.2, -3.0, 2.5)]:
        dz = (w.elevation(t + dt, n, e) - w.elevation(t - dt, n, e)) / (2 * dt)
        v, a = w.kinematics(t, n, e)
        assert dz == pytest.approx(-v[2], rel=1e-5)
        v1, _ = w.kinematics(t + dt, n, e)
        v0, _ = w.kinematics(t - dt, n, e)
        np.testing.assert_allclose((v1 - v0) / (2 * dt), a, rtol=1e-5, atol=1e-9)
    # one component alone: its velocity's magnitude falls as e^{-kz}
    w.amplitude_m = np.where(np.arange(len(w.amplitude_m)) == 10, 0.02, 0.0)
    k = w.wavenumber_radpm[10]
    v0, _ = w.kinematics(np.arange(0.0, 5.0, 0.01), 0.0, 0.0, 0.0)
    v1, _ = w.kinematics(np.arange(0.0, 5.0, 0.01), 0.0, 0.0, 0.1)
    assert np.abs(v1).max() / np.abs(v0).max() == pytest.approx(math.exp(-0.1 * k), rel=1e-3)


def run_hull(env: HullEnvironment, seconds: float, dt: float = 0.02, heading: float = 0.0, n_rps: float = 0.0,
             settle_s: float = 5.0) -> tuple[Hull6DOF, np.ndarray]:
    """Rows of eta, specific force, the elevation at the hull, u and t, every dt after settling."""
    h = Hull6DOF(environment=env, pose=(0.0, 0.0, heading))
    h.command(0.0, 0.0, n_rps, n_rps, 0.0)
    h.advance(settle_s)
    rows = []
    for _ in range(int(round(seconds / dt))):
        h.advance(dt)
        _, f = h.measure()
        rows.append([*h.eta, *f, h.wave_elevation(h.t, h.eta[0], h.eta[1]), h.nu[0], h.t])
    return h, np.array(rows)


def test_no_waves_is_bit_identical_and_waves_leave_the_gusts_alone():
    env = HullEnvironment(current_mps=0.06, current_to_deg=40.0, wind_mps=4.0, wind_from_deg=250.0,
                          gust_fraction=0.25, wind_wander_deg=15.0, seed=3)
    calm = replace(env, wave_hs_m=0.0, wave_tp_s=0.8, wave_from_deg=45.0, wave_spreading=2.0)
    wavy = replace(env, wave_hs_m=0.03, wave_tp_s=0.8, wave_from_deg=45.0)
    runs = []
    for e in (env, calm, wavy):
        h = Hull6DOF(environment=e)
        h.command(0.2, 0.1, 50.0, 40.0, 20.0)
        seen = []
        for _ in range(40):
            h.advance(0.25)
            seen.append([*h.state, *h.measure()[1], *h.wind_now])
        runs.append(np.array(seen))
    np.testing.assert_array_equal(runs[0], runs[1])  # Hs 0: the calm hull, bit for bit
    np.testing.assert_array_equal(runs[0][:, -2:], runs[2][:, -2:])  # the same gusts in waves
    assert np.abs(runs[0][:, :12] - runs[2][:, :12]).max() > 1e-3


def test_waves_are_seeded():
    a, b, c = (Hull6DOF(environment=HullEnvironment(wave_hs_m=0.03, wave_tp_s=0.8, wave_spreading=1.0, seed=s))
               for s in (7, 7, 8))
    for h in (a, b, c):
        h.advance(2.0)
    assert a.state == b.state and a.state != c.state
    t = np.arange(0.0, 20.0, 0.1)
    np.testing.assert_array_equal(a.wave_elevation(t, 1.0, 2.0), b.wave_elevation(t, 1.0, 2.0))
    assert np.abs(a.wave_elevation(t, 1.0, 2.0) - c.wave_elevation(t, 1.0, 2.0)).max() > 0.005


def test_head_seas_give_no_sway_yaw_or_roll():
    """A port-starboard symmetric hull in long-crested waves from dead ahead: surge, heave and pitch,
    and no sway, yaw or roll, at any moment (so none on the mean)."""
    h, rows = run_hull(HullEnvironment(wave_hs_m=0.05, wave_tp_s=1.0, wave_from_deg=0.0), 15.0, dt=0.1)
    assert np.abs(rows[:, [1, 3, 5]]).max() < 1e-9
    assert abs(h.nu[1]) < 1e-9 and abs(h.nu[5]) < 1e-9 and np.abs(rows[:, 7]).max() < 1e-9
    assert np.ptp(rows[:, 4]) > math.radians(1.0) and np.ptp(rows[:, 2]) > 0.005


def test_mean_drift_pushes_along_the_waves_and_goes_with_hs_squared():
    """The reflection drift (Faltinsen 1990 ch. 5): along the waves' travel, 4 x for 2 x Hs, a fraction
    of a newton on this hull in Hs 6 cm, small in waves much longer than the hull's draft and beam; a
    free hull drifts the way the waves go."""
    def drift(hs, tp, from_deg, heading=0.0):
        return Hull6DOF(environment=HullEnvironment(wave_hs_m=hs, wave_tp_s=tp, wave_from_deg=from_deg)
                        ).mean_wave_drift(heading)
    head3, head6 = drift(0.03, 0.8, 0.0), drift(0.06, 0.8, 0.0)
    beam3, beam6 = drift(0.03, 0.8, 90.0), drift(0.06, 0.8, 90.0)
    assert head6[0] < 0.0 and abs(head6[1]) < 1e-9 and beam6[1] < 0.0 and abs(beam6[0]) < 1e-9
    assert head6[0] / head3[0] == pytest.approx(4.0, rel=1e-9) and beam6[1] / beam3[1] == pytest.approx(4.0, rel=1e-9)
    assert 0.01 < -head6[0] < 0.1 and 0.2 < -beam6[1] < 1.0
    assert -drift(0.06, 3.0, 90.0)[1] < 0.01 * -beam6[1]  # 14 m waves hardly reflect off a 9 cm draft
    # quartering waves from the port bow (from 315 deg): pushed aft and to starboard, the bow turned
    # off towards beam-on (to starboard)
    q = drift(0.06, 0.8, 315.0)
    assert q[0] < 0.0 and q[1] > 0.0 and q[2] > 0.0
    # the hull, thrusters off, in beam seas from the east: it goes west
    _, rows = run_hull(HullEnvironment(wave_hs_m=0.06, wave_tp_s=1.0, wave_from_deg=90.0), 20.0, dt=0.1)
    assert rows[-1, 1] - rows[0, 1] < -0.3


def test_encounter_frequency_at_speed():
    """Under way at U into head seas the heave's peak frequency rises by about k U, in following seas
    it falls by about as much (the strips meet the waves where they are). 6 m waves, so that the
    heave follows the encountered surface; 30 s: the peak to within 0.2 rad/s."""
    tp = 2.0
    wp = 2.0 * math.pi / tp
    for from_deg, sign in [(0.0, 1.0), (180.0, -1.0)]:
        h, rows = run_hull(HullEnvironment(wave_hs_m=0.04, wave_tp_s=tp, wave_from_deg=from_deg, wave_gamma=7.0),
                           30.0, n_rps=70.0, settle_s=8.0)
        u = rows[:, 10].mean()
        assert 1.0 < u < 1.5
        z = -rows[:, 2] + rows[:, 2].mean()
        spectrum = np.convolve(np.abs(np.fft.rfft(z * np.hanning(len(z)))) ** 2, np.ones(5) / 5, mode="same")
        w = 2.0 * math.pi * np.fft.rfftfreq(len(z), 0.02)
        shift = (w[np.argmax(spectrum)] - wp) / (wp * wp / GRAVITY * u)  # in units of k_p U
        assert 0.6 < sign * shift < 1.5, (from_deg, shift)  # (the heave's own RAO leans it a little)


def test_long_waves_are_followed_and_short_ones_average_out():
    """Waves 14 m long (Tp 3 s): the hull heaves with the surface and its accelerometer's specific force
    stays normal to it. Waves a quarter of its length (Tp 0.4 s): it hardly heaves."""
    for from_deg in (0.0, 90.0):
        h, rows = run_hull(HullEnvironment(wave_hs_m=0.05, wave_tp_s=3.0, wave_from_deg=from_deg), 20.0)
        heave, zeta = -(rows[:, 2] - rows[:, 2].mean()), rows[:, 9]
        assert heave.std() / zeta.std() == pytest.approx(1.0, abs=0.05) and np.corrcoef(heave, zeta)[0, 1] > 0.99
        tilt, slope = [], []
        for n, e, _, phi, th, psi, fx, fy, fz, _, _, t in rows:
            c = [math.cos(a) for a in (phi, th, psi)]
            s = [math.sin(a) for a in (phi, th, psi)]
            R = np.array([[c[2] * c[1], -s[2] * c[0] + c[2] * s[1] * s[0], s[2] * s[0] + c[2] * c[0] * s[1]],
                          [s[2] * c[1], c[2] * c[0] + s[0] * s[1] * s[2], -c[2] * s[0] + s[1] * s[2] * c[0]],
                          [-s[1], c[1] * s[0], c[1] * c[0]]])
            f = R @ [fx, fy, fz]
            d = 1e-3
            grad = [(h.wave_elevation(t, n + d, e) - h.wave_elevation(t, n - d, e)) / (2 * d),
                    (h.wave_elevation(t, n, e + d) - h.wave_elevation(t, n, e - d)) / (2 * d)]
            tilt.append([f[0] / -f[2] + grad[0], f[1] / -f[2] + grad[1]])  # the surface's normal tilts by -grad
            slope.append(grad)
        assert np.sqrt(np.mean(np.square(tilt))) < 0.3 * np.sqrt(np.mean(np.square(slope)))
    _, rows = run_hull(HullEnvironment(wave_hs_m=0.01, wave_tp_s=0.4, wave_from_deg=0.0), 10.0)
    assert rows[:, 2].std() < 0.1 * rows[:, 9].std()


def test_wave_frequency_motion_of_a_small_boat():
    """Thrusters off in Hs 3 cm, Tp 0.8 s: millimetres to a centimetre at wave frequency, about a
    degree in pitch in head seas, a few in roll in beam seas (roll's own period is near 1 s)."""
    n = int(2.0 / 0.02)
    _, head = run_hull(HullEnvironment(wave_hs_m=0.03, wave_tp_s=0.8, wave_from_deg=0.0), 20.0)
    _, beam = run_hull(HullEnvironment(wave_hs_m=0.03, wave_tp_s=0.8, wave_from_deg=90.0), 20.0)
    hd = np.column_stack([highpass(head[:, i], n) for i in range(6)])
    bd = np.column_stack([highpass(beam[:, i], n) for i in range(6)])
    assert 0.0005 < hd[:, 0].std() < 0.01 and 0.0005 < hd[:, 2].std() < 0.01
    assert math.radians(0.3) < hd[:, 4].std() < math.radians(3.0)
    assert 0.002 < bd[:, 1].std() < 0.015 and 0.002 < bd[:, 2].std() < 0.015
    assert math.radians(1.0) < bd[:, 3].std() < math.radians(6.0) and bd[:, 4].std() < math.radians(0.5)


def test_environment_flags_raise_a_sea_in_records_and_the_server(tmp_path):
    import argparse

    from hull6dof import add_environment_arguments, environment_arguments

    ap = argparse.ArgumentParser()
    add_environment_arguments(ap)
    kw = environment_arguments(ap.parse_args(["--waves", "0.03,0.8,250", "--wave-spreading", "2"]))
    env = HullEnvironment(**kw)
    assert (env.wave_hs_m, env.wave_tp_s, env.wave_from_deg, env.wave_spreading) == (0.03, 0.8, 250.0, 2.0)
    assert environment_arguments(ap.parse_args([]))["wave_hs_m"] == 0.0
    rec = record(duration_s=2.0, **{**kw, "seed": 1})
    assert rec.environment.wave_hs_m == 0.03
    assert np.abs(rec.truth_x - record(duration_s=2.0, seed=1).truth_x).max() > 1e-4


def test_hull_server_flies_in_waves():
    """hull_server.py --waves: its replies' accelerometer has the sea's frequencies in it."""
    import json
    import socket
    import struct

    proc = subprocess.Popen([sys.executable, str(HERE / "hull_server.py"), "--port", "0", "--waves", "0.03,0.8,90"],
                            stdout=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()
        port = int(line.rsplit(":", 1)[1])
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.settimeout(5.0)
        acc = []
        for frame in range(400):  # 8 s at 50 Hz, servos neutral
            sock.sendto(struct.pack("<HHI16H", 18458, 50, frame, *([1500] * 16)), ("127.0.0.1", port))
            acc.append(json.loads(sock.recv(65536))["imu"]["accel_body"])
        sock.close()
    finally:
        proc.terminate()
        proc.wait(10)
    a = np.array(acc)[100:]
    assert a[:, 1].std() > 0.2 and a[:, 2].std() > 0.1  # beam seas: sway and heave
    y = a[:, 1] - a[:, 1].mean()
    w = 2.0 * math.pi * np.fft.rfftfreq(len(y), 0.02)
    peak = w[np.argmax(np.abs(np.fft.rfft(y * np.hanning(len(y)))))]
    wp = 2.0 * math.pi / 0.8
    assert 0.6 * wp < peak < 2.0 * wp
