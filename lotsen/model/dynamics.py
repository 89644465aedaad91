"""3-DOF vessel dynamics: thruster forces (seed eq. 19-20 with signed speeds and the housing
normal force of vessel-model.md), kinetics (seed eq. 22), kinematics (seed eq. 7-8), their
analytic Jacobians, and an RK4 step.

State x = [north, east, psi, u, v, r], input u = [alpha1, alpha2, n1, n2, nt] (rad, rev/s).
The equations are written once, on floats, in `_azimuth_force` and `_rhs`. They are compiled by
numba when available (simulation, MPC), and the very same code objects are re-bound to CasADi's
functions in `symbolic_rhs` (multiple-shooting identification), so no second copy can drift.

The compiled functions take the model as `mq`, the tuple `ModelArrays.packed` of its named
quantities M, D_L, D_NL, thrust coefficients and thruster positions (lotsen.model.quantities);
the float wrappers below take theta (seed eq. 26) and a `VesselGeometry`.
"""

from __future__ import annotations

import types
from dataclasses import dataclass
from math import cos, fabs, sin, sqrt
from typing import Any, Callable, Sequence

import numpy as np

from lotsen.model._jit import njit, py_func
from lotsen.model.parameters import (
    DEFAULT_GEOMETRY,
    DEFAULT_PARAMETERS,
    VesselGeometry,
    VesselParameters,
)
from lotsen.model.quantities import ModelArrays, geometry_tuple, packed_from_theta

STATE_NAMES = ("north", "east", "psi", "u", "v", "r")
INPUT_NAMES = ("alpha1", "alpha2", "n1", "n2", "nt")
NX, NU = 6, 5

# |w| is evaluated as sqrt(w.w + EPS_W2): smooth at w = 0 (CasADi gradients stay finite); the
# force changes by less than 1e-6 N for any speed of this vessel.
EPS_W2 = 1e-12


def _sign_py(x: float) -> float:
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


_sign = njit(_sign_py)


def _azimuth_force_py(a, n, lx, ly, u, v, r, kappa, g, mu_az, rev):  # type: ignore[no-untyped-def]
    """Force and moment of one azimuth unit (seed eq. 19 with n|n|, housing force of vessel-model.md).

        e = [cos a, sin a], e_perp = [-sin a, cos a]
        w = -[u - r l_y, v + r l_x] - kappa n e         water velocity relative to the housing
        F_N = 1/2 rho A_r C_N |w| (w . e_perp)           (g = 1/2 rho A_r C_N)
        F = mu_az n|n| e + F_N e_perp,  moment l_x F_y - l_y F_x
    """
    c = cos(a)
    s = sin(a)
    T = mu_az * n * fabs(n)
    if rev != 1.0:
        # asymmetric thrust (field notes: reverse is weaker): factor 1 for n > 0, rev for n < 0
        T = T * (0.5 * (1.0 + rev) + 0.5 * (1.0 - rev) * _sign(n))
    wx = -(u - r * ly) - kappa * n * c
    wy = -(v + r * lx) - kappa * n * s
    FN = g * sqrt(wx * wx + wy * wy + EPS_W2) * (-wx * s + wy * c)
    Fx = T * c - FN * s
    Fy = T * s + FN * c
    return Fx, Fy, lx * Fy - ly * Fx


_azimuth_force = njit(_azimuth_force_py)


def _tau_py(u, v, r, inp, mq):  # type: ignore[no-untyped-def]
    """tau = [tau_X, tau_Y, tau_N] of both azimuth units and the bow thruster (seed eq. 18-20)."""
    thrust = mq[3]
    arms = mq[4]
    kappa, g, mu_az, mu_t, rev = thrust  # g = 1/2 rho A_r C_N
    X1, Y1, N1 = _azimuth_force(inp[0], inp[2], arms[0, 0], arms[0, 1], u, v, r, kappa, g, mu_az, rev)
    X2, Y2, N2 = _azimuth_force(inp[1], inp[3], arms[1, 0], arms[1, 1], u, v, r, kappa, g, mu_az, rev)
    nt = inp[4]
    Ft = mu_t * nt * fabs(nt)  # bow tunnel thruster, seed eq. (20): pushes along +y for nt > 0
    return X1 + X2, Y1 + Y2 + Ft, N1 + N2 + arms[2, 0] * Ft


