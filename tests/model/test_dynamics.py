"""Physics properties of the vessel model (seed eq. 19-22) that must hold for any parameter set."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lotsen.model import (
    DEFAULT_PARAMETERS, VesselGeometry, VesselModel, VesselParameters, jacobians, thruster_forces,
)

MODEL = VesselModel()


def simulate(model, x0, u, duration, dt=0.01):
    x = np.array(x0, float)
    for _ in range(int(round(duration / dt))):
        x = model.step(x, u, dt)
    return x


def test_kinetic_energy_decreases_without_input():
    x = np.array([0, 0, 0.3, 1.0, 0.3, 0.4])
    energies = []
    for _ in range(500):
        energies.append(MODEL.kinetic_energy(x[3:]))
        x = MODEL.step(x, [0, 0, 0, 0, 0], 0.01)
    energies = np.array(energies)
    assert np.all(np.diff(energies) < 0), "damping must dissipate energy at every step"
    assert energies[-1] < 0.2 * energies[0]


def test_symmetric_thrust_straight_ahead_gives_no_sway_or_yaw():
    x = simulate(MODEL, [0, 0, 0, 0, 0, 0], [0, 0, 60, 60, 0], 20.0)
    assert x[3] > 0.5
    assert x[4] == 0.0 and x[5] == 0.0 and x[2] == 0.0 and x[1] == 0.0


def test_bow_thruster_alone_turns_to_starboard():
    x = simulate(MODEL, [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 40], 2.0)
    assert x[5] > 0.0, "n_t > 0 pushes the bow to starboard: positive yaw rate"
    assert x[2] > 0.0
    x = simulate(MODEL, [0, 0, 0, 0, 0, 0], [0, 0, 0, 0, -40], 2.0)
    assert x[5] < 0.0


def test_azimuth_to_starboard_yaws_bow_to_port():
    # alpha > 0 turns the thrust to starboard at the stern: the stern goes to starboard, bow to port
    x = simulate(MODEL, [0, 0, 0, 0.5, 0, 0], [0.3, 0.3, 50, 50, 0], 3.0)
    assert x[5] < 0.0


def test_steady_surge_speed_matches_thrust_drag_balance():
    n = 70.0
    x = simulate(MODEL, [0, 0, 0, 0, 0, 0], [0, 0, n, n, 0], 60.0)
    p = DEFAULT_PARAMETERS
    T = 2 * p.mu_az * n * n  # X_u U - X_|u|u U^2 = T
    U = (-p.X_u + math.sqrt(p.X_u ** 2 - 4 * p.X_uu * T)) / (-2 * p.X_uu)
    assert x[3] == pytest.approx(U, rel=1e-6)
    assert MODEL.propeller_speed_for_surge(U) == pytest.approx(n, rel=1e-9)


def test_housing_force_zero_when_aligned_and_acts_like_a_rudder():
    p = DEFAULT_PARAMETERS.to_vector()
    # alpha = 0, v = r = 0: no normal force, thrust only along x
    X, Y, N = thruster_forces((0.8, 0.0, 0.0), (0, 0, 40, 40, 0), p)
    assert Y == pytest.approx(0.0, abs=1e-12) and N == pytest.approx(0.0, abs=1e-12)
    # propellers stopped, moving ahead, units turned to starboard: stern pushed to starboard
    X, Y, N = thruster_forces((1.0, 0.0, 0.0), (0.3, 0.3, 0, 0, 0), p)
    assert Y > 0 and N < 0
    # C_N = 0 removes the term and leaves the seed's eq. (19)-(20) exactly
    p0 = DEFAULT_PARAMETERS.with_updates(C_N=0.0).to_vector()
    X, Y, N = thruster_forces((1.0, 0.2, 0.1), (0.3, -0.2, 50, -30, 20), p0)
    mu, mt = DEFAULT_PARAMETERS.mu_az, DEFAULT_PARAMETERS.mu_t
    T1, T2, Tt = mu * 50 * 50, -mu * 30 * 30, mt * 20 * 20
    g = VesselGeometry()
    exp_X = T1 * math.cos(0.3) + T2 * math.cos(-0.2)
    exp_Y = T1 * math.sin(0.3) + T2 * math.sin(-0.2) + Tt
    exp_N = (g.l_x1 * T1 * math.sin(0.3) - g.l_y1 * T1 * math.cos(0.3)
             + g.l_x2 * T2 * math.sin(-0.2) - g.l_y2 * T2 * math.cos(-0.2) + g.l_xt * Tt)
    assert (X, Y, N) == pytest.approx((exp_X, exp_Y, exp_N), rel=1e-12)


def test_reverse_thrust_ratio_weakens_reverse_only():
    geom = VesselGeometry(reverse_thrust_ratio=0.6)
    p = DEFAULT_PARAMETERS.with_updates(C_N=0.0).to_vector()
    fwd = thruster_forces((0, 0, 0), (0, 0, 50, 0, 0), p, geom)[0]
    rev = thruster_forces((0, 0, 0), (0, 0, -50, 0, 0), p, geom)[0]
    assert rev == pytest.approx(-0.6 * fwd)


def _fd_jacobians(model, x, u, h=1e-6):
    A = np.zeros((6, 6))
    B = np.zeros((6, 5))
    for i in range(6):
        e = np.zeros(6)
        e[i] = h
        A[:, i] = (model.f(0, x + e, u) - model.f(0, x - e, u)) / (2 * h)
    for i in range(5):
        e = np.zeros(5)
        e[i] = h
        B[:, i] = (model.f(0, x, u + e) - model.f(0, x, u - e)) / (2 * h)
    return A, B


component = st.floats(min_value=0.05, max_value=1.0)


@settings(max_examples=60, deadline=None)
@given(
    psi=st.floats(-3.1, 3.1), u=component, v=st.floats(0.02, 0.4), r=st.floats(0.02, 0.5),
    sv=st.sampled_from([1, -1]), sr=st.sampled_from([1, -1]),
    a1=st.floats(-0.7, 0.7), a2=st.floats(-0.7, 0.7), n1=st.floats(5, 100), n2=st.floats(-100, -5),
    nt=st.floats(5, 80),
)
def test_jacobians_match_finite_differences(psi, u, v, r, sv, sr, a1, a2, n1, n2, nt):
    x = np.array([3.0, -2.0, psi, u, sv * v, sr * r])
    uu = np.array([a1, a2, n1, n2, nt])
    A, B = MODEL.jacobians(x, uu)
    Af, Bf = _fd_jacobians(MODEL, x, uu)
    scale_A = np.maximum(np.abs(Af), 1.0)
    scale_B = np.maximum(np.abs(Bf), 1e-3)
    assert np.all(np.abs(A - Af) / scale_A < 1e-6)
    assert np.all(np.abs(B - Bf) / scale_B < 1e-6)


def test_jacobians_with_reverse_ratio_and_other_parameters():
    params = VesselParameters.from_vector(np.array(DEFAULT_PARAMETERS.to_vector()) * 1.3)
    model = VesselModel(params, VesselGeometry(reverse_thrust_ratio=0.7))
    x = np.array([0, 0, 1.0, 0.6, -0.1, 0.2])
    u = np.array([0.2, -0.4, -40.0, 60.0, -30.0])
    A, B = jacobians(x, u, model.theta, model.geometry)
    Af, Bf = _fd_jacobians(model, x, u)
    assert np.allclose(A, Af, rtol=1e-6, atol=1e-8)
    assert np.allclose(B, Bf, rtol=1e-6, atol=1e-8)


def test_current_moves_a_drifting_boat_with_the_water():
    x = np.zeros(6)
    for _ in range(6000):
        x = MODEL.step(x, [0, 0, 0, 0, 0], 0.01, current_ne=(0.0, 0.2))
    # after a minute the boat drifts east with the current (it may have turned: N_v yaws it) and has
    # no speed through the water
    c, s = np.cos(x[2]), np.sin(x[2])
    vel_ne = (x[3] * c - x[4] * s, x[3] * s + x[4] * c)
    assert vel_ne == pytest.approx((0.0, 0.2), abs=2e-3)
    assert x[1] > 9.0


def test_symbolic_model_equals_float_model():
    casadi = pytest.importorskip("casadi")
    from lotsen.model import symbolic_rhs

    f = symbolic_rhs(casadi)
    X = casadi.SX.sym("x", 6)
    U = casadi.SX.sym("u", 5)
    TH = casadi.SX.sym("th", len(MODEL.theta))
    F = casadi.Function("f", [X, U, TH], [casadi.vertcat(*f(casadi.vertsplit(X), casadi.vertsplit(U),
                                                               casadi.vertsplit(TH), MODEL.geom))])
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = rng.normal(size=6)
        u = np.concatenate([rng.uniform(-0.7, 0.7, 2), rng.uniform(-90, 90, 3)])
        assert np.allclose(np.array(F(x, u, MODEL.theta)).ravel(), MODEL.f(0, x, u), rtol=1e-12, atol=1e-12)


def test_wind_force_directions():
    from lotsen.model import Environment, wind_force

    from_west = Environment(wind_speed_mps=6.0, wind_from_deg=270.0)
    X, Y, N = wind_force(0.0, 0.0, 0.0, from_west)  # heading north: wind from port
    assert Y > 0 and abs(X) < 1e-9
    X, Y, N = wind_force(0.0, 1.0, 0.0, Environment())  # no wind: nothing, even when moving
    assert (X, Y, N) == (0.0, 0.0, 0.0)
    X, Y, N = wind_force(0.0, 0.0, 0.0, Environment(wind_speed_mps=6.0, wind_from_deg=0.0))  # head wind
    assert X < 0 and abs(Y) < 1e-9


def test_array_tau_is_the_simulators_thruster_force_on_arrays():
    """lotsen.model.array_tau (the equation-error regressors) runs the very thruster code on arrays of
    samples: the same forces as the float path, sample by sample, with astern thrust weaker too."""
    import dataclasses

    from lotsen.model import DEFAULT_GEOMETRY
    from lotsen.model.dynamics import array_tau, thruster_forces

    rng = np.random.default_rng(3)
    n = 40
    nu = [rng.uniform(-1, 1.5, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-0.6, 0.6, n)]
    inp = [rng.uniform(-0.7, 0.7, n), rng.uniform(-0.7, 0.7, n), rng.uniform(-100, 100, n),
           rng.uniform(-100, 100, n), rng.uniform(-80, 80, n)]
    theta = DEFAULT_PARAMETERS.to_vector()
    geom = dataclasses.replace(DEFAULT_GEOMETRY, reverse_thrust_ratio=0.8)
    tX, tY, tN = array_tau(nu, inp, theta, geom)
    for k in range(n):
        ref = thruster_forces([c[k] for c in nu], [c[k] for c in inp], theta, geom)
        np.testing.assert_allclose((tX[k], tY[k], tN[k]), ref, rtol=1e-12, atol=1e-12)
