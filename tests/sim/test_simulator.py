import math
from collections import Counter

import numpy as np
import pytest

from lotsen.messages import GnssFix, GnssFixType, ImuSample, MagSample, RpmSample, ThrustCommand
from lotsen.model import DEFAULT_LIMITS, Environment, VesselModel
from lotsen.sim import GRAVITY_MPS2, SimConfig, Simulator, simulate_inputs


def run(seed, seconds=5.0, u=(0.2, 0.2, 60, 60, 10)):
    sim = Simulator(config=SimConfig(seed=seed))
    sim.command(u)
    msgs = sim.advance(seconds)
    return sim, msgs


def _flatten(msgs):
    out = []
    for m in msgs:
        for k in m.__slots__:
            v = getattr(m, k)
            out.append(tuple(v) if isinstance(v, tuple) else v)
    return out


def test_same_seed_is_bit_identical_and_other_seed_differs():
    a, ma = run(7)
    b, mb = run(7)
    c, mc = run(8)
    assert a.x == b.x
    assert _flatten(ma) == _flatten(mb)  # exact equality, NaN-free
    assert _flatten(ma) != _flatten(mc)
    assert a.x == c.x  # noise never feeds back into the open-loop truth


def test_sensor_rates():
    sim, msgs = run(1, seconds=10.0)
    n = Counter(type(m) for m in msgs)
    assert n[ImuSample] == 1000
    assert n[MagSample] == 500
    assert n[GnssFix] == 80
    assert n[RpmSample] == 200
    stamps = np.array([m.stamp_s for m in msgs if isinstance(m, GnssFix)])
    assert np.all(np.abs(np.diff(stamps) - 0.125) <= 0.0051)  # one step of jitter at most


def test_rk4_step_size_is_accurate_against_a_fine_reference():
    u = np.tile([0.3, 0.3, 70, 70, 30], (1000, 1))
    _, x_coarse, _ = simulate_inputs(u, 0.01)
    _, x_fine, _ = simulate_inputs(np.repeat(u, 10, axis=0), 0.001)
    # actuator dynamics are also resolved finer in the reference; the difference stays tiny
    assert np.max(np.abs(x_coarse[-1] - x_fine[-1])) < 5e-3
    assert np.max(np.abs(x_coarse[-1, 3:] - x_fine[-1, 3:])) < 2e-3


def test_actuators_respect_slew_and_limits():
    sim = Simulator(VesselModel(), config=SimConfig(sensors=False))  # the actuator equations themselves
    sim.command([1.5, -1.5, 500, -500, 500])
    sim.step()
    a = sim.actuators.state
    max_step = DEFAULT_LIMITS.alpha_rate_max_radps * 0.01
    assert a[0] == pytest.approx(max_step) and a[1] == pytest.approx(-max_step)
    sim.advance(3.0)
    a = sim.actuators.state
    assert a[0] == pytest.approx(DEFAULT_LIMITS.alpha_max_rad)
    assert a[2] == pytest.approx(DEFAULT_LIMITS.n_az_max_rps, rel=1e-6)
    assert a[3] == pytest.approx(-DEFAULT_LIMITS.n_az_max_rps, rel=1e-6)
    assert a[4] == pytest.approx(DEFAULT_LIMITS.n_bow_max_rps, rel=1e-6)


def test_motor_time_constant():
    sim = Simulator(VesselModel(), config=SimConfig(sensors=False))  # the actuator equations themselves
    sim.command([0, 0, 20, 20, 0])
    sim.advance(DEFAULT_LIMITS.motor_time_constant_s)
    # 63 % of the step after one time constant (the ramp limit is not active for this small step)
    assert sim.actuators.state[2] == pytest.approx(20 * (1 - math.exp(-1)), rel=1e-6)


def test_non_finite_command_goes_neutral_and_failed_unit_stops():
    sim = Simulator(VesselModel(), config=SimConfig(sensors=False))  # the actuator equations themselves
    sim.command([0, 0, 60, 60, 0])
    sim.advance(1.0)
    sim.command(ThrustCommand(stamp_s=1.0, n1_rps=float("nan")))
    assert sim.actuators.command == (0.0, 0.0, 0.0, 0.0, 0.0)
    sim.command([0, 0, 60, 60, 0])
    sim.actuators.set_faults(failed_units={0})
    sim.advance(2.0)
    assert abs(sim.actuators.state[2]) < 0.1 and sim.actuators.state[3] > 59


