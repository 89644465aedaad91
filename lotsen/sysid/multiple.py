"""Multiple shooting (seed section 4, as in the earlier thesis): CasADi + IPOPT.

Decision variables: the free parameters (scaled by their size) and the state at every sample
of every gap-free segment; equality constraints tie each sample's state to the RK4 prediction
from the previous one (inputs held, `h_max` substeps). The objective is the same weighted least
squares as single shooting; psi is compared with the measured heading unwrapped along each
segment (a smooth objective for IPOPT instead of the wrapped residual). Because every sample
has its own state, the open-loop instability of the vessel does not make the problem ill-posed,
and segments need no cutting into windows.

Uncertainty: the Fisher information at the multiple-shooting estimate is evaluated by the
single-shooting machinery (windows with their initial states re-estimated at fixed theta), so
both methods report comparable standard deviations.
"""

from __future__ import annotations

import math
from typing import Callable, Mapping, Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters, geometry_tuple, \
    symbolic_rhs
from lotsen.sysid.data import OUTPUT_STATE_INDEX, IdRecord, Segment, split_segments
from lotsen.sysid.estimate import (
    DEFAULT_NOISE_STD, NAMES, EstimationError, IdentificationResult, check_scale_fixed, estimate,
    initial_state_guess, parameter_bounds, parameter_scale,
)


def _state_guess(seg: Segment, psi_unwrapped: np.ndarray) -> np.ndarray:
    """Initial guess of the state at every sample: measurements interpolated, velocities differenced."""
    names = seg.output_names
    t = seg.t
    X = np.zeros((len(t), 6))
    for j, name in enumerate(names):
        col = psi_unwrapped if name == "psi" else seg.outputs[:, j]
        ok = np.isfinite(col)
        if ok.sum() >= 1:
            X[:, OUTPUT_STATE_INDEX[name]] = np.interp(t, t[ok], col[ok])
    if "u" not in names:
        vn = np.gradient(X[:, 0], t)
        ve = np.gradient(X[:, 1], t)
        X[:, 3] = np.cos(X[:, 2]) * vn + np.sin(X[:, 2]) * ve
        X[:, 4] = -np.sin(X[:, 2]) * vn + np.cos(X[:, 2]) * ve
    X[0] = initial_state_guess(seg)
    X[0, 2] = psi_unwrapped[np.isfinite(psi_unwrapped)][0] if np.isfinite(psi_unwrapped).any() else 0.0
    return X


