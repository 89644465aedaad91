"""Experiment design: inputs that make the Fisher information of the parameters large, in a box.

The inputs are piecewise constant over `segment_s` levels per channel (alpha1 = alpha2 = alpha,
n1, n2, nt); the model's prediction from rest gives the trajectory (area constraint) and the
window-wise forward sensitivities give the Fisher information F of the free parameters, with
the initial state of every estimation window marginalised, exactly as the estimator sees it
(lotsen.sysid.estimate). The criterion works on the relative information (parameters scaled by
their size):
    A: J = log( mean_i (relvar_i)^p )^(1/p),  relvar_i = (F^-1)_ii / theta_i^2, p = 4
       (a smooth stand-in for the worst relative variance, which the 5 % target is about)
    D: J = -log det(F_rel) / n_free
plus a quadratic penalty on positions outside the area (with a margin). L-BFGS-B over the
levels within the actuator limits, gradients by finite differences (each evaluation is one
CasADi simulation with sensitivities, ~10 ms for a minute of 8 Hz data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, VesselParameters
from lotsen.sysid.data import OUTPUT_COLUMNS, Segment, split_windows
from lotsen.sysid.estimate import DEFAULT_NOISE_STD, NAMES, marginal_fisher, parameter_scale, _normal_blocks, \
    _X0_SCALE
from lotsen.sysid.experiment import Area, Experiment, Piece
from lotsen.sysid.sensitivity import WindowSimulator

# Parameters the design does not target, and the estimator keeps at their defaults, because no
# experiment of this vessel in a 30 m x 30 m box determines them to 5 % in minutes (see
# docs/sysid.md, "Identifiability in practice" and bench/bench_sysid.py): m11 fixes the scale.
DEFAULT_KNOWN = ("m11", "Y_r", "Y_rv", "N_v", "N_vv", "kappa")


@dataclass
class InformationModel:
    """Reusable simulators for the Fisher information of one sampling grid and window length."""

    t: np.ndarray  # row times
    output_rows: np.ndarray  # bool per row: outputs measured
    window_s: float = 10.0
    noise_std: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_NOISE_STD))
    output_names: tuple[str, ...] = OUTPUT_COLUMNS
    h_max: float = 0.0625

    def __post_init__(self) -> None:
        n = len(self.t)
        y = np.where(self.output_rows[:, None], 0.0, np.nan) * np.ones((n, len(self.output_names)))
        seg = Segment(self.t, np.zeros((n, 5)), y, self.output_names)
        self._full = WindowSimulator([seg], h_max=self.h_max)
        self.windows = split_windows([seg], self.window_s)
        self._win = WindowSimulator(self.windows, h_max=self.h_max)
        self._starts = np.array([w.first_row for w in self.windows])
        self._mask = np.vstack([np.isfinite(w.outputs) for w in self.windows])
        self._sqrt_w = np.array([1.0 / self.noise_std[n] for n in self.output_names])
        self._out_idx = self._win.output_index()
        self._wos = self._win.grid.window_of_sample

    def _set_inputs(self, U_rows: np.ndarray) -> None:
        from lotsen.sysid.sensitivity import make_grid

        seg = Segment(self.t, U_rows, np.zeros((len(self.t), 1)), ("north",))
        self._full.grid.U = make_grid([seg], self.h_max).U
        wins = [Segment(w.t, U_rows[w.first_row:w.first_row + len(w.t)], w.outputs, w.output_names, first_row=w.first_row)
                for w in self.windows]
        self._win.grid.U = make_grid(wins, self.h_max).U

    def trajectory(self, U_rows: np.ndarray, theta: Sequence[float], x0: Sequence[float]) -> np.ndarray:
        self._set_inputs(U_rows)
        return self._full.simulate(theta, np.asarray(x0, float)[None, :])

    def fisher(self, U_rows: np.ndarray, theta: Sequence[float], x0: Sequence[float],
               free_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        """(F of free_names in absolute units, predicted states per row)."""
        theta = np.asarray(theta, float)
        X = self.trajectory(U_rows, theta, x0)
        if not np.all(np.isfinite(X)):
            return np.full((len(free_names),) * 2, np.nan), X
        x0s = X[self._starts]
        _, S = self._win.simulate_sens(theta, x0s)
        free = np.array([NAMES.index(n) for n in free_names], dtype=int)
        tscale = parameter_scale(theta)

        class _P:  # the fields _normal_blocks reads
            pass

        p = _P()
        p.out_idx, p.sqrt_w, p.mask, p.n_windows, p.window_of_sample = (
            self._out_idx, self._sqrt_w, self._mask, len(self.windows), self._wos)
        nb = _normal_blocks(p, S, np.zeros(self._mask.shape), free, tscale, _X0_SCALE)  # type: ignore[arg-type]
        Dinv = np.diag(1.0 / tscale[free])
        return Dinv @ marginal_fisher(nb) @ Dinv, X


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
    window_s: float = 10.0
    iterations: int = 40
    seed: int = 0
    sample_rate_hz: float = 8.0
    noise_std: tuple[tuple[str, float], ...] = tuple(DEFAULT_NOISE_STD.items())
    limits: ActuatorLimits = DEFAULT_LIMITS
    start_speed_mps: float = 0.0


@dataclass
class DesignResult:
    experiment: Experiment
    free_names: tuple[str, ...]
    fisher: np.ndarray
    rel_std: np.ndarray
    criterion_value: float
    trajectory: np.ndarray
    history: list[float]
    time_to_5pct_s: float

    def summary(self) -> str:
        worst = int(np.argmax(self.rel_std))
        return (f"{self.experiment.duration_s:.0f} s designed experiment; worst 1.96-sigma relative error "
                f"{196 * self.rel_std[worst]:.1f} % ({self.free_names[worst]}); experiment time to 5 % for all "
                f"{len(self.free_names)} estimated parameters: {self.time_to_5pct_s:.0f} s "
                f"(known/fixed: {', '.join(n for n in NAMES if n not in self.free_names)})")


def _levels_to_rows(z: np.ndarray, nseg: int, rows_per_seg: int, lim: np.ndarray) -> np.ndarray:
    """Decision vector (nseg x 4 in [-1, 1]) -> input rows (alpha1 = alpha2)."""
    L = z.reshape(nseg, 4) * lim[None, :]
    U = np.column_stack([L[:, 0], L[:, 0], L[:, 1], L[:, 2], L[:, 3]])
    return np.repeat(U, rows_per_seg, axis=0)


def design_experiment(params: VesselParameters, config: DesignConfig = DesignConfig(),
                      progress: Callable[[int, float], None] | None = None,
                      initial: np.ndarray | None = None) -> DesignResult:
    """Optimise piecewise-constant inputs for the Fisher information inside the area."""
    from scipy.optimize import minimize

    cfg = config
    theta = np.array(params.to_vector())
    free_names = tuple(n for n in NAMES if n not in cfg.fixed)
    th_free = np.array([theta[NAMES.index(n)] for n in free_names])
    rows_per_seg = int(round(cfg.segment_s * cfg.sample_rate_hz))
    nseg = int(math.ceil(cfg.duration_s / cfg.segment_s))
    n_rows = nseg * rows_per_seg
    t = np.arange(n_rows) / cfg.sample_rate_hz
    info = InformationModel(t, np.ones(n_rows, bool), cfg.window_s, dict(cfg.noise_std))
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

    def objective(z: np.ndarray) -> float:
        U = _levels_to_rows(z, nseg, rows_per_seg, lim)
        F, X = info.fisher(U, theta, x0, free_names)
        if not np.all(np.isfinite(F)):
            return 1e6
        Fr = F * th_free[:, None] * th_free[None, :]  # relative information
        try:
            if cfg.criterion == "D":
                sign, logdet = np.linalg.slogdet(Fr)
                J = -logdet / len(free_names) if sign > 0 else 1e3
            else:
                rv = np.diag(np.linalg.inv(Fr))
                J = math.log(np.mean(np.abs(rv) ** p_norm)) / p_norm if np.all(rv > 0) else 1e3
        except np.linalg.LinAlgError:
            J = 1e3
        m = cfg.margin_m
        over = (np.maximum(X[:, 0] - (area.north_m[1] - m), 0) + np.maximum((area.north_m[0] + m) - X[:, 0], 0)
                + np.maximum(X[:, 1] - (area.east_m[1] - m), 0) + np.maximum((area.east_m[0] + m) - X[:, 1], 0))
        return J + 10.0 * float(np.mean(over ** 2)) * len(over) / 8.0

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
    F, X = info.fisher(U, theta, x0, free_names)
    rs = relative_std(F, theta, free_names)
    L = U[::rows_per_seg]
    piece = Piece("piecewise", nseg * cfg.segment_s, {"segment_s": cfg.segment_s, "table": L}, "designed")
    exp = Experiment(f"designed_{cfg.duration_s:.0f}s", (piece,), area, 0.0, cfg.start_speed_mps, 20.0,
                     description=f"{cfg.criterion}-optimal piecewise-constant inputs for "
                                 f"{', '.join(free_names)} (known: {', '.join(cfg.fixed)})")
    return DesignResult(exp, free_names, F, rs, float(res.fun), X, history,
                        time_to_accuracy(rs, nseg * cfg.segment_s))
