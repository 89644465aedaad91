"""Thrust allocation: generalized forces tau = [tau_X, tau_Y, tau_N] -> actuators [a1, a2, n1, n2, nt].

Extended-thrust formulation (Fossen 2021, sec. 11.2; Johansen & Fossen 2013): each azimuth unit
is a force vector (F_ix, F_iy) in the body frame, the bow tunnel thruster a force F_t along +y.
The decision vector of the QP is

    z = [F_1x, F_1y, F_2x, F_2y, F_t, s_X, s_Y, s_N]      (N; s = slack on the force balance)

    minimise   1/2 z^T P z + q^T z
               P = diag(w_az, w_az, w_az, w_az, w_bow, w_slack_X, w_slack_Y, w_slack_N)
               q = -lambda f_prev   (optional smoothing term lambda ||f - f_prev||^2 / 2)
    subject to B f + s = tau                                 (3 rows, force balance)
               |F_iy| <= tan(alpha_max) sigma_i F_ix         (angle limit: a convex cone)
               sigma_i F_ix cos(m) + |F_iy| sin(m) <= T_max,i cos(h)   (chords of the thrust circle)
               |F_t| <= T_t,max

Quadratic force weights approximate minimum power (power ~ |T|^1.5) and spread the load; the bow
weight is larger because a tunnel thruster produces less thrust per watt. The angle limit
|alpha_i| <= alpha_max is exact and linear once the thrust *direction* sigma_i (ahead +1 or reverse
-1) of each unit is fixed: the feasible set of one unit is a double cone (non-convex), so the four
sign combinations are four QPs, each set up once with OSQP (fixed sparsity; only l, u, q change
per call). The cheapest solution wins; a small hysteresis keeps the previous combination unless
another is clearly cheaper. Reverse thrust may be weaker (VesselGeometry.reverse_thrust_ratio):
T_max for sigma = -1 is scaled, and n = sign(T) sqrt(|T| / (mu rev)).

The slack makes every request feasible: an unattainable tau is approximated in the weighted
least-squares sense with the saturated actuators (saturation is handled, never an infeasible QP).

The housing normal force (vessel-model.md) is not part of this static map; with `nu` given,
`allocate` corrects the request once by the force error predicted by the full model
(tau_req + (tau_req - tau_model(nu, u))), which removes most of it at speed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from lotsen.model.dynamics import VesselModel
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits

_SOLVED = (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)


@dataclass(frozen=True)
class AllocationConfig:
    weight_azimuth: float = 1.0  # per N^2
    weight_bow: float = 4.0  # tunnel thrusters are less efficient: use the azimuths first
    # unattained force per axis (X per N^2, Y per N^2, N per (N m)^2): when saturated, speed gives
    # way before sway and yaw (the yaw dynamics are open-loop unstable above ~0.5 m/s)
    weight_slack: tuple[float, float, float] = (1.0e4, 1.0e6, 1.0e7)
    smoothing: float = 0.05  # lambda: pull towards the previous forces (less chattering)
    switch_hysteresis: float = 0.02  # relative cost margin before the sign combination changes
    # and an absolute one per azimuth that would reverse, 1/2 weight_azimuth F^2: at small forces (a hold)
    # the relative margin is nothing (station_keeping.HOLD_ALLOCATION)
    switch_force_N: float = 0.0
    min_force_for_angle_N: float = 0.02  # below this the azimuth keeps its previous angle
    housing_correction: bool = True  # one model-based correction for the housing force when nu is given


@dataclass(frozen=True)
class AllocationResult:
    command: tuple[float, float, float, float, float]  # [a1, a2, n1, n2, nt]
    forces: np.ndarray  # [F1x, F1y, F2x, F2y, Ft]
    tau_achieved: np.ndarray  # B f of the static thrust map
    saturated: bool  # the slack was needed: tau not reachable within the limits
    signs: tuple[int, int]


def thrust_configuration(model: VesselModel) -> np.ndarray:
    """B (3 x 5): tau = B [F1x, F1y, F2x, F2y, Ft]; moment of (F_x, F_y) at (l_x, l_y) is l_x F_y - l_y F_x."""
    g = model.geometry
    return np.array([
        [1.0, 0.0, 1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 1.0, 1.0],
        [-g.l_y1, g.l_x1, -g.l_y2, g.l_x2, g.l_xt],
    ])


def rate_limit(previous: tuple[float, ...] | None, command: tuple[float, ...], dt_s: float,
               limits: ActuatorLimits) -> tuple[float, float, float, float, float]:
    """Clip a command to the actuator limits and to the servo slew / ESC ramp from `previous`."""
    a1, a2, n1, n2, nt = limits.clip(*command)
    if previous is None:
        return (a1, a2, n1, n2, nt)
    da = limits.alpha_rate_max_radps * dt_s
    dn = limits.n_rate_max_rps2 * dt_s
    p = previous

    def lim(x: float, x0: float, d: float) -> float:
        return min(max(x, x0 - d), x0 + d)

    return (lim(a1, p[0], da), lim(a2, p[1], da), lim(n1, p[2], dn), lim(n2, p[3], dn), lim(nt, p[4], dn))


class ThrustAllocator:
    """Constrained minimum-power allocation (see module docstring); pure, no clock."""

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: AllocationConfig = AllocationConfig()) -> None:
        self.model = model or VesselModel()
        self.limits = limits
        self.config = config
        p = self.model.params
        self.rev = float(self.model.geometry.reverse_thrust_ratio)
        self.mu_az, self.mu_t = p.mu_az, p.mu_t
        self.B = thrust_configuration(self.model)
        self.T_max = p.mu_az * limits.n_az_max_rps ** 2
        self.T_bow_max = p.mu_t * limits.n_bow_max_rps ** 2
        c = config
        self._P_diag = np.array([c.weight_azimuth] * 4 + [c.weight_bow] + list(c.weight_slack))
        self._solvers: dict[tuple[int, int], tuple[osqp.OSQP, np.ndarray, np.ndarray]] = {}
        for s1 in (1, -1):
            for s2 in (1, -1):
                self._solvers[(s1, s2)] = self._setup((s1, s2))
        self._signs = (1, 1)
        self._f_prev = np.zeros(5)
        self._alpha_prev = (0.0, 0.0)

    def _setup(self, signs: tuple[int, int]) -> tuple[osqp.OSQP, np.ndarray, np.ndarray]:
        t = math.tan(self.limits.alpha_max_rad)
        rows: list[np.ndarray] = []
        lo: list[float] = []
        hi: list[float] = []
        eq = np.hstack([self.B, np.eye(3)])
        for r in eq:
            rows.append(r)
            lo.append(0.0)
            hi.append(0.0)  # replaced by tau at every call
        # chords of the circle |F| <= T_max over [-alpha_max, alpha_max]: two per side
        half = self.limits.alpha_max_rad / 4.0
        mids = [-3 * half, -half, half, 3 * half]
        for i, sg in enumerate(signs):
            ix, iy = 2 * i, 2 * i + 1
            tmax = self.T_max * (1.0 if sg > 0 else self.rev)
            for sy in (1.0, -1.0):  # +-F_y - t sigma F_x <= 0
                r = np.zeros(8)
                r[iy] = sy
                r[ix] = -t * sg
                rows.append(r)
                lo.append(-np.inf)
                hi.append(0.0)
            for m in mids:
                r = np.zeros(8)
                r[ix] = sg * math.cos(m)
                r[iy] = math.sin(m)
                rows.append(r)
                lo.append(-np.inf)
                hi.append(tmax * math.cos(half))
        r = np.zeros(8)
        r[4] = 1.0
        rows.append(r)
        lo.append(-self.T_bow_max)
        hi.append(self.T_bow_max)
        A = sp.csc_matrix(np.array(rows))
        solver = osqp.OSQP()
        solver.setup(sp.csc_matrix(np.diag(self._P_diag)), np.zeros(8), A, np.array(lo), np.array(hi),
                     verbose=False, eps_abs=1e-6, eps_rel=1e-6, polishing=True, warm_starting=True,
                     max_iter=4000)
        return solver, np.array(lo), np.array(hi)

    def _solve(self, signs: tuple[int, int], tau: np.ndarray) -> tuple[float, np.ndarray] | None:
        solver, lo, hi = self._solvers[signs]
        lo[:3] = tau
        hi[:3] = tau
        q = np.zeros(8)
        q[:5] = -self.config.smoothing * self._f_prev
        solver.update(q=q, l=lo, u=hi)
        res = solver.solve(raise_error=False)
        if res.info.status_val not in _SOLVED or res.x is None or not np.all(np.isfinite(res.x)):
            return None
        z = np.array(res.x, dtype=float)
        cost = 0.5 * float(np.sum(self._P_diag * z * z))
        return cost, z

    def reset(self) -> None:
        self._signs = (1, 1)
        self._f_prev = np.zeros(5)
        self._alpha_prev = (0.0, 0.0)

    def forces_to_command(self, f: np.ndarray, signs: tuple[int, int]) -> tuple[float, float, float, float, float]:
        """Convert forces to angles and signed propeller speeds (n = sign(T) sqrt(|T| / mu))."""
        out_a: list[float] = []
        out_n: list[float] = []
        amax = self.limits.alpha_max_rad
        for i, sg in enumerate(signs):
            fx, fy = f[2 * i], f[2 * i + 1]
            mag = math.hypot(fx, fy)
            if mag < self.config.min_force_for_angle_N:
                alpha = self._alpha_prev[i]
            else:
                alpha = math.atan2(sg * fy, sg * fx)  # direction of the unit's axis
            alpha = min(max(alpha, -amax), amax)
            # thrust along the axis: project the force (exact inside the cone)
            T = sg * mag if mag >= self.config.min_force_for_angle_N else fx * math.cos(alpha) + fy * math.sin(alpha)
            mu = self.mu_az * (1.0 if T >= 0 else self.rev)
            out_a.append(alpha)
            out_n.append(math.copysign(math.sqrt(abs(T) / mu), T))
        ft = f[4]
        nt = math.copysign(math.sqrt(abs(ft) / self.mu_t), ft) if self.mu_t > 0 else 0.0
        return self.limits.clip(out_a[0], out_a[1], out_n[0], out_n[1], nt)  # type: ignore[return-value]

    def _allocate_static(self, tau: np.ndarray) -> tuple[np.ndarray, tuple[int, int], np.ndarray]:
        best: tuple[float, np.ndarray, tuple[int, int]] | None = None
        for signs in self._solvers:
            out = self._solve(signs, tau)
            if out is None:
                continue
            cost, z = out
            if signs == self._signs:
                cost *= 1.0 - self.config.switch_hysteresis
            else:
                flips = sum(a != b for a, b in zip(signs, self._signs))
                cost += flips * 0.5 * self.config.weight_azimuth * self.config.switch_force_N ** 2
            if best is None or cost < best[0]:
                best = (cost, z, signs)
        if best is None:  # cannot happen with the slack unless OSQP fails: neutral forces
            return np.zeros(5), self._signs, np.zeros(3)
        return best[1][:5], best[2], best[1][5:]

    def allocate(self, tau: np.ndarray | tuple[float, float, float],
                 nu: tuple[float, float, float] | None = None) -> AllocationResult:
        """Actuator set-points for the generalized force `tau` (N, N, N m).

        `nu` = (u, v, r) relative to the water: with it, one correction for the housing force.
        """
        tau = np.asarray(tau, dtype=float)
        if tau.shape != (3,) or not np.all(np.isfinite(tau)):
            tau = np.zeros(3)
        f, signs, slack = self._allocate_static(tau)
        cmd = self.forces_to_command(f, signs)
        if nu is not None and self.config.housing_correction:
            achieved = self.model.tau(nu, cmd)
            tau2 = tau + (tau - achieved)
            f2, signs2, slack2 = self._allocate_static(tau2)
            cmd2 = self.forces_to_command(f2, signs2)
            if np.linalg.norm(self.model.tau(nu, cmd2) - tau) < np.linalg.norm(achieved - tau):
                f, signs, slack, cmd = f2, signs2, slack2, cmd2
        self._signs = signs
        self._f_prev = f.copy()
        self._alpha_prev = (cmd[0], cmd[1])
        return AllocationResult(command=cmd, forces=f, tau_achieved=self.B @ f,
                                saturated=bool(np.max(np.abs(slack)) > 1e-3), signs=signs)