def estimate_multiple_shooting(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                               fixed: Mapping[str, float] | None = None, gap_s: float = 1.0,
                               noise_std: Mapping[str, float] | None = None,
                               geometry: VesselGeometry = DEFAULT_GEOMETRY, h_max: float = 0.0625,
                               max_iterations: int = 200, window_s: float = 10.0,
                               progress: Callable[[int, float], None] | None = None) -> IdentificationResult:
    import casadi as ca

    fixed = dict(fixed or {})
    check_scale_fixed(fixed)
    segs = [s for r in records for s in split_segments(r, gap_s)]
    if not segs:
        raise EstimationError("no usable data segments")
    names_out = segs[0].output_names
    noise = dict(DEFAULT_NOISE_STD)
    noise.update(noise_std or {})
    theta_init = np.array(theta0.with_updates(**fixed).to_vector(), float)
    lo, hi = parameter_bounds()
    theta_init = np.clip(theta_init, lo, hi)
    free = [i for i, n in enumerate(NAMES) if n not in fixed]
    scale = parameter_scale(theta_init)
    f = symbolic_rhs(ca)
    geom = geometry_tuple(geometry)

    # one RK4 interval with M substeps, parameters as a full vector
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 5)
    th = ca.SX.sym("th", 18)
    dt = ca.SX.sym("dt")
    dts = max(float(np.max(np.diff(s.t))) for s in segs if len(s.t) > 1)
    M = max(1, int(math.ceil(dts / h_max - 1e-9)))
    ul, thl = ca.vertsplit(u), ca.vertsplit(th)

    def rhs(xx):  # type: ignore[no-untyped-def]
        return ca.vertcat(*f(ca.vertsplit(xx), ul, thl, geom))

    h = dt / M
    xk = x
    for _ in range(M):
        k1 = rhs(xk)
        k2 = rhs(xk + h / 2 * k1)
        k3 = rhs(xk + h / 2 * k2)
        k4 = rhs(xk + h * k3)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    Phi = ca.Function("Phi", [x, u, th, dt], [xk])

    p = ca.MX.sym("p", len(free))
    th_full = []
    for i in range(18):
        th_full.append(p[free.index(i)] * scale[i] if i in free else ca.MX(theta_init[i]))
    TH = ca.vertcat(*th_full)
    w_vars, w0, g, J = [p], [theta_init[free] / scale[free]], [], 0
    lbw = [lo[free] / scale[free]]
    ubw = [hi[free] / scale[free]]
    out_idx = [OUTPUT_STATE_INDEX[n] for n in names_out]
    sw = np.array([1.0 / noise[n] for n in names_out])
    for s in segs:
        n = len(s.t)
        yv = s.outputs.copy()
        if "psi" in names_out:
            j = names_out.index("psi")
            ok = np.isfinite(yv[:, j])
            yv[ok, j] = np.unwrap(yv[ok, j])
        Xg = _state_guess(s, yv[:, names_out.index("psi")] if "psi" in names_out else np.zeros(n))
        S = ca.MX.sym("S", 6, n)
        w_vars.append(ca.vec(S))
        w0.append(Xg.T.ravel(order="F"))
        lbw.append(np.full(6 * n, -np.inf))
        ubw.append(np.full(6 * n, np.inf))
        if n > 1:
            F = Phi.map(n - 1)
            Xn = F(S[:, :-1], s.inputs[:-1].T, ca.repmat(TH, 1, n - 1), np.diff(s.t)[None, :])
            g.append(ca.vec(Xn - S[:, 1:]))
        mask = np.isfinite(yv)
        Y = np.where(mask, yv, 0.0)
        E = (Y.T - S[out_idx, :]) * mask.T * sw[:, None]
        J = J + ca.sumsqr(E)
    nlp = {"x": ca.vertcat(*w_vars), "f": J, "g": ca.vertcat(*g)}
    it_count = [0]

    class _Cb(ca.Callback):  # iteration callback for the progress bar
        def __init__(self) -> None:
            ca.Callback.__init__(self)
            self.construct("cb", {})

        def get_n_in(self):  # type: ignore[no-untyped-def]
            return ca.nlpsol_n_out()

        def get_n_out(self):  # type: ignore[no-untyped-def]
            return 1

        def get_name_in(self, i):  # type: ignore[no-untyped-def]
            return ca.nlpsol_out(i)

        def get_name_out(self, i):  # type: ignore[no-untyped-def]
            return "ret"

        def get_sparsity_in(self, i):  # type: ignore[no-untyped-def]
            name = ca.nlpsol_out(i)
            if name == "f":
                return ca.Sparsity.scalar()
            if name in ("x", "lam_x"):
                return ca.Sparsity.dense(nlp["x"].numel(), 1)
            if name in ("g", "lam_g"):
                return ca.Sparsity.dense(nlp["g"].numel(), 1)
            return ca.Sparsity(0, 0)

        def eval(self, arg):  # type: ignore[no-untyped-def]
            it_count[0] += 1
            if progress:
                progress(it_count[0], float(arg[1]))
            return [0]

    cb = _Cb()
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.max_iter": max_iterations, "ipopt.tol": 1e-8,
            "iteration_callback": cb, "ipopt.sb": "yes"}
    solver = ca.nlpsol("ms", "ipopt", nlp, opts)
    sol = solver(x0=np.concatenate(w0), lbx=np.concatenate(lbw), ubx=np.concatenate(ubw), lbg=0, ubg=0)
    stats = solver.stats()
    pv = np.array(sol["x"][: len(free)]).ravel()
    theta = theta_init.copy()
    theta[free] = pv * scale[free]
    params = VesselParameters.from_vector(theta)
    # uncertainty at the estimate, as single shooting sees it (initial states re-estimated at fixed theta)
    all_fixed = dict(zip(NAMES, theta))
    x0_res = estimate(records, params, fixed=all_fixed, window_s=window_s, gap_s=gap_s, noise_std=noise_std,
                      geometry=geometry, max_iterations=20, h_max=h_max)
    res = estimate(records, params, fixed=fixed, window_s=window_s, gap_s=gap_s, noise_std=noise_std,
                   geometry=geometry, max_iterations=0, h_max=h_max, x0s=x0_res.x0s)
    res.method = "multiple"
    res.iterations = int(stats.get("iter_count", it_count[0]))
    res.converged = bool(stats.get("success", False))
    res.history = [float(sol["f"])]
    return res