_tau = njit(_tau_py)


def _current_body_py(cos_psi, sin_psi, current_n, current_e):  # type: ignore[no-untyped-def]
    """The earth-frame current (north, east) in the body frame at heading psi: (u_c, v_c) = R(psi)^T c."""
    return current_n * cos_psi + current_e * sin_psi, -current_n * sin_psi + current_e * cos_psi


_current_body = njit(_current_body_py)


def _rhs_py(x, inp, mq, current_n, current_e, tau_x, tau_y, tau_n):  # type: ignore[no-untyped-def]
    """x_dot = f(x, u; theta): seed eq. (7-8) and (22).

    With a current (earth-frame velocity of the water, constant) the kinetics act on the relative
    velocity nu_r = nu - nu_c (Fossen 2021, sec. 10.3) and the kinematics on the ground velocity.
    tau_x, tau_y, tau_n add external (wind, wave) forces in the body frame.
    """
    M, D_L, D_NL, thrust, arms = mq
    m11, m22, m33 = M[0, 0], M[1, 1], M[2, 2]
    X_u, Y_v, Y_r, N_v, N_r = D_L[0, 0], D_L[1, 1], D_L[1, 2], D_L[2, 1], D_L[2, 2]
    X_uu, Y_uv, Y_vv, Y_rv, N_vv, N_rr, X_uuu = D_NL
    psi = x[2]
    u = x[3]
    v = x[4]
    r = x[5]
    cpsi = cos(psi)
    spsi = sin(psi)
    uc, vc = _current_body(cpsi, spsi, current_n, current_e)
    ur = u - uc
    vr = v - vc
    tX, tY, tN = _tau(ur, vr, r, inp, mq)
    tX = tX + tau_x
    tY = tY + tau_y
    tN = tN + tau_n
    au = fabs(ur)
    av = fabs(vr)
    ar = fabs(r)
    # seed eq. (22) on the relative velocity
    ur_dot = (m22 * vr * r - X_u * ur + X_uu * au * ur + X_uuu * ur * ur * ur + tX) / m11
    vr_dot = (-m11 * ur * r - Y_v * vr - Y_r * r + Y_uv * au * vr + Y_vv * av * vr + Y_rv * ar * vr + tY) / m22
    r_dot = ((m11 - m22) * ur * vr - N_v * vr + N_vv * av * vr - N_r * r + N_rr * ar * r + tN) / m33
    # d(nu_c)/dt = r [v_c, -u_c] for a current fixed in the earth frame; seed eq. (7-8) kinematics
    return (u * cpsi - v * spsi, u * spsi + v * cpsi, r, ur_dot + r * vc, vr_dot - r * uc, r_dot)


_rhs = njit(_rhs_py)


def _rk4_py(x, inp, mq, current_n, current_e, tau_x, tau_y, tau_n, dt):  # type: ignore[no-untyped-def]
    """One classical Runge-Kutta step with the input held (zero-order hold) over dt."""
    h = 0.5 * dt
    k1 = _rhs(x, inp, mq, current_n, current_e, tau_x, tau_y, tau_n)
    x2 = (x[0] + h * k1[0], x[1] + h * k1[1], x[2] + h * k1[2], x[3] + h * k1[3], x[4] + h * k1[4], x[5] + h * k1[5])
    k2 = _rhs(x2, inp, mq, current_n, current_e, tau_x, tau_y, tau_n)
    x3 = (x[0] + h * k2[0], x[1] + h * k2[1], x[2] + h * k2[2], x[3] + h * k2[3], x[4] + h * k2[4], x[5] + h * k2[5])
    k3 = _rhs(x3, inp, mq, current_n, current_e, tau_x, tau_y, tau_n)
    x4 = (x[0] + dt * k3[0], x[1] + dt * k3[1], x[2] + dt * k3[2], x[3] + dt * k3[3], x[4] + dt * k3[4], x[5] + dt * k3[5])
    k4 = _rhs(x4, inp, mq, current_n, current_e, tau_x, tau_y, tau_n)
    d = dt / 6.0
    return ((x[0] + d * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
             x[1] + d * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
             x[2] + d * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
             x[3] + d * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
             x[4] + d * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4]),
             x[5] + d * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5])), k1)