def test_imu_measures_specific_force_and_rate():
    sim = Simulator(config=SimConfig(seed=3))
    sim.command([0, 0, 0, 0, 60])  # spin on the bow thruster
    msgs = sim.advance(10.0)
    imu = [m for m in msgs if isinstance(m, ImuSample)][-200:]
    gz = np.mean([m.gyro_radps[2] for m in imu])
    assert gz == pytest.approx(sim.x[5] + sim.imu.gyro_bias_radps, abs=0.01)
    az = np.mean([m.accel_mps2[2] for m in imu])
    assert az == pytest.approx(-GRAVITY_MPS2, abs=0.01)


def test_magnetometer_lies_on_the_distorted_ellipse():
    sim = Simulator(config=SimConfig(seed=2))
    cfg = sim.config.imu
    S = np.array(cfg.soft_iron)
    b = np.array(cfg.hard_iron_uT)
    for psi in np.linspace(-np.pi, np.pi, 13):
        m = sim.mag.sample(0.0, psi)
        h = np.linalg.solve(S, np.array(m.field_uT[:2]) - b)
        assert np.linalg.norm(h) == pytest.approx(cfg.earth_field_horizontal_uT, abs=2.0)
        assert math.atan2(-h[1], h[0]) == pytest.approx(psi, abs=0.1) or abs(abs(psi) - math.pi) < 0.1


def test_gnss_noise_by_fix_type_and_outage():
    sim = Simulator(config=SimConfig(seed=4))
    fixes = [m for m in sim.advance(20.0) if isinstance(m, GnssFix)]
    gnss = sim.gnss
    north = np.array([gnss.frame.to_ne(f.lat_deg, f.lon_deg, f.height_m)[0] for f in fixes])
    assert 0.005 < np.std(north) < 0.02  # RTK fixed: about 1 cm
    assert all(f.fix_type == GnssFixType.RTK_FIXED for f in fixes)
    sim.set_gnss_fix_type(GnssFixType.FIX_3D)
    fixes = [m for m in sim.advance(20.0) if isinstance(m, GnssFix)]
    north = np.array([gnss.frame.to_ne(f.lat_deg, f.lon_deg, f.height_m)[0] for f in fixes])
    assert np.std(north) > 0.3
    sim.gnss.outage = True
    assert not [m for m in sim.advance(5.0) if isinstance(m, GnssFix)]


def test_wind_pushes_a_stopped_boat_downwind():
    env = Environment(wind_speed_mps=6.0, wind_from_deg=270.0)  # from the west
    sim = Simulator(config=SimConfig(sensors=False, environment=env))
    sim.advance(60.0)
    assert sim.x[1] > 1.0  # drifted east


def test_truth_and_model_agree():
    model = VesselModel()
    u = np.tile([0.1, 0.1, 50, 50, 0], (300, 1))
    _, xs, acts = simulate_inputs(u, 0.01, model)
    assert np.all(np.isfinite(xs)) and xs[-1, 3] > 0.3


def test_advance_equals_stepping():
    """advance() integrates held set-points in one compiled call; it must match step() exactly."""
    a = Simulator(config=SimConfig(seed=5))
    b = Simulator(config=SimConfig(seed=5))
    for sim in (a, b):
        sim.command([0.2, -0.1, 60, 55, 20])
    ma = a.advance(7.0)
    mb = []
    for _ in range(700):
        mb.extend(b.step())
    assert a.x == b.x and a.t == b.t and a.actuators.state == b.actuators.state
    assert _flatten(ma) == _flatten(mb)
    a.command([0.0, 0.0, 30, 30, 0])
    b.command([0.0, 0.0, 30, 30, 0])
    assert _flatten(a.step()) == _flatten(b.advance(0.01))
    assert a.x == b.x


def test_advance_motors_is_the_simulators_motor_model():
    """The controllers', monitors' and estimators' model of the ESCs (`advance_motors`) is the
    simulated boat's: 10 steps of 10 ms give the propeller speeds ActuatorDynamics reaches."""
    from lotsen.model.actuators import advance_motors
    from lotsen.sim.actuators import ActuatorDynamics

    act = ActuatorDynamics(dt_s=0.01)
    act.state = (0.0, 0.0, 20.0, -30.0, 5.0)
    act.set_command(0.0, 0.0, 90.0, 10.0, -60.0)
    for _ in range(10):
        act.step()
    n = advance_motors((20.0, -30.0, 5.0), (90.0, 10.0, -60.0), 0.1, act.limits, steps=10)
    assert n == pytest.approx(act.state[2:], abs=1e-12)
    assert n != pytest.approx(advance_motors((20.0, -30.0, 5.0), (90.0, 10.0, -60.0), 0.1, act.limits), abs=1e-3)



