"""Grey-box estimation: weighted least squares of the output error (seed eq. 1-3).

    V(theta) = sum_k (y_k - yhat_k(theta))^T W (y_k - yhat_k(theta)),   psi residuals wrapped to (-pi, pi]

Single shooting (`estimate`): every window (a gap-free piece of data, cut to at most `window_s`)
is simulated from its own estimated initial state; Levenberg-Marquardt on theta and all initial
states, with the exact Jacobian from forward sensitivities (lotsen.sysid.sensitivity). The normal
equations have block-arrow structure (theta couples to everything, each window's initial state
only to its own residuals), so each iteration eliminates the initial states window by window
(Schur complement) and solves only an 18 x 18 system for theta: the cost is linear in the data.
Bounds (the physical ranges of the parameter metadata, seed 16a-c strict) are kept by
projecting each trial point onto the box.

The parameter covariance is the inverse of the Fisher information of theta with the initial
states marginalised (the same Schur complement), times the a-posteriori noise factor
s^2 = 2 V / (m - p) when that exceeds 1 (model error inflates the honest uncertainty).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from lotsen.errors import LotsenError
from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.model.angles import wrap_angle
from lotsen.sysid.data import IdRecord, Segment, check_excitation, check_record, split_segments, split_windows
from lotsen.sysid.kernels import WindowSimulator

NAMES = VesselParameters.names()
# Multiplying these by one factor leaves the motion unchanged (vessel-model.md "Identifiability"):
# M, every damping coefficient, the thrust coefficients and the housing force coefficient C_N. (An
# optional term scales too, but one held at 0 -- off -- fixes no scale.)
SCALE_GROUP = tuple(n for n in NAMES if n != "kappa" and n not in OPTIONAL_TERMS)
# a typical magnitude of each optional term (its default, 0, gives none): relative steps and sigmas
_TERM_SCALE = {"X_uuu": 2.0}
# Default measurement noise (1 sigma) of each output: RTK-fixed GNSS, heading, MEMS gyro.
DEFAULT_NOISE_STD = {"north": 0.01, "east": 0.01, "psi": 0.01, "r": 0.003, "u": 0.03, "v": 0.03}
# Parameters that must be strictly positive (seed eq. 16a-c) get this lower bound instead of 0.
_STRICT_POSITIVE = ("X_u", "Y_v", "N_r")


@dataclass(frozen=True)
class SolverOptions:
    """How an output-error solver runs on a record (single and multiple shooting alike): the record's
    gaps, the assumed noise, the hull's known geometry, the integration step and the iteration budget;
    for multiple shooting the interval length, the lake model (current, wind, gusts), a yaw-rate
    offset per record, which fixed values to test and which optional model terms to estimate."""

    gap_s: float = 1.0  # a longer time gap between measurements splits a record
    noise_std: Mapping[str, float] = field(default_factory=dict)  # per output (DEFAULT_NOISE_STD)
    geometry: VesselGeometry = DEFAULT_GEOMETRY
    h_max: float = 0.0625  # the longest RK4 step, s
    max_iterations: int = 60  # per pass
    total_iterations: int | None = None  # both passes together (None: no common cap)
    tol: float = 1e-9
    window_s: float | None = 10.0  # single shooting: window length
    node_s: float = 2.0  # multiple shooting: shooting interval length
    estimate_noise: bool = True  # re-estimate each output's noise from its residuals (a second pass)
    lake: bool = False  # current, wind and gusts estimated with the coefficients
    gust_std: float = 0.3  # lake: prior spread of the per-interval gust factors
    wind_coefficient_spread: float = 0.01  # lake: relative prior spread of the wind's drag coefficients
    gyro_bias: bool | None = None  # yaw-rate offsets (None: with `lake`)
    gyro_offset_block_s: float = 60.0  # one offset per record and block of about this long (0: per record)
    test_fixed: tuple[str, ...] = ()  # fixed coefficients whose value the record may contradict
    misfit_check: int = 0  # stop after this many iterations when the track's errors stay correlated
    terms: tuple[str, ...] = ()  # optional model terms estimated (OPTIONAL_TERMS; the others off)


class IdentifiabilityError(LotsenError):
    """The data/parameter choice cannot determine the parameters (e.g. the common scale)."""


class EstimationError(LotsenError):
    """The estimation could not run (no usable data, diverged simulation, ...)."""


def parameter_bounds() -> tuple[np.ndarray, np.ndarray]:
    lo, hi = [], []
    for f in fields(VesselParameters):
        a, b = f.metadata["range"]
        if f.name in _STRICT_POSITIVE:
            a = max(a, 1e-3)
        lo.append(a)
        hi.append(b)
    return np.array(lo, float), np.array(hi, float)


def parameter_scale(theta: Sequence[float]) -> np.ndarray:
    """Typical magnitude of each parameter (relative steps and relative uncertainties)."""
    d = np.abs(np.array(DEFAULT_PARAMETERS.to_vector()))
    for n, v in _TERM_SCALE.items():
        d[NAMES.index(n)] = 10.0 * v  # (x 0.1 below)
    t = np.abs(np.asarray(theta, float))
    return np.maximum(np.maximum(t, 0.1 * d), 1e-6)


def check_scale_fixed(fixed: Mapping[str, float]) -> None:
    """Refuse to estimate when the common scale of M, damping and thrust is free."""
    if not any(n in fixed for n in SCALE_GROUP):
        raise IdentifiabilityError(
            "the common scale of mass, damping and thrust coefficients is unidentifiable from motion "
            "data (multiplying m11..N_rr, C_N, mu_az, mu_t by one factor gives the same motion): fix "
            "one of them, e.g. --fix m11=14.0 (weighed mass 13 kg + surge added mass) or "
            "--fix mu_az=<bollard-pull value>")


def initial_state_guess(seg: Segment) -> np.ndarray:
    """x0 = [N, E, psi, u, v, r] from the first samples of a window."""
    names = seg.output_names
    y = seg.outputs
    t = seg.t

    def first(name: str, default: float = 0.0) -> float:
        if name not in names:
            return default
        col = y[:, names.index(name)]
        ok = np.isfinite(col)
        return float(col[ok][0]) if ok.any() else default

    N0, E0, psi0, r0 = first("north"), first("east"), first("psi"), first("r")
    u0, v0 = first("u", math.nan), first("v", math.nan)
    if not (math.isfinite(u0) and math.isfinite(v0)):
        # velocity from a line fit over the first ~0.6 s of positions, rotated into the body frame
        iN, iE = names.index("north"), names.index("east")
        m = (t <= t[0] + 0.6) & np.isfinite(y[:, iN]) & np.isfinite(y[:, iE])
        if m.sum() >= 2:
            vn = np.polyfit(t[m] - t[0], y[m, iN], 1)[0]
            ve = np.polyfit(t[m] - t[0], y[m, iE], 1)[0]
            u0 = math.cos(psi0) * vn + math.sin(psi0) * ve
            v0 = -math.sin(psi0) * vn + math.cos(psi0) * ve
        else:
            u0, v0 = 0.0, 0.0
    return np.array([N0, E0, psi0, u0, v0, r0])


@dataclass
class WindowedProblem:
    """Windows of data, their simulator, weights and the residual layout."""

    windows: list[Segment]
    sim: WindowSimulator
    noise_std: dict[str, float]
    out_idx: list[int]
    mask: np.ndarray  # n_samples x ny: finite measurement
    y: np.ndarray  # n_samples x ny
    sqrt_w: np.ndarray  # ny
    psi_col: int | None
    window_of_sample: np.ndarray

    @property
    def n_windows(self) -> int:
        return len(self.windows)

    def residuals(self, X: np.ndarray) -> np.ndarray:
        """Weighted residual matrix (n_samples x ny), 0 where not measured."""
        yhat = X[:, self.out_idx]
        e = self.y - yhat
        if self.psi_col is not None:
            e[:, self.psi_col] = wrap_angle(e[:, self.psi_col])
        e = np.where(self.mask, e, 0.0)
        return e * self.sqrt_w


def build_problem(records: Sequence[IdRecord] | Sequence[Segment], window_s: float | None = 10.0,
                  gap_s: float = 1.0, noise_std: Mapping[str, float] | None = None,
                  geometry: VesselGeometry = DEFAULT_GEOMETRY, h_max: float = 0.0625) -> WindowedProblem:
    segs: list[Segment] = []
    for r in records:
        if isinstance(r, IdRecord):
            check_record(r)
            segs.extend(split_segments(r, gap_s))
        else:
            segs.append(r)
    windows = split_windows(segs, window_s)
    if not windows:
        raise EstimationError("no usable data: every segment is shorter than 8 samples with outputs")
    names = windows[0].output_names
    if any(w.output_names != names for w in windows):
        raise EstimationError("all data files must have the same output columns")
    noise = dict(DEFAULT_NOISE_STD)
    noise.update(noise_std or {})
    sim = WindowSimulator(windows, geometry, h_max)
    y = np.vstack([w.outputs for w in windows])
    mask = np.isfinite(y)
    y = np.where(mask, y, 0.0)
    sqrt_w = np.array([1.0 / noise[n] for n in names])
    psi_col = names.index("psi") if "psi" in names else None
    return WindowedProblem(windows, sim, noise, sim.output_index(), mask, y, sqrt_w, psi_col,
                           sim.grid.window_of_sample)


@dataclass
class NormalBlocks:
    """J^T J blocks of the block-arrow structure, and gradients (weighted, in scaled parameters)."""

    A: np.ndarray  # nf x nf
    B: np.ndarray  # nw x nf x 6
    C: np.ndarray  # nw x 6 x 6
    g_theta: np.ndarray  # nf
    g_x: np.ndarray  # nw x 6


def _normal_blocks(prob: WindowedProblem, S: np.ndarray, E: np.ndarray, free: np.ndarray,
                   theta_scale: np.ndarray, x_scale: np.ndarray) -> NormalBlocks:
    """Residual Jacobian d e / d p = -sqrt(w) dyhat/dp, reduced directly into normal-equation blocks."""
    # dyhat/d[x0, theta] at measured entries, weighted: n_samples x ny x 24
    Jy = S[:, prob.out_idx, :] * prob.sqrt_w[None, :, None] * prob.mask[:, :, None]
    Jx = -Jy[:, :, :6] * x_scale[None, None, :]
    Jt = -Jy[:, :, 6:][:, :, free] * theta_scale[free][None, None, :]
    nw, nf = prob.n_windows, len(free)
    A = np.zeros((nf, nf))
    B = np.zeros((nw, nf, 6))
    C = np.zeros((nw, 6, 6))
    g_t = np.zeros(nf)
    g_x = np.zeros((nw, 6))
    wos = prob.window_of_sample
    bounds = np.searchsorted(wos, np.arange(nw + 1))
    for w in range(nw):
        a, b = bounds[w], bounds[w + 1]
        jt = Jt[a:b].reshape((b - a) * Jt.shape[1], nf)
        jx = Jx[a:b].reshape((b - a) * Jx.shape[1], 6)
        e = E[a:b].reshape(-1)
        A += jt.T @ jt
        B[w] = jt.T @ jx
        C[w] = jx.T @ jx
        g_t += jt.T @ e
        g_x[w] = jx.T @ e
    return NormalBlocks(A, B, C, g_t, g_x)


def marginal_fisher(nb: NormalBlocks, ridge: float = 1e-12) -> np.ndarray:
    """Fisher information of theta with the window initial states eliminated (Schur complement)."""
    F = nb.A.copy()
    for w in range(len(nb.C)):
        Cw = nb.C[w] + ridge * np.trace(nb.C[w]) * np.eye(6)
        F -= nb.B[w] @ np.linalg.solve(Cw, nb.B[w].T)
    return 0.5 * (F + F.T)


@dataclass
class Identifiability:
    """SVD of the relative Fisher information: which directions the data determines poorly."""

    singular_values: np.ndarray  # of the scaled Jacobian (sqrt of FIM eigenvalues), descending
    directions: list[str]  # human-readable weak directions
    unidentifiable: bool
    relative_std: dict[str, float]
    poorly_determined: list[str]
    condition_number: float


def identifiability(F_rel: np.ndarray, free_names: Sequence[str], rel_std: np.ndarray,
                    poor_threshold: float = 0.05, singular_ratio: float = 1e-7) -> Identifiability:
    """Name unidentifiable (near-null) and poorly determined directions of the relative FIM."""
    evals, evecs = np.linalg.eigh(F_rel)
    order = np.argsort(evals)[::-1]
    evals, evecs = np.clip(evals[order], 0.0, None), evecs[:, order]
    sv = np.sqrt(evals)
    smax = sv[0] if len(sv) and sv[0] > 0 else 1.0
    directions = []
    unident = False
    for i in range(len(sv) - 1, -1, -1):
        ratio = sv[i] / smax
        std_dir = 1.0 / sv[i] if sv[i] > 0 else math.inf  # relative std along this direction
        if ratio > 1e-3 and std_dir < poor_threshold / 1.96:
            break
        vec = evecs[:, i]
        top = np.argsort(-np.abs(vec))[:4]
        terms = " ".join(f"{'+' if vec[j] >= 0 else '-'}{abs(vec[j]):.2f}*{free_names[j]}" for j in top
                         if abs(vec[j]) > 0.1)
        kind = "UNIDENTIFIABLE" if ratio < singular_ratio else "poorly determined"
        unident |= ratio < singular_ratio
        scale_ind = np.array([1.0 if n in SCALE_GROUP else 0.0 for n in free_names])
        if scale_ind.sum() > 1 and abs(vec @ scale_ind) / np.linalg.norm(scale_ind) > 0.9:
            terms = ("the common scale of " + ", ".join(n for n in free_names if n in SCALE_GROUP)
                     + " (all multiplied by one factor; fix one of them, e.g. --fix m11=14.0)")
        directions.append(f"{kind}: relative direction [{terms}] (singular value ratio {ratio:.1e}, "
                          f"relative 1-sigma {std_dir:.2g})")
    rs = {n: float(s) for n, s in zip(free_names, rel_std)}
    poor = [n for n, s in rs.items() if not (1.96 * s <= poor_threshold)]
    cond = float(smax / sv[-1]) if len(sv) and sv[-1] > 0 else math.inf
    return Identifiability(sv, directions, unident, rs, poor, cond)


@dataclass
class IdentificationResult:
    params: VesselParameters
    std: dict[str, float]  # of each estimated parameter (fixed ones are absent)
    fixed: dict[str, float]
    free_names: tuple[str, ...]
    covariance: np.ndarray  # of the free parameters (absolute units)
    fisher: np.ndarray  # marginal Fisher information of the free parameters (absolute units)
    x0s: np.ndarray  # estimated initial state per window
    cost: float  # V = sum of squared weighted residuals
    n_residuals: int
    noise_factor: float  # s^2 = 2V/(m - p)... here V/(m-p) with V the plain sum of squares
    iterations: int
    converged: bool
    identifiability: Identifiability
    method: str = "single"
    windows: list[Segment] = field(default_factory=list)
    history: list[float] = field(default_factory=list)
    details: Any = None  # method-specific (multiple shooting: lotsen.sysid.multiple.MultipleShootingResult)

    def confidence_interval(self, name: str, z: float = 1.96) -> tuple[float, float]:
        v = getattr(self.params, name)
        s = self.std.get(name, 0.0)
        return v - z * s, v + z * s

    def to_json_dict(self) -> dict:
        d: dict = dict(self.params.to_dict())
        # null where no interval exists (a coefficient at its bound): strict JSON has no Infinity
        d["std"] = {n: float(self.std[n]) if math.isfinite(self.std[n]) else None for n in self.free_names}
        return d


def _lm_solve(nb: NormalBlocks, lam: float) -> tuple[np.ndarray, np.ndarray]:
    """Damped (Marquardt-scaled) Schur-complement solve of the block-arrow normal equations."""
    nf = len(nb.g_theta)
    dA = np.diag(nb.A).copy()
    dA = np.where(dA > 0, dA, 1e-12)
    Ad = nb.A + lam * np.diag(dA) + 1e-12 * np.eye(nf)
    rhs = -nb.g_theta.copy()
    Cinv = []
    for w in range(len(nb.C)):
        dC = np.diag(nb.C[w]).copy()
        dC = np.where(dC > 0, dC, 1e-12)
        Cw = nb.C[w] + lam * np.diag(dC) + 1e-12 * np.eye(6)
        Ci = np.linalg.inv(Cw)
        Cinv.append(Ci)
        Ad -= nb.B[w] @ Ci @ nb.B[w].T
        rhs += nb.B[w] @ Ci @ nb.g_x[w]
    dtheta = np.linalg.solve(0.5 * (Ad + Ad.T), rhs) if nf else np.zeros(0)
    dx = np.array([-Cinv[w] @ (nb.g_x[w] + nb.B[w].T @ dtheta) for w in range(len(nb.C))])
    return dtheta, dx


_X0_SCALE = np.array([1.0, 1.0, 0.1, 0.1, 0.1, 0.1])


def with_terms_off(fixed: Mapping[str, float], theta0: VesselParameters,
                   terms: Sequence[str] = ()) -> dict[str, float]:
    """`fixed` with every optional model term not in `terms` held at `theta0`'s value (0: off)."""
    out = dict(fixed)
    for n in OPTIONAL_TERMS:
        if n not in terms and n not in out:
            out[n] = float(getattr(theta0, n))
    return out


