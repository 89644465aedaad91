"""Parametric cubic segments between two route nodes (seed eqs. 38-40), vectorised with numpy.

Coordinates are local NED metres: x = north, y = east. A heading psi (radians, 0 = north,
positive clockwise) has the unit tangent (cos psi, sin psi) in (north, east).

The seed writes the segment as x(delta) = alpha_1 + alpha_2 delta + alpha_3 delta^2 + alpha_4 delta^3
and y(delta) likewise with beta (eqs. 38-39). Fixing both end positions (40a-d) and both end
heading *directions* (40e-f) leaves two degrees of freedom: the tangent magnitudes ``a`` at
delta = 0 and ``b`` at delta = 1 (cubic Hermite form). The seed varies alpha_3/beta_3 by +-1;
here (a, b) are searched continuously, which spans exactly the same family of cubics.
"""

from __future__ import annotations

import numpy as np


def unit_tangent(heading_rad: float | np.ndarray) -> np.ndarray:
    """(north, east) unit vector of a NED heading (0 = north, clockwise positive)."""
    heading_rad = np.asarray(heading_rad, dtype=float)
    return np.stack([np.cos(heading_rad), np.sin(heading_rad)], axis=-1)


def hermite_coefficients(
    p0: np.ndarray, p1: np.ndarray, t0: np.ndarray, t1: np.ndarray, a: np.ndarray, b: np.ndarray
) -> np.ndarray:
    """Monomial coefficients [alpha; beta] of the cubics, shape (..., 4, 2).

    p0, p1: end positions (2,); t0, t1: unit end tangents (2,); a, b: tangent magnitudes
    (any broadcastable shape, metres per unit delta). Row j of the result multiplies delta^j,
    column 0 is north (alpha_{j+1}, eq. 38), column 1 east (beta_{j+1}, eq. 39).
    """
    a = np.asarray(a, dtype=float)[..., None]
    b = np.asarray(b, dtype=float)[..., None]
    dp = p1 - p0
    c0 = np.broadcast_to(p0, a.shape[:-1] + (2,))                 # 40a, 40c: r(0) = P_k
    c1 = a * t0                                                    # 40e: r'(0) parallel to rho_k
    c2 = 3.0 * dp - 2.0 * a * t0 - b * t1                          # 40b, 40d, 40f solved
    c3 = -2.0 * dp + a * t0 + b * t1
    return np.stack([c0, c1, c2, c3], axis=-2)


def evaluate(coef: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, first and second derivative w.r.t. delta; each of shape (..., m, 2)."""
    d = np.asarray(delta, dtype=float)[:, None]
    c0, c1, c2, c3 = (coef[..., j, None, :] for j in range(4))
    r = c0 + d * (c1 + d * (c2 + d * c3))
    dr = c1 + d * (2.0 * c2 + d * 3.0 * c3)
    ddr = 2.0 * c2 + 6.0 * d * c3
    return r, dr, ddr


def curvature(dr: np.ndarray, ddr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed curvature (1/m, positive = turning to starboard) and speed |r'| (seed eq. 40h).

    kappa = (x' y'' - y' x'') / (x'^2 + y'^2)^(3/2) with x = north, y = east, which is
    d(psi)/ds for the clockwise NED heading psi = atan2(y', x').
    """
    speed = np.hypot(dr[..., 0], dr[..., 1])
    cross = dr[..., 0] * ddr[..., 1] - dr[..., 1] * ddr[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = cross / speed**3
    kappa = np.where(speed > 1e-12, kappa, np.inf)
    return kappa, speed


def heading(dr: np.ndarray) -> np.ndarray:
    """NED heading psi = atan2(east', north') of the tangent, radians in (-pi, pi]."""
    return np.arctan2(dr[..., 1], dr[..., 0])