rk4_step = njit(_rk4_py)


def _jacobians_py(x, inp, mq):  # type: ignore[no-untyped-def]
    """A = df/dx (6x6), B = df/du (6x5) of `_rhs` in calm water, analytic.

    Where |u|, |v|, |r| meet zero the one-sided derivative at +0 is used.
    """
    M, D_L, D_NL, thrust, arms = mq
    m11, m22, m33 = M[0, 0], M[1, 1], M[2, 2]
    X_u, Y_v, Y_r, N_v, N_r = D_L[0, 0], D_L[1, 1], D_L[1, 2], D_L[2, 1], D_L[2, 2]
    X_uu, Y_uv, Y_vv, Y_rv, N_vv, N_rr, X_uuu = D_NL
    kappa, g, mu_az, mu_t, rev = thrust  # g = 1/2 rho A_r C_N
    psi = x[2]
    u = x[3]
    v = x[4]
    r = x[5]
    c = cos(psi)
    s = sin(psi)
    A = np.zeros((6, 6))
    B = np.zeros((6, 5))
    A[0, 2] = -u * s - v * c
    A[0, 3] = c
    A[0, 4] = -s
    A[1, 2] = u * c - v * s
    A[1, 3] = s
    A[1, 4] = c
    A[2, 5] = 1.0
    au = fabs(u)
    av = fabs(v)
    ar = fabs(r)
    su = 1.0 if u >= 0.0 else -1.0
    sr = 1.0 if r >= 0.0 else -1.0
    # d tau / d nu (rows X, Y, N; columns u, v, r) and d tau / d input
    Tn = np.zeros((3, 3))
    Ti = np.zeros((3, 5))
    for k in range(2):
        a = inp[k]
        n = inp[2 + k]
        lx = arms[k, 0]
        ly = arms[k, 1]
        ca = cos(a)
        sa = sin(a)
        factor = 1.0 if (n >= 0.0 or rev == 1.0) else rev
        T = mu_az * n * fabs(n) * factor
        dT_dn = 2.0 * mu_az * fabs(n) * factor
        wx = -(u - r * ly) - kappa * n * ca
        wy = -(v + r * lx) - kappa * n * sa
        wn = sqrt(wx * wx + wy * wy + EPS_W2)
        wp = -wx * sa + wy * ca  # w . e_perp
        we = wx * ca + wy * sa  # w . e
        FN = g * wn * wp
        # gradient of F_N with respect to w: g (w wp / |w| - ... ) = g (w wp/|w| + |w| e_perp)
        gx = g * (wx * wp / wn - wn * sa)
        gy = g * (wy * wp / wn + wn * ca)
        # d w / d(u, v, r, n) and d F_N / d(.)
        dFN_du = -gx
        dFN_dv = -gy
        dFN_dr = gx * ly - gy * lx
        dFN_dn = -kappa * (gx * ca + gy * sa)
        # alpha turns the slipstream (d w = -kappa n e_perp d alpha) and e_perp (d e_perp = -e d alpha)
        dFN_da = -kappa * n * (-gx * sa + gy * ca) - g * wn * we
        for j in range(3):
            dF = dFN_du if j == 0 else (dFN_dv if j == 1 else dFN_dr)
            dFx = -dF * sa
            dFy = dF * ca
            Tn[0, j] += dFx
            Tn[1, j] += dFy
            Tn[2, j] += lx * dFy - ly * dFx
        # d F / d n = dT/dn e + dF_N/dn e_perp
        dFx = dT_dn * ca - dFN_dn * sa
        dFy = dT_dn * sa + dFN_dn * ca
        Ti[0, 2 + k] = dFx
        Ti[1, 2 + k] = dFy
        Ti[2, 2 + k] = lx * dFy - ly * dFx
        # d F / d alpha = T e_perp + dF_N/d alpha e_perp - F_N e
        dFx = -(T + dFN_da) * sa - FN * ca
        dFy = (T + dFN_da) * ca - FN * sa
        Ti[0, k] = dFx
        Ti[1, k] = dFy
        Ti[2, k] = lx * dFy - ly * dFx
    dFt = 2.0 * mu_t * fabs(inp[4])
    Ti[1, 4] = dFt
    Ti[2, 4] = arms[2, 0] * dFt
    # seed eq. (22) differentiated
    A[3, 3] = (-X_u + 2.0 * X_uu * au + 3.0 * X_uuu * u * u + Tn[0, 0]) / m11
    A[3, 4] = (m22 * r + Tn[0, 1]) / m11
    A[3, 5] = (m22 * v + Tn[0, 2]) / m11
    A[4, 3] = (-m11 * r + Y_uv * su * v + Tn[1, 0]) / m22
    A[4, 4] = (-Y_v + Y_uv * au + 2.0 * Y_vv * av + Y_rv * ar + Tn[1, 1]) / m22
    A[4, 5] = (-m11 * u - Y_r + Y_rv * sr * v + Tn[1, 2]) / m22
    A[5, 3] = ((m11 - m22) * v + Tn[2, 0]) / m33
    A[5, 4] = ((m11 - m22) * u - N_v + 2.0 * N_vv * av + Tn[2, 1]) / m33
    A[5, 5] = (-N_r + 2.0 * N_rr * ar + Tn[2, 2]) / m33
    for j in range(5):
        B[3, j] = Ti[0, j] / m11
        B[4, j] = Ti[1, j] / m22
        B[5, j] = Ti[2, j] / m33
    return A, B


