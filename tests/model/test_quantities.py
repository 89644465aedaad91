"""The named model quantities (M, C(nu), D(nu), tau) reproduce the model the kernels integrate."""

from __future__ import annotations

import numpy as np
import pytest

from lotsen.model import DEFAULT_PARAMETERS, ModelArrays, VesselGeometry, VesselModel, VesselParameters
from lotsen.model.quantities import packed_from_theta

PARAMS = VesselParameters(m11=13.0, m22=26.0, m33=2.1, X_u=3.0, X_uu=-6.0, Y_v=10.0, Y_r=1.4, Y_uv=-7.0,
                          Y_vv=-35.0, Y_rv=-2.5, N_v=0.7, N_r=2.6, N_vv=-1.2, N_rr=-1.7, kappa=0.03, C_N=1.3,
                          mu_az=0.0012, mu_t=0.0005, X_uuu=-2.0)  # the optional cubic term on
MODEL = VesselModel(PARAMS, VesselGeometry(reverse_thrust_ratio=0.7))


def _samples(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 6)) * [5.0, 5.0, 2.0, 0.8, 0.3, 0.4]
    u = rng.uniform(-1, 1, size=(n, 5)) * [0.7, 0.7, 90.0, 90.0, 70.0]
    return x, u


def _kinetics(q: ModelArrays, nu: np.ndarray, u: np.ndarray, tau_ext: np.ndarray) -> np.ndarray:
    """nu_dot from M nu_dot + C(nu) nu + D(nu) nu = tau(nu, u) + tau_ext, in matrix form."""
    tau = MODEL.tau(nu, u) + tau_ext
    return np.linalg.solve(q.M, tau - q.coriolis(nu) @ nu - q.damping(nu) @ nu)


def test_the_record_names_the_parameters():
    q = MODEL.arrays
    p, g = PARAMS, MODEL.geometry
    np.testing.assert_array_equal(q.M, np.diag([p.m11, p.m22, p.m33]))
    np.testing.assert_array_equal(q.D_L, [[p.X_u, 0, 0], [0, p.Y_v, p.Y_r], [0, p.N_v, p.N_r]])
    np.testing.assert_array_equal(q.D_NL, [p.X_uu, p.Y_uv, p.Y_vv, p.Y_rv, p.N_vv, p.N_rr, p.X_uuu])
    np.testing.assert_array_equal(q.thrust, [p.kappa, 0.5 * g.rho_water * g.rudder_area_m2 * p.C_N, p.mu_az,
                                             p.mu_t, 0.7])
    np.testing.assert_array_equal(q.arms, [[g.l_x1, g.l_y1], [g.l_x2, g.l_y2], [g.l_xt, 0.0]])
    assert q.packed == (q.M, q.D_L, q.D_NL, q.thrust, q.arms)
    for a in q.packed:
        assert a.dtype == np.float64 and not a.flags.writeable  # one compiled signature, no silent edits
    with pytest.raises(ValueError):
        q.M[0, 0] = 1.0


def test_fossen_form_reproduces_the_model():
    """M nu_dot + C(nu) nu + D(nu) nu = tau + tau_ext holds for the model's own nu_dot (calm water)."""
    x, u = _samples(200, 1)
    rng = np.random.default_rng(2)
    worst = 0.0
    for xi, ui in zip(x, u):
        tau_ext = rng.normal(size=3)
        f = MODEL.f(0.0, xi, ui, tau_ext=tuple(tau_ext))
        nu_dot = _kinetics(MODEL.arrays, xi[3:], ui, tau_ext)
        worst = max(worst, float(np.max(np.abs(f[3:] - nu_dot) / (1.0 + np.abs(f[3:])))))
    assert worst < 1e-12


def test_damping_dissipates_energy():
    """nu^T C(nu) nu = 0 (C skew) and nu^T D(nu) nu > 0 for the signed coefficients of the defaults."""
    q = ModelArrays.build(DEFAULT_PARAMETERS.with_updates(X_uuu=-2.0))
    x, _ = _samples(100, 3)
    for nu in x[:, 3:]:
        assert abs(nu @ q.coriolis(nu) @ nu) < 1e-12
        assert nu @ q.damping(nu) @ nu > 0.0


def test_analytic_linearisation_matches_finite_differences_of_the_fossen_form():
    """The kernels' d nu_dot / d nu (Jacobian rows 3-5) against central differences of the matrix form."""
    x, u = _samples(30, 4)
    h = 1e-6
    zero = np.zeros(3)
    for xi, ui in zip(x, u):
        A, _ = MODEL.jacobians(xi, ui)
        fd = np.empty((3, 3))
        for j in range(3):
            e = np.zeros(3)
            e[j] = h
            fd[:, j] = (_kinetics(MODEL.arrays, xi[3:] + e, ui, zero)
                        - _kinetics(MODEL.arrays, xi[3:] - e, ui, zero)) / (2 * h)
        np.testing.assert_allclose(A[3:6, 3:6], fd, rtol=1e-5, atol=1e-6)


def test_symbolic_layout_matches_the_float_one():
    """`packed_from_theta` lays symbols out exactly as floats (identification's CasADi path)."""
    theta = PARAMS.to_vector()
    geom = MODEL.geom
    floats = packed_from_theta(theta, geom)
    objects = packed_from_theta(list(theta), geom, symbolic=True)
    for a, b in zip(floats, objects):
        assert b.dtype == object and a.shape == b.shape
        np.testing.assert_array_equal(a, b.astype(float))
    with pytest.raises(ValueError):
        packed_from_theta(theta[:17], geom)