def _achieved_input_record(seconds: float = 40.0, seed: int = 4):
    """A noise-free record of a boat equal to the default model as the stack logs it: the actuator
    state at 20 Hz stamped when the simulator reports it, north/east/psi/r at 8 Hz from the truth,
    under random set-points held 0.4-1.2 s (turns, speed and bow-thruster changes). Returns the
    record and the true state after every step (t, x)."""
    from lotsen.sim import SimulatedBoat
    from lotsen.sysid.data import IdRecord

    rng = np.random.default_rng(seed)
    sim = Simulator(SimulatedBoat.ideal_for(VesselModel()), config=SimConfig(seed=seed, sensors=False))
    rows, ts, xs = [], [0.0], [list(sim.x)]
    t_next = 0.0
    nan4 = [math.nan] * 4
    while sim.t < seconds:
        if sim.t >= t_next - 1e-9:
            sim.command((rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-20, 90), rng.uniform(-20, 90),
                         rng.uniform(-80, 80)))
            t_next = sim.t + rng.uniform(0.4, 1.2)
        sim.step()
        ts.append(sim.t)
        xs.append(list(sim.x))
        k = round(sim.t / sim.config.dt_s)
        if k % 5 == 0:
            a = sim.actuator_state()
            rows.append([a.stamp_s, a.alpha1_rad, a.alpha2_rad, a.n1_rps, a.n2_rps, a.nt_rps, *nan4])
        if k % 25 == 12:  # 8 Hz, out of phase with the actuator state
            rows.append([sim.t, *[math.nan] * 5, sim.x[0], sim.x[1], sim.x[2], sim.x[5]])
    a = np.array(rows)
    return IdRecord(a[:, 0], a[:, 1:6], a[:, 6:], input_kind="sample"), np.array(ts), np.array(xs)


def test_the_reported_actuator_state_is_what_drove_the_boat_at_its_stamp():
    """Identification interpolates the logged actuator state linearly between its stamps. The
    simulator must move the boat under exactly that input: it integrates each 10 ms step under the
    actuators' mean over the step. Under the step's end value (as it did before) the inputs acted
    half a step before their stamps, and on calm lab records identification came back biased by
    1-2 % on m33, N_r and mu_t (z-scores 3-4 on random boats, N_v up to 18 % off). Checked on the
    estimator's own simulation at the true parameters, every 2 s interval started from the true
    state: its misfit (residuals and continuity defects, in noise units) with the stamps as
    reported against the same record with the inputs moved 5 ms either way."""
    pytest.importorskip("casadi")  # the estimator's kernels: the sysid extra, not installed on the boat
    import dataclasses

    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sysid.estimate import NAMES, parameter_scale
    from lotsen.sysid.multiple import MultipleShootingProblem

    rec, ts, xs = _achieved_input_record()
    theta = np.array([getattr(DEFAULT_PARAMETERS, n) for n in NAMES])
    is_input = np.isnan(rec.outputs[:, 0])

    def misfit(shift_s: float) -> float:
        t = np.where(is_input, rec.t + shift_s, rec.t)
        order = np.argsort(t, kind="stable")
        r = dataclasses.replace(rec, t=t[order], inputs=rec.inputs[order], outputs=rec.outputs[order])
        prob = MultipleShootingProblem([r])
        nodes = xs[np.clip(np.searchsorted(ts, prob.grid.node_time - 1e-9), 0, len(ts) - 1)]
        lin = prob.linearise(theta, nodes, np.zeros(0, int), parameter_scale(theta), False)
        return float(max(np.sqrt(np.mean(lin.e ** 2, axis=0)).max(), np.sqrt(np.mean(lin.c ** 2, axis=0)).max()))

    on_time, late, early = misfit(0.0), misfit(0.005), misfit(-0.005)
    assert on_time < 0.8 * min(late, early), (on_time, late, early)  # measured 0.42 vs 0.63 and 0.72