_jacobians = njit(_jacobians_py)


def _jacobians_current_py(x, inp, mq, current_n, current_e):  # type: ignore[no-untyped-def]
    """A = df/dx, B = df/du of `_rhs` with a constant earth-frame current (current_n, current_e), analytic.

    The kinetics act on nu_r = nu - nu_c(psi) with u_c = c_N cos psi + c_E sin psi,
    v_c = -c_N sin psi + c_E cos psi (so du_c/dpsi = v_c, dv_c/dpsi = -u_c), plus r [v_c, -u_c];
    the kinematics on the ground velocity. With zero current this is `_jacobians`.
    """
    psi = x[2]
    u = x[3]
    v = x[4]
    r = x[5]
    c = cos(psi)
    s = sin(psi)
    uc, vc = _current_body(c, s, current_n, current_e)
    A, B = _jacobians((x[0], x[1], psi, u - uc, v - vc, r), inp, mq)
    # kinematics on the ground velocity (the calm Jacobian above saw the relative one)
    A[0, 2] = -u * s - v * c
    A[1, 2] = u * c - v * s
    # d/dpsi through nu_c(psi) and the r [v_c, -u_c] terms; d/dr of r [v_c, -u_c]
    for i in range(3, 6):
        A[i, 2] = -A[i, 3] * vc + A[i, 4] * uc
    A[3, 2] += -r * uc
    A[4, 2] += -r * vc
    A[3, 5] += vc
    A[4, 5] += -uc
    return A, B


_jacobians_current = njit(_jacobians_current_py)


def _as_floats(seq: Sequence[float], n: int) -> tuple[float, ...]:
    t = tuple(float(s) for s in seq)
    if len(t) != n:
        raise ValueError(f"expected {n} values, got {len(t)}")
    return t


def _rhs_floats(x: Sequence[float], inp: Sequence[float], mq: tuple[np.ndarray, ...],
                current_ne: Sequence[float], tau_ext: Sequence[float]) -> tuple[float, ...]:
    return _rhs(_as_floats(x, NX), _as_floats(inp, NU), mq, float(current_ne[0]), float(current_ne[1]),
                float(tau_ext[0]), float(tau_ext[1]), float(tau_ext[2]))


def _tau_floats(nu: Sequence[float], inp: Sequence[float], mq: tuple[np.ndarray, ...]) -> tuple[float, float, float]:
    return _tau(float(nu[0]), float(nu[1]), float(nu[2]), _as_floats(inp, NU), mq)


def _jacobians_floats(x: Sequence[float], inp: Sequence[float], mq: tuple[np.ndarray, ...],
                      current_ne: Sequence[float] | None) -> tuple[np.ndarray, np.ndarray]:
    if current_ne is None:
        return _jacobians(_as_floats(x, NX), _as_floats(inp, NU), mq)
    return _jacobians_current(_as_floats(x, NX), _as_floats(inp, NU), mq, float(current_ne[0]), float(current_ne[1]))


