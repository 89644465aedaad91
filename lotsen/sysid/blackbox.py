"""Black-box alternative: a NARX model of the body velocities with the known kinematics.

Body velocities are not measured, so they are derived from the data: the ground velocity from a
central difference of the GNSS positions, rotated into the body frame by the measured heading,
and r from the gyro. A one-step model, linear in its parameters, is fitted by least squares:

    nu_{k+1} = nu_k + dt_k * Theta^T phi(nu_k, u_k)
    phi = [u, v, r, |u|u, |v|v, |r|r, u r, v r, u v, thrust features of seed eq. (19-20): sum n|n| cos a,
           sum n|n| sin a, yaw moment of the azimuths, nt|nt|, 1]

(a physics-agnostic regression on physically motivated features, no hull-model structure).
The validation simulates it over the same windows as the grey-box model (from the measured
initial position and heading and the derived initial velocity), with the same kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, VesselGeometry
from lotsen.sysid.data import IdRecord, Segment, split_segments, split_windows
from lotsen.model.angles import wrap_angle
from lotsen.sysid.validate import OutputFit, fit_percent


def _features(nu: np.ndarray, u: np.ndarray, geom: VesselGeometry) -> np.ndarray:
    uu, vv, rr = nu[..., 0], nu[..., 1], nu[..., 2]
    a1, a2, n1, n2, nt = (u[..., i] for i in range(5))
    T1, T2 = n1 * np.abs(n1), n2 * np.abs(n2)
    X = T1 * np.cos(a1) + T2 * np.cos(a2)
    Y = T1 * np.sin(a1) + T2 * np.sin(a2)
    N = (geom.l_x1 * T1 * np.sin(a1) - geom.l_y1 * T1 * np.cos(a1)
         + geom.l_x2 * T2 * np.sin(a2) - geom.l_y2 * T2 * np.cos(a2))
    Tt = nt * np.abs(nt)
    return np.stack([uu, vv, rr, np.abs(uu) * uu, np.abs(vv) * vv, np.abs(rr) * rr, uu * rr, vv * rr, uu * vv,
                     X, Y, N, Tt, np.ones_like(uu)], axis=-1)


def _output_rows(seg: Segment) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows with all outputs measured: times, inputs held at them, outputs [N, E, psi, r]."""
    names = seg.output_names
    idx = [names.index(n) for n in ("north", "east", "psi", "r")]
    ok = np.all(np.isfinite(seg.outputs[:, idx]), axis=1)
    return seg.t[ok], seg.inputs[ok], seg.outputs[ok][:, idx]


def _body_velocity(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    vn = np.gradient(y[:, 0], t)
    ve = np.gradient(y[:, 1], t)
    psi = y[:, 2]
    u = np.cos(psi) * vn + np.sin(psi) * ve
    v = -np.sin(psi) * vn + np.cos(psi) * ve
    return np.column_stack([u, v, y[:, 3]])


@dataclass
class NarxModel:
    theta: np.ndarray  # n_features x 3
    geometry: VesselGeometry = DEFAULT_GEOMETRY

    def step(self, nu: np.ndarray, u: np.ndarray, dt: float) -> np.ndarray:
        return nu + dt * (_features(nu, u, self.geometry) @ self.theta)

    def simulate(self, t: np.ndarray, U: np.ndarray, x0: np.ndarray) -> np.ndarray:
        """States [N, E, psi, u, v, r] at t, forward Euler on the velocity model, trapezoid on the kinematics."""
        X = np.empty((len(t), 6))
        X[0] = x0
        for k in range(len(t) - 1):
            dt = t[k + 1] - t[k]
            nu = X[k, 3:]
            nu1 = self.step(nu, U[k], dt)
            if not np.all(np.isfinite(nu1)) or np.any(np.abs(nu1) > 50):
                X[k + 1:] = np.nan
                break
            psi1 = X[k, 2] + 0.5 * dt * (nu[2] + nu1[2])
            c0, s0, c1, s1 = np.cos(X[k, 2]), np.sin(X[k, 2]), np.cos(psi1), np.sin(psi1)
            X[k + 1, 0] = X[k, 0] + 0.5 * dt * ((c0 * nu[0] - s0 * nu[1]) + (c1 * nu1[0] - s1 * nu1[1]))
            X[k + 1, 1] = X[k, 1] + 0.5 * dt * ((s0 * nu[0] + c0 * nu[1]) + (s1 * nu1[0] + c1 * nu1[1]))
            X[k + 1, 2] = psi1
            X[k + 1, 3:] = nu1
        return X


def fit_narx(records: Sequence[IdRecord], gap_s: float = 1.0, ridge: float = 1e-6,
             geometry: VesselGeometry = DEFAULT_GEOMETRY) -> NarxModel:
    Phi, Yd = [], []
    for rec in records:
        for seg in split_segments(rec, gap_s):
            t, U, y = _output_rows(seg)
            if len(t) < 5:
                continue
            nu = _body_velocity(t, y)
            dt = np.diff(t)
            Phi.append(_features(nu[:-1], U[:-1], geometry))
            Yd.append((nu[1:] - nu[:-1]) / dt[:, None])
    if not Phi:
        from lotsen.sysid.estimate import EstimationError

        raise EstimationError("no data for the black-box model (need rows with north, east, psi, r)")
    A = np.vstack(Phi)
    B = np.vstack(Yd)
    scale = np.maximum(np.abs(A).max(axis=0), 1e-9)
    As = A / scale
    theta = np.linalg.solve(As.T @ As + ridge * len(As) * np.eye(As.shape[1]), As.T @ B) / scale[:, None]
    return NarxModel(theta, geometry)


def narx_fit(model: NarxModel, records: Sequence[IdRecord], window_s: float = 10.0, gap_s: float = 1.0) -> OutputFit:
    """Simulation fit of the NARX model over the same windows as the grey-box validation."""
    ts, ys, yh, starts = [], [], [], []
    for rec in records:
        for w in split_windows(split_segments(rec, gap_s), window_s):
            t, U, y = _output_rows(w)
            if len(t) < 3:
                continue
            nu = _body_velocity(t, y)
            x0 = np.array([y[0, 0], y[0, 1], y[0, 2], *nu[0]])
            X = model.simulate(t, U, x0)
            ts.append(t)
            ys.append(y)
            yh.append(np.column_stack([X[:, 0], X[:, 1], wrap_angle(X[:, 2]), X[:, 5]]))
            starts.append(t[0])
    names = ("north", "east", "psi", "r")
    if not ts:
        return OutputFit(np.zeros(0), np.zeros((0, 4)), np.zeros((0, 4)), names, {n: float("nan") for n in names})
    t, y, yhat = np.concatenate(ts), np.vstack(ys), np.vstack(yh)
    fits = {n: fit_percent(y[:, j], yhat[:, j], n == "psi") for j, n in enumerate(names)}
    return OutputFit(t, y, yhat, names, fits, np.array(starts))
