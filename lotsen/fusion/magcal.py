"""Planar magnetometer calibration (seed section 3.3): ellipse fit of one full turn.

Model of the measured horizontal field (as in `lotsen.sim.sensors.MagnetometerModel`):

    m = M w + c,    |w| = 1,  w = [cos(psi - d), -sin(psi - d)]

with `c` the hard-iron offset (ellipse centre) and `M` the symmetric positive definite 2x2
soft-iron matrix that maps the unit circle onto the ellipse (it absorbs the field strength, so
the calibrated field `w = inv(M) (m - c)` has unit norm). Heading = atan2(-w_y, w_x) + d.

What one turn can and cannot tell:
- `c` and the symmetric `M` (3 numbers: two semi-axes and the axis rotation) are determined.
- A pure rotation of the whole picture, i.e. `M R` with R a rotation, fits the same ellipse:
  it is a constant heading offset (mounting misalignment, declination) and is NOT observable from
  the magnetometer alone. It is the separate parameter `heading_offset_rad` (default 0; set it
  from the local declination and/or a GNSS-course comparison at speed).
- Any overall scale of `M` is absorbed by the unit-norm convention.

Algorithm: algebraic least-squares conic fit (Fitzgibbon's direct ellipse fit with the
ellipse constraint 4AC - B^2 = 1, solved as a generalised eigenproblem with scipy), then
centre and M = Q^(-1/2) from the conic's quadratic form Q. Data quality is checked before a
result is returned: enough finite points, an ellipse (not a hyperbola), and angular coverage
around the fitted centre (a half turn pins neither the centre nor the axes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
import scipy.linalg

from lotsen.errors import DataError
from lotsen.fusion.common import wrap_angle
from lotsen.messages import MagCalibrated, MagSample
from lotsen.settings import Number


class CalibrationError(DataError):
    """Magnetometer data cannot give a calibration (too few points, too little of a turn, ...)."""


# what a calibration file's numbers may be: a field in any unit (uT ~50, raw counts, nT ~5e4)
_FIELD = Number(-1e7, 1e7)
_RMS = Number(0.0, 10.0)
_COVERAGE = Number(0.0, 360.0, "deg")
_POINTS = Number(0, 10**9, integer=True)
_OFFSET = Number(-2 * math.pi, 2 * math.pi, "rad")


@dataclass(frozen=True)
class MagCalibration:
    """Hard iron `center` (2, raw units), soft iron `matrix` (2x2, symmetric, raw units per unit
    field), fit quality, and the separately set heading offset (declination + mounting, rad)."""

    center: tuple[float, float]
    matrix: tuple[tuple[float, float], tuple[float, float]]
    residual_rms: float = float("nan")  # RMS of |w| - 1 over the fitted points (unit-less)
    coverage_deg: float = float("nan")  # angular coverage of the points around the centre
    n_points: int = 0
    heading_offset_rad: float = 0.0  # NOT from the fit: declination / mounting offset
    units: str = ""

    def __post_init__(self) -> None:
        M = np.asarray(self.matrix, dtype=float)
        if M.shape != (2, 2) or not np.all(np.isfinite(M)) or np.linalg.det(M) <= 0.0:
            raise CalibrationError(f"magnetometer calibration: matrix {self.matrix} must be a finite "
                                   "2x2 matrix with positive determinant")
        if len(self.center) != 2 or not all(math.isfinite(v) for v in self.center):
            raise CalibrationError(f"magnetometer calibration: center {self.center} must be 2 finite numbers")
        # cached inverse for the per-sample path (plain floats are faster than numpy here)
        Mi = np.linalg.inv(M)
        object.__setattr__(self, "_inv", (float(Mi[0, 0]), float(Mi[0, 1]), float(Mi[1, 0]), float(Mi[1, 1])))

    @classmethod
    def identity(cls) -> "MagCalibration":
        return cls(center=(0.0, 0.0), matrix=((1.0, 0.0), (0.0, 1.0)))

    @property
    def radius(self) -> float:
        """Mean field strength in raw units (sqrt(det M))."""
        return math.sqrt(float(np.linalg.det(np.asarray(self.matrix))))

    def apply(self, mx: float, my: float) -> tuple[float, float]:
        """Calibrated, unit-norm horizontal field w = inv(M) (m - c)."""
        a, b, c, d = self._inv  # type: ignore[attr-defined]
        x, y = mx - self.center[0], my - self.center[1]
        return (a * x + b * y, c * x + d * y)

    def heading(self, mx: float, my: float) -> float:
        """Heading (rad, clockwise from north, in (-pi, pi]) from a raw measurement."""
        wx, wy = self.apply(mx, my)
        return wrap_angle(math.atan2(-wy, wx) + self.heading_offset_rad)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (strict JSON has no NaN: an unknown fit quality is null)."""
        def known(v: float) -> float | None:
            return v if math.isfinite(v) else None

        return {"center": list(self.center), "matrix": [list(r) for r in self.matrix],
                "residual_rms": known(self.residual_rms), "coverage_deg": known(self.coverage_deg),
                "n_points": self.n_points, "heading_offset_rad": self.heading_offset_rad,
                "units": self.units}

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str = "calibration") -> "MagCalibration":
        """A calibration file's content; every number finite and in its range (settings.Number)."""
        if not isinstance(d, dict):
            raise CalibrationError(f"{where}: expected a JSON object with 'center' and 'matrix'")
        known = {"center", "matrix", "residual_rms", "coverage_deg", "n_points", "heading_offset_rad", "units"}
        unknown = set(d) - known
        if unknown:
            raise CalibrationError(f"{where}: unknown keys {sorted(map(str, unknown))[:5]}")
        c, m = d.get("center"), d.get("matrix")
        if not (isinstance(c, list) and len(c) == 2 and isinstance(m, list) and len(m) == 2
                and all(isinstance(r, list) and len(r) == 2 for r in m)):
            raise CalibrationError(f"{where}: needs 'center' (2 numbers) and 'matrix' (2x2 numbers)")
        center = tuple(_FIELD.check(v, f"{where}: center[{i}]", CalibrationError) for i, v in enumerate(c))
        matrix = tuple(tuple(_FIELD.check(v, f"{where}: matrix[{i}][{j}]", CalibrationError) for j, v in enumerate(r))
                       for i, r in enumerate(m))
        rms = d.get("residual_rms")
        cov = d.get("coverage_deg")
        units = d.get("units", "")
        if not isinstance(units, str):
            raise CalibrationError(f"{where}: units: expected text, got {units!r:.40}")
        return cls(center=center, matrix=matrix,  # type: ignore[arg-type]
                   residual_rms=float("nan") if rms is None else _RMS.check(rms, f"{where}: residual_rms", CalibrationError),
                   coverage_deg=float("nan") if cov is None else _COVERAGE.check(cov, f"{where}: coverage_deg",
                                                                                 CalibrationError),
                   n_points=_POINTS.check(d.get("n_points", 0), f"{where}: n_points", CalibrationError),
                   heading_offset_rad=_OFFSET.check(d.get("heading_offset_rad", 0.0), f"{where}: heading_offset_rad",
                                                    CalibrationError),
                   units=units[:40])