def starting_point(theta0: VesselParameters, fixed: Mapping[str, float], terms: Sequence[str] = ()
                   ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], np.ndarray]:
    """The parameter vector to start from (fixed values in, clipped to the physical bounds), the
    indices and names of the free parameters, and their scale; a fixed value outside its
    physical range is a LotsenError naming it. The optional model terms are estimated only when
    named in `terms` (else held at theta0's value: 0, off)."""
    fixed = with_terms_off(fixed, theta0, terms)
    theta = np.array(theta0.with_updates(**fixed).to_vector(), float)
    lo, hi = parameter_bounds()
    out_of = [f"{n} = {fixed[n]:g} outside [{lo[i]:g}, {hi[i]:g}]" for i, n in enumerate(NAMES)
              if n in fixed and not lo[i] <= fixed[n] <= hi[i]]
    if out_of:
        raise LotsenError("fixed value(s) not physical: " + "; ".join(out_of))
    theta = np.clip(theta, lo, hi)
    free = np.array([i for i, n in enumerate(NAMES) if n not in fixed], dtype=int)
    return theta, free, tuple(NAMES[i] for i in free), parameter_scale(theta)


def estimate(records: Sequence[IdRecord] | WindowedProblem, theta0: VesselParameters = DEFAULT_PARAMETERS,
             fixed: Mapping[str, float] | None = None, options: SolverOptions = SolverOptions(),
             x0s: np.ndarray | None = None, estimate_x0: bool = True,
             progress: Callable[[int, float], None] | None = None) -> IdentificationResult:
    """Single-shooting Levenberg-Marquardt estimate of the free parameters and window initial states.

    `fixed` maps parameter names to values held constant (must include one of SCALE_GROUP).
    `x0s` gives initial states per window (else guessed from the data); `estimate_x0=False`
    keeps them (the docs' "given initial state").
    """
    fixed = with_terms_off(dict(fixed or {}), theta0 if isinstance(theta0, VesselParameters) else DEFAULT_PARAMETERS)
    unknown = [n for n in fixed if n not in NAMES]
    if unknown:
        raise LotsenError(f"cannot fix unknown parameter(s) {', '.join(unknown)} (known: {', '.join(NAMES)})")
    check_scale_fixed(fixed)
    if isinstance(records, WindowedProblem):
        prob = records
    else:
        prob = build_problem(records, options.window_s, options.gap_s, options.noise_std, options.geometry,
                             options.h_max)
        check_excitation(prob.windows)
    max_iterations, tol = options.max_iterations, options.tol
    theta, free, free_names, tscale = starting_point(theta0, fixed)
    lo, hi = parameter_bounds()
    X0 = np.array(x0s, float) if x0s is not None else np.array([initial_state_guess(w) for w in prob.windows])
    xscale = _X0_SCALE if estimate_x0 else np.zeros(6)

    def evaluate(th: np.ndarray, x0: np.ndarray, sens: bool):
        if sens:
            X, S = prob.sim.simulate_sens(th, x0)
        else:
            X, S = prob.sim.simulate(th, x0), None
        E = prob.residuals(X)
        cost = float(np.sum(E * E)) if np.all(np.isfinite(E)) else math.inf
        return cost, E, S

    cost, E, S = evaluate(theta, X0, True)
    if not math.isfinite(cost):
        raise EstimationError("the simulation with the initial parameters diverged (non-finite output); "
                              "use shorter windows (--window) or a better initial guess")
    lam = 1e-3
    history = [cost]
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        nb = _normal_blocks(prob, S, E, free, tscale, xscale)
        accepted = False
        for _ in range(12):
            dth, dx = _lm_solve(nb, lam)
            th_new = theta.copy()
            th_new[free] = np.clip(theta[free] + dth * tscale[free], lo[free], hi[free])
            X0_new = X0 + dx * xscale[None, :]
            c_new, _, _ = evaluate(th_new, X0_new, False)
            if c_new < cost:
                accepted = True
                break
            lam *= 4.0
        if not accepted:
            converged = True  # no descent possible at any damping: a (local) minimum
            break
        rel = (cost - c_new) / max(cost, 1e-300)
        theta, X0 = th_new, X0_new
        cost, E, S = evaluate(theta, X0, True)
        history.append(cost)
        lam = max(lam / 3.0, 1e-9)
        if progress:
            progress(it, cost)
        if rel < tol:
            converged = True
            break
    nb = _normal_blocks(prob, S, E, free, tscale, xscale)
    F_rel = marginal_fisher(nb)  # in scaled parameters p = theta / tscale
    m = int(prob.mask.sum())
    p = len(free) + (6 * prob.n_windows if estimate_x0 else 0)
    s2 = cost / max(m - p, 1)
    factor = max(1.0, s2)
    try:
        cov_rel = np.linalg.inv(F_rel) * factor
    except np.linalg.LinAlgError:
        cov_rel = np.linalg.pinv(F_rel) * factor
    rel_std = np.sqrt(np.clip(np.diag(cov_rel), 0, None)) * tscale[free] / np.maximum(np.abs(theta[free]), 1e-12)
    # relative to each parameter's typical size (a parameter at 0 keeps 10 % of its default)
    ident = identifiability(F_rel / factor, free_names, rel_std)
    D = np.diag(tscale[free])
    cov = D @ cov_rel @ D
    Dinv = np.diag(1.0 / tscale[free])
    fisher = Dinv @ F_rel @ Dinv
    std = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(free_names)}
    params = VesselParameters.from_vector(theta)
    return IdentificationResult(params, std, {n: float(v) for n, v in fixed.items()}, free_names, cov, fisher,
                                X0, cost, m, s2, it, converged, ident, "single", prob.windows, history)


def fisher_information(prob: WindowedProblem, theta: Sequence[float], x0s: np.ndarray,
                       free_names: Sequence[str]) -> np.ndarray:
    """Fisher information of `free_names` (absolute units), initial states marginalised.

    For experiment design and the benchmark: the information that data with the problem's
    inputs and noise carries, evaluated along the model's own prediction (residuals do not enter).
    """
    theta = np.asarray(theta, float)
    free = np.array([NAMES.index(n) for n in free_names], dtype=int)
    tscale = parameter_scale(theta)
    _, S = prob.sim.simulate_sens(theta, x0s)
    E = np.zeros(prob.y.shape)
    nb = _normal_blocks(prob, S, E, free, tscale, _X0_SCALE)
    F_rel = marginal_fisher(nb)
    Dinv = np.diag(1.0 / tscale[free])
    return Dinv @ F_rel @ Dinv
