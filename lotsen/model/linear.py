"""Linearisation about straight-ahead motion (seed eq. 15) and the stability conditions (seed eq. 16)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from lotsen.model.dynamics import VesselModel


@dataclass(frozen=True)
class LinearSwayYaw:
    """M [v_dot, r_dot]^T + N(U0) [v, r]^T = b tau  (seed eq. 15), with the surge mode beside it."""

    U0: float
    M: np.ndarray
    N: np.ndarray
    surge_pole: float  # -(X_u - 2 X_|u|u |U0| - 3 X_uuu U0^2) / m11

    @property
    def eigenvalues(self) -> np.ndarray:
        return np.linalg.eigvals(-np.linalg.solve(self.M, self.N))


def linearise_straight(model: VesselModel, U0: float) -> LinearSwayYaw:
    """Seed eq. (15): sway-yaw subsystem linearised at u = U0, v = r = 0 (thruster housing terms excluded)."""
    p = model.params
    M = np.diag([p.m22, p.m33])
    N = np.array([
        [p.Y_v - p.Y_uv * abs(U0), p.m11 * U0 + p.Y_r],
        [p.N_v - (p.m11 - p.m22) * U0, p.N_r],
    ])
    return LinearSwayYaw(U0=U0, M=M, N=N, surge_pole=-(p.X_u - 2.0 * p.X_uu * abs(U0)
                                                                          - 3.0 * p.X_uuu * U0 * U0) / p.m11)


@dataclass(frozen=True)
class StabilityReport:
    """Which of the seed's conditions (16a-d) hold; 16d at U0 = 0 and U0 = U_max."""

    U_max: float
    conditions: dict[str, bool]
    values: dict[str, float]
    eigenvalues: dict[str, list[complex]] = field(default_factory=dict)

    @property
    def stable_for_all_speeds(self) -> bool:
        """Seed: 16a-c, 16d at both ends and m11 < m22 imply stability for 0 <= u <= U_max."""
        return all(self.conditions.values())

    def lines(self) -> list[str]:
        out = []
        for k, ok in self.conditions.items():
            out.append(f"  {'holds ' if ok else 'FAILS '} {k:<38s} value {self.values[k]: .4g}")
        for k, ev in self.eigenvalues.items():
            out.append(f"  eigenvalues of the linear sway-yaw model at {k}: "
                       + ", ".join(f"{e.real:.3f}{e.imag:+.3f}j" for e in ev))
        verdict = ("stable for all 0 <= u <= U_max" if self.stable_for_all_speeds else
                   "NOT guaranteed stable over 0 <= u <= U_max (feedback control must stabilise it)")
        out.append(f"  verdict: {verdict}")
        return out


def condition_16d(model: VesselModel, U0: float) -> float:
    """(Y_v - Y_|u|v |U0|) N_r - (m11 U0 + Y_r)(N_v - (m11 - m22) U0): the determinant of N(U0)."""
    return float(np.linalg.det(linearise_straight(model, U0).N))


def stability_report(model: VesselModel, U_max: float | None = None, n_max_rps: float = 100.0) -> StabilityReport:
    p = model.params
    if U_max is None:
        U_max = model.max_surge_speed(n_max_rps)
    d0, dmax = condition_16d(model, 0.0), condition_16d(model, U_max)
    values = {
        "16a X_u > 0": p.X_u, "16b Y_v > 0": p.Y_v, "16c N_r > 0": p.N_r,
        "16d at U0 = 0": d0, f"16d at U0 = U_max = {U_max:.2f} m/s": dmax,
        "m11 < m22": p.m22 - p.m11,
    }
    conditions = {k: v > 0 for k, v in values.items()}
    eig = {f"U0 = {U:.2f}": list(linearise_straight(model, U).eigenvalues) for U in (0.0, U_max)}
    return StabilityReport(U_max=U_max, conditions=conditions, values=values, eigenvalues=eig)


def linearise(model: VesselModel, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Full 6-state linearisation A = df/dx, B = df/du at (x, u) (analytic)."""
    return model.jacobians(x, u)


def straight_trim(model: VesselModel, U0: float) -> tuple[np.ndarray, np.ndarray]:
    """Operating point of steady straight motion at U0 heading north: x0, u0."""
    n = model.propeller_speed_for_surge(U0)
    return np.array([0.0, 0.0, 0.0, U0, 0.0, 0.0]), np.array([0.0, 0.0, n, n, 0.0])