def vessel_rhs(x: Sequence[float], inp: Sequence[float], theta: Sequence[float],
               geom: VesselGeometry = DEFAULT_GEOMETRY, current_ne: tuple[float, float] = (0.0, 0.0),
               tau_ext: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[float, ...]:
    """x_dot = f(x, u; theta) on floats (seed eq. 7-8, 22)."""
    return _rhs_floats(x, inp, packed_from_theta(theta, geometry_tuple(geom)), current_ne, tau_ext)


def thruster_forces(nu: Sequence[float], inp: Sequence[float], theta: Sequence[float],
                    geom: VesselGeometry = DEFAULT_GEOMETRY) -> tuple[float, float, float]:
    """tau = [tau_X, tau_Y, tau_N] for the velocity `nu` relative to the water."""
    return _tau_floats(nu, inp, packed_from_theta(theta, geometry_tuple(geom)))


def jacobians(x: Sequence[float], inp: Sequence[float], theta: Sequence[float],
              geom: VesselGeometry = DEFAULT_GEOMETRY,
              current_ne: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A = df/dx (6x6) and B = df/du (6x5), analytic (MPC, EKF, identification); in calm water, or
    with a constant earth-frame current `current_ne` (north, east, m/s)."""
    return _jacobians_floats(x, inp, packed_from_theta(theta, geometry_tuple(geom)), current_ne)


def _rebound(cos_: Any, sin_: Any, sqrt_: Any, fabs_: Any, sign_: Any) -> dict[str, Any]:
    """The equations' code objects (`_azimuth_force`, `_tau`, `_current_body`, `_rhs`) re-bound to other
    elementary functions: CasADi's (symbols) or numpy's (arrays of samples)."""
    ns = dict(globals())
    ns.update(cos=cos_, sin=sin_, sqrt=sqrt_, fabs=fabs_, _sign=sign_)
    for name, fn in (("_azimuth_force", _azimuth_force_py), ("_tau", _tau_py), ("_current_body", _current_body_py),
                     ("_rhs", _rhs_py)):
        ns[name] = types.FunctionType(py_func(fn).__code__, ns, name)
    return ns


def array_tau(nu: Sequence[np.ndarray], inp: Sequence[np.ndarray], theta: Sequence[float],
              geom: VesselGeometry = DEFAULT_GEOMETRY) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """tau = (tau_X, tau_Y, tau_N) of the thrusters (seed eq. 18-20) at arrays of samples: the same
    code as the simulator's, on numpy arrays (the regressors of lotsen.sysid.equation_error)."""
    tau = _rebound(np.cos, np.sin, np.sqrt, np.abs, np.sign)["_tau"]
    mq = packed_from_theta(theta, geometry_tuple(geom))
    return tuple(np.asarray(t, float) for t in tau(nu[0], nu[1], nu[2], inp, mq))  # type: ignore[return-value]


def symbolic_rhs(casadi_module: Any) -> Callable[..., Any]:
    """The same equations on CasADi symbols: f(x, u, theta, geom_tuple) -> list of 6 expressions.

    Re-binds the code objects of `_rhs`, `_tau`, `_azimuth_force`, `_current_body` to CasADi's cos/sin/sqrt/fabs,
    so identification differentiates exactly the model that the simulator integrates.
    `x`, `u`, `theta` are sequences of scalar CasADi expressions (e.g. `casadi.vertsplit(X)`).
    """
    ca = casadi_module
    rhs = _rebound(ca.cos, ca.sin, ca.sqrt, ca.fabs, ca.sign)["_rhs"]

    def f(x: Sequence[Any], u: Sequence[Any], theta: Sequence[Any], geom: tuple[float, ...],
          current_ne: tuple[Any, Any] = (0.0, 0.0), tau_ext: tuple[Any, Any, Any] = (0.0, 0.0, 0.0)) -> list[Any]:
        mq = packed_from_theta(theta, geom, symbolic=True)
        return list(rhs(x, u, mq, current_ne[0], current_ne[1], tau_ext[0], tau_ext[1], tau_ext[2]))

    return f


def surge_drag(p: VesselParameters, speed_mps: Any) -> Any:
    """The surge damping force at a steady speed through the water (seed eq. 22 at v = r = 0, with the
    optional cubic term): X_u U - X_|u|u |U| U - X_uuu U^3; floats or arrays. The one place the
    controllers' trims and fallbacks take it from."""
    return p.X_u * speed_mps - p.X_uu * abs(speed_mps) * speed_mps - p.X_uuu * speed_mps ** 3


@dataclass
class VesselModel:
    """A vessel: parameters + geometry, with numpy-facing f(t, x, u) and Jacobians.

    `arrays` holds its named quantities M, D_L, D_NL, thrust coefficients and thruster positions
    (`ModelArrays`); the compiled kernels take `arrays.packed`. `theta` and `geom` are the same
    vessel as the parameter vector and geometry tuple of identification."""

    params: VesselParameters = DEFAULT_PARAMETERS
    geometry: VesselGeometry = DEFAULT_GEOMETRY

    def __post_init__(self) -> None:
        self.theta = self.params.to_vector()
        self.geom = geometry_tuple(self.geometry)
        self.arrays = ModelArrays.build(self.params, self.geometry)

    def f(self, t: float, x: Sequence[float], u: Sequence[float],
          current_ne: tuple[float, float] = (0.0, 0.0),
          tau_ext: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
        """x_dot (python-control's f(t, x, u, params) signature, params bound)."""
        return np.array(_rhs_floats(x, u, self.arrays.packed, current_ne, tau_ext))

    def tau(self, nu: Sequence[float], u: Sequence[float]) -> np.ndarray:
        return np.array(_tau_floats(nu, u, self.arrays.packed))

    def jacobians(self, x: Sequence[float], u: Sequence[float],
                  current_ne: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
        return _jacobians_floats(x, u, self.arrays.packed, current_ne)

    def step(self, x: Sequence[float], u: Sequence[float], dt: float,
             current_ne: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
        """x(t + dt) by one RK4 step with u held."""
        x1, _ = rk4_step(_as_floats(x, NX), _as_floats(u, NU), self.arrays.packed,
                         float(current_ne[0]), float(current_ne[1]), 0.0, 0.0, 0.0, float(dt))
        return np.array(x1)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) every jitted function now: the first call costs
        0.1-0.3 s, which a live control loop must not pay when the operator presses AUTO."""
        x, u = (0.1,) * NX, (0.1,) * NU
        self.f(0.0, x, u)
        self.tau(x[3:], u)
        self.jacobians(x, u)
        self.jacobians(x, u, current_ne=(0.1, 0.1))
        self.step(x, u, 0.1)

    def kinetic_energy(self, nu: Sequence[float]) -> float:
        """1/2 nu^T M nu."""
        p = self.params
        return 0.5 * (p.m11 * nu[0] ** 2 + p.m22 * nu[1] ** 2 + p.m33 * nu[2] ** 2)

    def surge_thrust_for_speed(self, speed_mps: float) -> float:
        """Steady straight-ahead thrust that balances drag: X_u U - X_|u|u |U| U - X_uuu U^3."""
        return float(surge_drag(self.params, speed_mps))

    def propeller_speed_for_surge(self, speed_mps: float) -> float:
        """Equal azimuth speeds (alpha = 0) for a steady surge speed; the housing force is zero there."""
        T = self.surge_thrust_for_speed(speed_mps) / 2.0
        if T >= 0:
            return float(np.sqrt(T / self.params.mu_az))
        return -float(np.sqrt(-T / (self.params.mu_az * self.geometry.reverse_thrust_ratio)))

    def max_surge_speed(self, n_max_rps: float) -> float:
        """U_max: both azimuths at n_max straight ahead against the drag X_u U - X_|u|u U^2 - X_uuu U^3."""
        p = self.params
        T = 2.0 * p.mu_az * n_max_rps ** 2
        a, b = -p.X_uu, p.X_u
        U = float((-b + np.sqrt(b * b + 4 * a * T)) / (2 * a)) if a > 0 else T / b
        if p.X_uuu == 0.0:
            return U
        lo, hi = 0.0, U  # the cubic term only adds drag: the root lies below the quadratic one
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if surge_drag(p, mid) < T else (lo, mid)
        return 0.5 * (lo + hi)
