"""Experiment design: inputs that make the Fisher information of the parameters large, in a box,
for a range of parameter values (robust to the prior).

The inputs are piecewise constant over `segment_s` levels per channel (alpha1 = alpha2 = alpha,
n1, n2, nt). For each parameter vector of a small set around the prior (the prior itself and
`robust_samples - 1` draws within +-`robust_spread`), the model's prediction from rest gives the
trajectory (area constraint) and the Fisher information F of the free parameters of the *whole
record*, every node state eliminated under continuity, exactly as the multiple-shooting
estimator sees it (lotsen.sysid.multiple.record_fisher). The criterion works on the relative
information (parameters scaled by their size) and is averaged over the set:
    A: J = log( mean_i (relvar_i)^p )^(1/p),  relvar_i = (F^-1)_ii / theta_i^2, p = 4
       (a smooth stand-in for the worst relative variance, which the 5 % target is about)
    D: J = -log det(F_rel) / n_free
plus a quadratic penalty on positions outside the area (with a margin) for every member of the
set. L-BFGS-B over the levels within the actuator limits, gradients by finite differences.
By default every parameter but the scale (m11) is free: nothing is held at a default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, VesselParameters
from lotsen.sysid.data import OUTPUT_COLUMNS, IdRecord
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.estimate import DEFAULT_NOISE_STD, NAMES
from lotsen.sysid.experiment import Area, Experiment, Piece

# Only the scale is fixed (docs/sysid.md "Scale"); every other parameter is designed for.
DEFAULT_KNOWN = ("m11",)


@dataclass
class InformationModel:
    """Whole-record Fisher information of an input sequence on a fixed time grid.

    `t` are the row times, `output_rows` marks the rows with measurements (all outputs)."""

    t: np.ndarray
    output_rows: np.ndarray
    window_s: float | None = None  # unused (kept for callers of the windowed version)
    noise_std: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_NOISE_STD))
    output_names: tuple[str, ...] = OUTPUT_COLUMNS
    h_max: float = 0.0625
    node_s: float = 2.0

    def _problem(self, U_rows: np.ndarray, rows: np.ndarray, node_s: float):  # type: ignore[no-untyped-def]
        from lotsen.sysid.estimate import SolverOptions
        from lotsen.sysid.multiple import MultipleShootingProblem

        n = len(self.t)
        Y = np.full((n, len(self.output_names)), np.nan)
        Y[rows] = 0.0
        rec = IdRecord(self.t, U_rows, Y, self.output_names, "design")
        return MultipleShootingProblem([rec], SolverOptions(gap_s=math.inf, noise_std=dict(self.noise_std or {}),
                                                            h_max=self.h_max, node_s=node_s))

    def trajectory(self, U_rows: np.ndarray, theta: Sequence[float], x0: Sequence[float]) -> np.ndarray:
        """The model's prediction at every row from x0 (one simulation, no noise)."""
        prob = self._problem(U_rows, np.ones(len(self.t), bool), 1e12)
        Xm, _ = prob.sim.run(np.asarray(theta, float), np.asarray(x0, float)[None, :], False)
        return Xm

    def fisher(self, U_rows: np.ndarray, theta: Sequence[float], x0: Sequence[float],
               free_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """(F of free_names in absolute units, predicted states per row)."""
        from lotsen.sysid.multiple import record_fisher

        theta = np.asarray(theta, float)
        X = self.trajectory(U_rows, theta, x0)
        if not np.all(np.isfinite(X)) or np.abs(X[:, 3:]).max() > 50:
            return np.full((len(free_names),) * 2, np.nan), X
        prob = self._problem(U_rows, np.asarray(self.output_rows, bool), self.node_s)
        rows = np.searchsorted(self.t, prob.grid.node_time)
        F = record_fisher([], VesselParameters.from_vector(theta), free_names, problem=prob, nodes=X[rows])
        return F, X


def parameter_samples(params: VesselParameters, n: int, spread: float, seed: int = 0,
                      keep: Sequence[str] = DEFAULT_KNOWN) -> list[np.ndarray]:
    """The prior and n - 1 parameter vectors with every parameter but `keep` scaled by 1 +- spread."""
    theta = np.array(params.to_vector())
    rng = np.random.default_rng(np.random.SeedSequence([seed, 16]))
    out = [theta]
    for _ in range(max(n, 1) - 1):
        f = rng.uniform(1 - spread, 1 + spread, len(theta))
        f[[NAMES.index(k) for k in keep if k in NAMES]] = 1.0
        out.append(theta * f)
    return out


def relative_std(F: np.ndarray, theta: Sequence[float], free_names: Sequence[str]) -> np.ndarray:
    """1-sigma relative to |theta| of each free parameter from the Fisher information."""
    th = np.array([theta[NAMES.index(n)] for n in free_names])
    try:
        C = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        return np.full(len(free_names), np.inf)
    d = np.diag(C)
    return np.where(d > 0, np.sqrt(np.abs(d)), np.inf) / np.maximum(np.abs(th), 1e-12)


def time_to_accuracy(rel_std: np.ndarray, duration_s: float, target: float = 0.05, z: float = 1.96) -> float:
    """Experiment time for z * sigma / |theta| <= target for every parameter, repeating the experiment.

    Information adds over repetitions, so sigma scales as 1/sqrt(time)."""
    worst = float(np.max(z * rel_std / target))
    return duration_s * worst * worst


@dataclass(frozen=True)
class DesignConfig:
    duration_s: float = 60.0
    area_size_m: tuple[float, float] = (30.0, 30.0)
    margin_m: float = 2.0
    segment_s: float = 3.0
    criterion: str = "A"
    fixed: tuple[str, ...] = DEFAULT_KNOWN
    iterations: int = 40
    seed: int = 0
    sample_rate_hz: float = 8.0
    noise_std: tuple[tuple[str, float], ...] = tuple(DEFAULT_NOISE_STD.items())
    limits: ActuatorLimits = DEFAULT_LIMITS
    start_speed_mps: float = 0.0
    robust_samples: int = 3  # the prior + 2 draws: the design must work for all of them
    robust_spread: float = 0.15
    node_s: float = 2.0


@dataclass
class DesignResult:
    experiment: Experiment
    free_names: tuple[str, ...]
    fisher: np.ndarray
    rel_std: np.ndarray
    criterion_value: float
    trajectory: np.ndarray
    history: list[float]
    time_to_5pct_s: float  # worst over the parameter set, repeating the experiment
    rel_std_samples: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # per member of the set
    trajectories: list[np.ndarray] = field(default_factory=list)

    def summary(self) -> str:
        worst = int(np.argmax(self.rel_std))
        return (f"{self.experiment.duration_s:.0f} s designed experiment; at the prior the worst 1.96-sigma relative "
                f"error is {196 * self.rel_std[worst]:.1f} % ({self.free_names[worst]}); experiment time to 5 % for "
                f"all {len(self.free_names)} estimated parameters (worst over {max(len(self.rel_std_samples), 1)} "
                f"parameter sets, repeating it): {self.time_to_5pct_s:.0f} s "
                f"(fixed: {', '.join(n for n in NAMES if n not in self.free_names)})")


def _levels_to_rows(z: np.ndarray, nseg: int, rows_per_seg: int, lim: np.ndarray) -> np.ndarray:
    """Decision vector (nseg x 4 in [-1, 1]) -> input rows (alpha1 = alpha2)."""
    L = z.reshape(nseg, 4) * lim[None, :]
    U = np.column_stack([L[:, 0], L[:, 0], L[:, 1], L[:, 2], L[:, 3]])
    return np.repeat(U, rows_per_seg, axis=0)


def design_experiment(params: VesselParameters, config: DesignConfig = DesignConfig(),
                      progress: Callable[[int, float], None] | None = None,
                      initial: np.ndarray | None = None) -> DesignResult:
    """Optimise piecewise-constant inputs for the whole-record information over a parameter set."""
    from scipy.optimize import minimize

    cfg = config
    # the optional model terms are off unless identification turns them on: not designed for
    free_names = tuple(n for n in NAMES if n not in cfg.fixed and n not in OPTIONAL_TERMS)
    samples = parameter_samples(params, cfg.robust_samples, cfg.robust_spread, cfg.seed, cfg.fixed)
    rows_per_seg = int(round(cfg.segment_s * cfg.sample_rate_hz))
    nseg = int(math.ceil(cfg.duration_s / cfg.segment_s))
    n_rows = nseg * rows_per_seg
    t = np.arange(n_rows) / cfg.sample_rate_hz
    info = InformationModel(t, np.ones(n_rows, bool), None, dict(cfg.noise_std), node_s=cfg.node_s)
    lim = np.array([cfg.limits.alpha_max_rad, cfg.limits.n_az_max_rps, cfg.limits.n_az_max_rps,
                    cfg.limits.n_bow_max_rps])
    area = Area.centred(*cfg.area_size_m)
    x0 = np.array([0.0, 0.0, 0.0, cfg.start_speed_mps, 0.0, 0.0])
    rng = np.random.default_rng(cfg.seed)
    if initial is None:
        # a start that turns a lot at moderate speed: random steering, forward thrust, bow thruster
        z0 = np.column_stack([rng.uniform(-1, 1, nseg), rng.uniform(0.3, 0.8, nseg),
                              rng.uniform(0.3, 0.8, nseg), rng.uniform(-1, 1, nseg)]).ravel()
    else:
        z0 = np.asarray(initial, float).ravel()
    p_norm = 4.0
    fidx = np.array([NAMES.index(n) for n in free_names])

    def crit(F: np.ndarray, th: np.ndarray) -> float:
        if not np.all(np.isfinite(F)):
            return 1e3
        thf = th[fidx]
        Fr = F * thf[:, None] * thf[None, :]  # relative information
        try:
            if cfg.criterion == "D":
                sign, logdet = np.linalg.slogdet(Fr)
                return -logdet / len(free_names) if sign > 0 else 1e3
            rv = np.diag(np.linalg.inv(Fr))
            return math.log(np.mean(np.abs(rv) ** p_norm)) / p_norm if np.all(rv > 0) else 1e3
        except np.linalg.LinAlgError:
            return 1e3

    def penalty(X: np.ndarray) -> float:
        m = cfg.margin_m
        if not np.all(np.isfinite(X)):
            return 1e6
        over = (np.maximum(X[:, 0] - (area.north_m[1] - m), 0) + np.maximum((area.north_m[0] + m) - X[:, 0], 0)
                + np.maximum(X[:, 1] - (area.east_m[1] - m), 0) + np.maximum((area.east_m[0] + m) - X[:, 1], 0))
        return 10.0 * float(np.mean(over ** 2)) * len(over) / 8.0

    def objective(z: np.ndarray) -> float:
        U = _levels_to_rows(z, nseg, rows_per_seg, lim)
        J = 0.0
        for th in samples:
            F, X = info.fisher(U, th, x0, free_names)
            J += crit(F, th) + penalty(X)
        return J / len(samples)

    history: list[float] = []
    it = [0]

    def callback(zk: np.ndarray) -> None:
        it[0] += 1
        history.append(objective(zk))
        if progress:
            progress(it[0], history[-1])

    res = minimize(objective, z0, method="L-BFGS-B", bounds=[(-1.0, 1.0)] * len(z0), callback=callback,
                   options=dict(maxiter=cfg.iterations, eps=1e-3, maxfun=cfg.iterations * (len(z0) + 1) * 2))
    z = res.x
    U = _levels_to_rows(z, nseg, rows_per_seg, lim)
    rs_all, trajs = [], []
    for th in samples:
        F, X = info.fisher(U, th, x0, free_names)
        rs_all.append(relative_std(F, th, free_names) if np.all(np.isfinite(F)) else np.full(len(free_names), np.inf))
        trajs.append(X)
    rs_all = np.array(rs_all)
    L = U[::rows_per_seg]
    piece = Piece("piecewise", nseg * cfg.segment_s, {"segment_s": cfg.segment_s, "table": L}, "designed")
    exp = Experiment(f"designed_{cfg.duration_s:.0f}s", (piece,), area, 0.0, cfg.start_speed_mps, 20.0,
                     description=f"{cfg.criterion}-optimal piecewise-constant inputs for "
                                 f"{', '.join(free_names)} (fixed: {', '.join(cfg.fixed)}), robust over "
                                 f"{len(samples)} parameter sets within +-{100 * cfg.robust_spread:.0f} %")
    return DesignResult(exp, free_names, info.fisher(U, samples[0], x0, free_names)[0], rs_all[0], float(res.fun),
                        trajs[0], history, time_to_accuracy(rs_all.max(axis=0), nseg * cfg.segment_s), rs_all, trajs)


def experiment_information(experiment: Experiment, params: VesselParameters, free_names: Sequence[str],
                           sample_rate_hz: float = 8.0, dt_s: float = 0.025,
                           noise_std: dict[str, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Whole-record relative std of `free_names` for an experiment (set-points applied directly,
    outputs at sample_rate_hz), predicted with `params`: (rel_std, predicted states)."""
    from lotsen.model import VesselModel
    from lotsen.sysid.experiment import predict_trajectory

    pred = predict_trajectory(experiment, VesselModel(params), dt_s=dt_s)
    t, U = pred.t[:-1], pred.u[:-1]
    every = max(1, int(round(1.0 / (sample_rate_hz * dt_s))))
    info = InformationModel(t, np.arange(len(t)) % every == 0, None, dict(noise_std or DEFAULT_NOISE_STD))
    x0 = pred.x[0]
    F, X = info.fisher(U, params.to_vector(), x0, free_names)
    if not np.all(np.isfinite(F)):
        return np.full(len(free_names), np.inf), X
    return relative_std(F, params.to_vector(), free_names), X
