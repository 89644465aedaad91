"""The model's named quantities in Fossen's notation, as the few float64 arrays the compiled code takes.

Kinetics (seed eq. 9, written out in eq. 22), on the velocity nu = [u, v, r] relative to the water:

    M nu_dot + C(nu) nu + D(nu) nu = tau(nu, u) + tau_ext

    M        = diag(m11, m22, m33)                      rigid body plus added mass (seed eq. 11)
    C(nu)    = [[0, 0, -m22 v], [0, 0, m11 u], [m22 v, -m11 u, 0]]      from M (seed eq. 12)
    D(nu)    = D_L + D_NL(nu)                                              (seed eq. 14)
    D_L      = [[X_u, 0, 0], [0, Y_v, Y_r], [0, N_v, N_r]]
    D_NL(nu) = -[[X_|u|u |u| + X_uuu u^2, 0, 0],      (X_uuu: an optional term, 0 = off)
                 [0, Y_|u|v |u| + Y_|v|v |v| + Y_|r|v |r|, 0],
                 [0, N_|v|v |v|, N_|r|r |r|]]
    tau      = the thruster forces of seed eq. (18-20) with the housing force (docs/model.md)

`ModelArrays` holds these, built once from `VesselParameters` and `VesselGeometry`; the compiled
kernels of the model, the simulator, the MPC and the EKF receive `ModelArrays.packed`, a plain
tuple of its five read-only arrays (numba takes a tuple of arrays as one argument at the cost of
a tuple of floats, and a named tuple at twice that). `packed_from_theta` builds the same tuple
from a parameter vector theta (seed eq. 26), of floats or of CasADi symbols (identification).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from lotsen.model.parameters import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters

N_THETA = len(VesselParameters.names())  # seed eq. (26)'s 18 and the optional terms
# entries of D_NL: the quadratic damping coefficients and the optional cubic surge term (negative,
# Fossen's sign convention)
DNL_NAMES = ("X_uu", "Y_uv", "Y_vv", "Y_rv", "N_vv", "N_rr", "X_uuu")
# entries of the thrust coefficients of tau(nu, u)
THRUST_NAMES = ("kappa", "half_rho_Ar_CN", "mu_az", "mu_t", "reverse_thrust_ratio")


def geometry_tuple(geom: VesselGeometry = DEFAULT_GEOMETRY) -> tuple[float, ...]:
    """(l_x1, l_y1, l_x2, l_y2, l_xt, 1/2 rho A_r, reverse_thrust_ratio): the geometry as identification
    keys its compiled functions."""
    return (geom.l_x1, geom.l_y1, geom.l_x2, geom.l_y2, geom.l_xt,
            0.5 * geom.rho_water * geom.rudder_area_m2, geom.reverse_thrust_ratio)


def _layout(theta: Sequence[Any], geom: Sequence[float]) -> tuple[list, ...]:
    """M, D_L, D_NL, thrust coefficients, thruster positions as nested lists of theta's entries."""
    (m11, m22, m33, X_u, X_uu, Y_v, Y_r, Y_uv, Y_vv, Y_rv, N_v, N_r, N_vv, N_rr,
     kappa, C_N, mu_az, mu_t, X_uuu) = theta
    l_x1, l_y1, l_x2, l_y2, l_xt, half_rho_Ar, rev = geom
    return ([[m11, 0.0, 0.0], [0.0, m22, 0.0], [0.0, 0.0, m33]],
            [[X_u, 0.0, 0.0], [0.0, Y_v, Y_r], [0.0, N_v, N_r]],
            [X_uu, Y_uv, Y_vv, Y_rv, N_vv, N_rr, X_uuu],
            [kappa, half_rho_Ar * C_N, mu_az, mu_t, rev],
            [[l_x1, l_y1], [l_x2, l_y2], [l_xt, 0.0]])


def _float_array(values: list) -> np.ndarray:
    a = np.array(values, dtype=np.float64)
    a.flags.writeable = False  # one compiled signature (read-only arrays) and no silent edits
    return a


def _object_array(values: list) -> np.ndarray:
    """An object array of symbols: indexes like the float arrays (a[1, 2]) without numpy looking inside."""
    shape = (len(values), len(values[0])) if isinstance(values[0], list) else (len(values),)
    a = np.empty(shape, dtype=object)
    for idx in np.ndindex(*shape):
        a[idx] = values[idx[0]][idx[1]] if len(shape) == 2 else values[idx[0]]
    return a


def packed_from_theta(theta: Sequence[Any], geom: Sequence[float], symbolic: bool = False) -> tuple[np.ndarray, ...]:
    """(M, D_L, D_NL, thrust, arms) for the kernels from theta (seed eq. 26) and `geometry_tuple`;
    `symbolic`: theta holds CasADi expressions (object arrays, for `symbolic_rhs`)."""
    if len(theta) != N_THETA:
        raise ValueError(f"expected {N_THETA} parameters theta, got {len(theta)}")
    make = _object_array if symbolic else _float_array
    if not symbolic:
        theta = [float(t) for t in theta]
    return tuple(make(v) for v in _layout(theta, geom))


@dataclass(frozen=True)
class ModelArrays:
    """M, D_L, D_NL, the thrust coefficients and the thruster positions of one vessel (module docstring).

    M (3x3, diagonal for this hull: port-starboard symmetric, origin amidships), D_L (3x3),
    D_NL (6: `DNL_NAMES`), thrust (5: `THRUST_NAMES`), arms (3x2: (l_x, l_y) of azimuth 1, azimuth 2
    and the bow thruster, body frame). The kernels read the diagonal of M.
    """

    M: np.ndarray
    D_L: np.ndarray
    D_NL: np.ndarray
    thrust: np.ndarray
    arms: np.ndarray
    packed: tuple[np.ndarray, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "packed", (self.M, self.D_L, self.D_NL, self.thrust, self.arms))

    @classmethod
    def build(cls, params: VesselParameters = DEFAULT_PARAMETERS,
              geometry: VesselGeometry = DEFAULT_GEOMETRY) -> "ModelArrays":
        return cls.from_theta(params.to_vector(), geometry)

    @classmethod
    def from_theta(cls, theta: Sequence[float], geometry: VesselGeometry = DEFAULT_GEOMETRY) -> "ModelArrays":
        return cls(*packed_from_theta(theta, geometry_tuple(geometry)))

    def coriolis(self, nu: Sequence[float]) -> np.ndarray:
        """C(nu) (seed eq. 12) of the diagonal M."""
        u, v = float(nu[0]), float(nu[1])
        m11, m22 = self.M[0, 0], self.M[1, 1]
        return np.array([[0.0, 0.0, -m22 * v], [0.0, 0.0, m11 * u], [m22 * v, -m11 * u, 0.0]])

    def damping(self, nu: Sequence[float]) -> np.ndarray:
        """D(nu) = D_L + D_NL(nu) (seed eq. 14)."""
        au, av, ar = (abs(float(s)) for s in nu[:3])
        X_uu, Y_uv, Y_vv, Y_rv, N_vv, N_rr, X_uuu = self.D_NL
        return self.D_L - np.array([[X_uu * au + X_uuu * au * au, 0.0, 0.0],
                                    [0.0, Y_uv * au + Y_vv * av + Y_rv * ar, 0.0],
                                    [0.0, N_vv * av, N_rr * ar]])