@dataclass(frozen=True)
class CalibrationLimits:
    min_points: int = 30
    min_coverage_deg: float = 300.0
    max_residual_rms: float = 0.25  # |w| - 1; larger means the data are not an ellipse (disturbed)


def _direct_ellipse_fit(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Conic coefficients [A, B, C, D, E, F] of A x^2 + B xy + C y^2 + D x + E y + F = 0,
    least squares under 4AC - B^2 = 1 (Fitzgibbon, Pilu & Fisher 1999, the numerically stable
    split form of Halir & Flusser 1998)."""
    D1 = np.column_stack([x * x, x * y, y * y])
    D2 = np.column_stack([x, y, np.ones_like(x)])
    S1, S2, S3 = D1.T @ D1, D1.T @ D2, D2.T @ D2
    try:
        T = -np.linalg.solve(S3, S2.T)
    except np.linalg.LinAlgError:
        raise CalibrationError("magnetometer calibration: degenerate data (all points on a line or equal)") from None
    with np.errstate(all="ignore"):
        Mred = S1 + S2 @ T
    C1 = np.array([[0.0, 0.0, 2.0], [0.0, -1.0, 0.0], [2.0, 0.0, 0.0]])
    if not (np.all(np.isfinite(T)) and np.all(np.isfinite(Mred))):  # nearly singular: points (nearly) on a line
        raise CalibrationError("magnetometer calibration: degenerate data (all points on a line or equal)")
    try:
        w, V = scipy.linalg.eig(Mred, C1)
    except (ValueError, np.linalg.LinAlgError, scipy.linalg.LinAlgError):
        raise CalibrationError("magnetometer calibration: degenerate data (the ellipse fit has no solution)") from None
    V = np.real(V)
    cond = 4.0 * V[0] * V[2] - V[1] ** 2
    ok = np.where((cond > 0) & np.isfinite(np.real(w)))[0]
    if ok.size == 0:
        raise CalibrationError("magnetometer calibration: the points do not lie on an ellipse "
                               "(not a full turn, or a strongly disturbed field)")
    # the ellipse solution is the one with positive constraint value (exactly one in theory)
    a1 = V[:, ok[np.argmin(np.abs(np.real(w[ok])))]]
    return np.concatenate([a1, T @ a1])


def coverage_deg(wx: np.ndarray, wy: np.ndarray) -> float:
    """360 deg minus the largest angular gap between the points seen from the origin."""
    ang = np.sort(np.arctan2(wy, wx))
    if ang.size < 2:
        return 0.0
    gaps = np.diff(np.concatenate([ang, [ang[0] + 2.0 * math.pi]]))
    return float(math.degrees(2.0 * math.pi - gaps.max()))


def fit_mag_calibration(mag_x: Sequence[float], mag_y: Sequence[float],
                        limits: CalibrationLimits = CalibrationLimits(),
                        heading_offset_rad: float = 0.0, units: str = "") -> MagCalibration:
    """Fit centre and soft-iron matrix to raw horizontal field samples of (at least) one turn.

    Non-finite samples are dropped. Raises CalibrationError if fewer than `limits.min_points`
    remain, if the best conic is not an ellipse, if the coverage around the fitted centre is below
    `limits.min_coverage_deg`, or if the RMS of |w| - 1 exceeds `limits.max_residual_rms`.
    """
    x = np.asarray(mag_x, dtype=float).ravel()
    y = np.asarray(mag_y, dtype=float).ravel()
    if x.shape != y.shape:
        raise CalibrationError(f"magnetometer calibration: {x.size} mag_x but {y.size} mag_y values")
    good = np.isfinite(x) & np.isfinite(y)
    x, y = x[good], y[good]
    if x.size < limits.min_points:
        raise CalibrationError(f"magnetometer calibration: {x.size} finite points, need at least "
                               f"{limits.min_points} from one full turn")
    # centre and scale the data so the normal equations are well conditioned in any units
    mx, my = x.mean(), y.mean()
    s = float(np.sqrt(np.mean((x - mx) ** 2 + (y - my) ** 2)))
    if not s > 0.0:
        raise CalibrationError("magnetometer calibration: all points are equal (no turn?)")
    xs, ys = (x - mx) / s, (y - my) / s
    A, B, C, D, E, F = _direct_ellipse_fit(xs, ys)
    Q = np.array([[A, B / 2.0], [B / 2.0, C]])
    try:
        c_s = np.linalg.solve(2.0 * Q, -np.array([D, E]))  # gradient zero at the centre
    except np.linalg.LinAlgError:
        raise CalibrationError("magnetometer calibration: the fitted conic has no centre (not an ellipse)") from None
    with np.errstate(all="ignore"):
        k = float(c_s @ Q @ c_s - F)  # (p - c)' Q (p - c) = k
    if k == 0.0 or not math.isfinite(k):
        raise CalibrationError("magnetometer calibration: the fitted conic is degenerate")
    Qn = Q / k  # (p - c)' Qn (p - c) = 1; the eigenvector's sign is arbitrary, k carries it
    if not np.all(np.isfinite(Qn)):
        raise CalibrationError("magnetometer calibration: the fitted conic is degenerate")
    evals, evecs = np.linalg.eigh(Qn)
    if evals.min() <= 0.0:
        raise CalibrationError("magnetometer calibration: the points do not lie on an ellipse")
    # M = Qn^(-1/2): symmetric, maps the unit circle onto the ellipse (M Qn M = I)
    M_s = evecs @ np.diag(1.0 / np.sqrt(evals)) @ evecs.T
    center = np.array([mx, my]) + s * c_s
    M = s * M_s
    W = np.linalg.solve(M, np.vstack([x - center[0], y - center[1]]))
    cov = coverage_deg(W[0], W[1])
    if cov < limits.min_coverage_deg:
        raise CalibrationError(f"magnetometer calibration: the data cover {cov:.0f} deg of the turn around "
                               f"the fitted centre, need {limits.min_coverage_deg:.0f} deg: turn the boat "
                               "one full turn (slowly, level, away from steel)")
    resid = float(np.sqrt(np.mean((np.hypot(W[0], W[1]) - 1.0) ** 2)))
    if resid > limits.max_residual_rms:
        raise CalibrationError(f"magnetometer calibration: residual RMS {resid:.3f} of the unit circle exceeds "
                               f"{limits.max_residual_rms}: the field is disturbed or not planar")
    Msym = 0.5 * (M + M.T)
    return MagCalibration(center=(float(center[0]), float(center[1])),
                          matrix=((float(Msym[0, 0]), float(Msym[0, 1])), (float(Msym[1, 0]), float(Msym[1, 1]))),
                          residual_rms=resid, coverage_deg=cov, n_points=int(x.size),
                          heading_offset_rad=heading_offset_rad, units=units)


def calibrated_heading(mag_sample: MagSample, calibration: MagCalibration) -> MagCalibrated | None:
    """imu/mag -> imu/mag_calibrated: calibrated unit field and heading of one raw sample.

    The calibrated vector is rotated by `heading_offset_rad` too, so that the message's invariant
    heading_rad = atan2(-mag_y, mag_x) holds (with offset 0 this is the magnetic heading).
    Returns None for a non-finite sample (skipped, never propagated).
    """
    mx, my = mag_sample.field_uT[0], mag_sample.field_uT[1]
    if not (math.isfinite(mx) and math.isfinite(my) and math.isfinite(mag_sample.stamp_s)):
        return None
    wx, wy = calibration.apply(mx, my)
    off = calibration.heading_offset_rad
    if off:
        # heading = atan2(-y, x) grows clockwise: adding `off` rotates (x, y) by -off in the xy plane
        co, so = math.cos(off), math.sin(off)
        wx, wy = co * wx + so * wy, -so * wx + co * wy
    return MagCalibrated(stamp_s=mag_sample.stamp_s, mag_x=wx, mag_y=wy, heading_rad=math.atan2(-wy, wx))
