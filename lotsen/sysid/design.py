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

Speed (issue 49): the candidates are evaluated by `DesignInformation` (grid, kernels and the KKT
matrix's pattern made once; a banded elimination in time order), and a finite-difference column,
which changes one level, reuses the trajectory and the intervals before that level's segment from the
point it differs from; the optimisation integrates with one RK4 step per row (`OPTIMISATION_H_MAX`).
A 60-s design: 24 s of CPU instead of 119 s (and 214 s in the issue), A and D criteria within 0.5 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_LIMITS, ActuatorLimits, VesselGeometry, VesselParameters, geometry_tuple
from lotsen.sysid.data import OUTPUT_COLUMNS, OUTPUT_STATE_INDEX, IdRecord, Segment
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.estimate import DEFAULT_NOISE_STD, NAMES, parameter_scale
from lotsen.sysid.experiment import Area, Experiment, Piece

# Only the scale is fixed (docs/sysid.md "Scale"); every other parameter is designed for.
DEFAULT_KNOWN = ("m11",)
#: the optimisation's integration step, s: one RK4 step per 8-Hz row instead of two, half the simulation. A
#: cheaper measure of the same information: the A and D criteria within 0.003 of the 0.0625-s step's
#: (measured 2026-11-28 on the 60-s design of the unchanged code and three random designs, two parameter
#: sets each); the designed experiment is reported at the estimator's 0.0625 s
OPTIMISATION_H_MAX = 0.125


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


@dataclass
class Evaluation:
    """One input sequence at one parameter vector (`DesignInformation.evaluate`): the states at every row
    and each shooting interval's share of the information, which a candidate that differs only in later
    inputs reuses."""

    X: np.ndarray  # n_rows x 6
    Hss: np.ndarray  # per node: J_x^T J_x of its interval's rows (scaled node state)
    Hsp: np.ndarray  # per node: J_x^T J_p (relative parameters)
    Hpp: np.ndarray  # per node: J_p^T J_p
    Gx: np.ndarray  # per interval with a successor: d (scaled end state) / d (scaled node state)
    Gp: np.ndarray  # ... / d (relative parameters)
    F: np.ndarray  # the free parameters' information, absolute units (NaN: the boat left the model's range)


class DesignInformation:
    """The whole-record Fisher information of held inputs on one time grid, every row measured, the node
    states eliminated under continuity: lotsen.sysid.multiple.record_fisher's F (within ~1e-9 relative,
    tests/sysid/test_design_multiple.py), made for the design's thousands of candidates.

    The grid, the kernels, the scales and the KKT matrix's pattern are made once. The nodes and the
    continuity constraints are ordered in time, (s_0, lambda_0, s_1, lambda_1, ...), which makes the
    KKT matrix banded (11 diagonals either side): LAPACK's banded LU with partial pivoting eliminates
    them (scipy.linalg.solve_banded), a fraction of a sparse LU's cost on 30 nodes. A candidate that
    differs from `base` only in inputs from row `from_row` on (a finite-difference column of the
    design's gradient) keeps the trajectory and the intervals before the node whose interval holds
    that row (`evaluate(..., base=, from_row=)`): on average half the simulation, and the same numbers
    as a whole evaluation to the last digit. (A forward or backward recursion over the intervals would
    have reused the elimination too, but it multiplies the information by the flow's Jacobians or
    their inverses, and the boat's damped and unstable modes overflow it within 30 intervals.)"""

    def __init__(self, t: np.ndarray, free_names: Sequence[str], noise_std: dict[str, float] | None = None,
                 output_names: tuple[str, ...] = OUTPUT_COLUMNS, h_max: float = 0.0625, node_s: float = 2.0,
                 geometry: VesselGeometry = DEFAULT_GEOMETRY) -> None:
        from lotsen.sysid.kernels import step_kernels
        from lotsen.sysid.multiple import X_SCALE, build_grid

        t = np.asarray(t, float)
        n = len(t)
        # the template's first input is the row number: its grid's input lines name each step's row
        template = Segment(t, np.column_stack([np.arange(n, dtype=float), np.zeros((n, 4))]),
                           np.zeros((n, len(output_names))), tuple(output_names))
        g = build_grid([template], node_s, h_max)
        self.grid = g
        self.step_row = g.U[:, 0].astype(int)
        self.free = np.array([NAMES.index(n) for n in free_names], dtype=int)
        noise = {**DEFAULT_NOISE_STD, **(noise_std or {})}
        self.sqrt_w = np.array([1.0 / noise[o] for o in output_names])
        self.out_idx = [OUTPUT_STATE_INDEX[o] for o in output_names]
        self.kernels = step_kernels(geometry_tuple(geometry))
        self.node_row = np.searchsorted(t, g.node_time)
        self.meas_bounds = np.searchsorted(g.meas_node, np.arange(g.n_nodes + 1))
        self.xs = X_SCALE
        self._band_pattern()
        self._from: dict[int, tuple[np.ndarray, ...]] = {}
        self._scales: dict[bytes, np.ndarray] = {}  # the free parameters' scale at each parameter vector
        self._cols = np.concatenate([np.arange(6), 6 + self.free])  # S's columns: node state, free parameters
        self._w_col = self.sqrt_w[:, None]

    def _steps_from(self, m: int) -> tuple[np.ndarray, ...]:
        """From node m on (local steps): each row's step, the interval ends, the steps needed, their
        positions in it, and each node's rows padded to the longest interval's (a batched product)."""
        if m not in self._from:
            g = self.grid
            s0, r0 = int(g.node_step[m]), int(self.node_row[m])
            rows_steps = g.meas_step[r0:] - s0  # every row is measured: one measurement step per row
            ends = g.end_step[m:][g.has_next[m:]] - s0
            need = np.unique(np.concatenate([rows_steps, ends]))
            bounds = self.meas_bounds[m:] - self.meas_bounds[m]
            longest = int(np.max(np.diff(bounds)))
            # node k's j-th row at padded[k, j] (rows beyond a node's own count point at a zero row)
            padded = np.full((len(bounds) - 1, longest), len(rows_steps))
            for k in range(len(bounds) - 1):
                padded[k, :bounds[k + 1] - bounds[k]] = np.arange(bounds[k], bounds[k + 1])
            self._from[m] = (rows_steps, ends, need, np.searchsorted(need, rows_steps), np.searchsorted(need, ends),
                             padded)
        return self._from[m]

    def _band_pattern(self) -> None:
        """Where each block of the KKT matrix goes in LAPACK's band storage (fixed for the grid)."""
        N = self.grid.n_nodes
        self.n_kkt = 12 * N - 6
        i6 = np.arange(6)
        s_at = 12 * np.arange(N)  # node i's state
        l_at = 12 * np.arange(N - 1) + 6  # constraint i: G_x s_i - s_{i+1}
        rows = [s_at[:, None, None] + i6[None, :, None] + 0 * i6[None, None, :]]  # H_ss
        cols = [s_at[:, None, None] + 0 * i6[None, :, None] + i6[None, None, :]]
        rows += [l_at[:, None, None] + i6[None, :, None] + 0 * i6[None, None, :]]  # G_x in the constraint's rows
        cols += [s_at[:-1, None, None] + 0 * i6[None, :, None] + i6[None, None, :]]
        rows += [cols[1], (l_at[:, None] + i6[None, :]), (s_at[1:, None] + i6[None, :])]  # G_x^T; -I and its transpose
        cols += [rows[1], (s_at[1:, None] + i6[None, :]), (l_at[:, None] + i6[None, :])]
        r, c = np.concatenate([x.ravel() for x in rows]), np.concatenate([x.ravel() for x in cols])
        self._half_band = u = 11
        self._band_at = (2 * u + r - c) * self.n_kkt + c  # flat positions in LAPACK's band storage
        self._B_state_rows = (s_at[:, None] + i6[None, :]).ravel()
        self._B_constraint_rows = (l_at[:, None] + i6[None, :]).ravel()

    def node_of_row(self, row: int) -> int:
        """The node whose interval holds `row` (its state at the node row does not depend on the input there)."""
        return int(np.searchsorted(self.node_row, row, side="right") - 1)

    def evaluate(self, U_rows: np.ndarray, theta: np.ndarray, x0: np.ndarray, base: Evaluation | None = None,
                 from_row: int = 0) -> Evaluation:
        """The trajectory and information of inputs `U_rows` (rows x 5, held) at `theta` from `x0`; with
        `base` (the same theta and x0, inputs equal before row `from_row`), from there on only."""
        g, k, xs = self.grid, self.kernels, self.xs
        theta = np.asarray(theta, float)
        m = self.node_of_row(from_row) if base is not None else 0
        s0, r0 = int(g.node_step[m]), int(self.node_row[m])
        lines = np.zeros((g.n_steps - s0, 10))
        lines[:, :5] = U_rows[self.step_row[s0:]]
        h = g.h[s0:]
        # the trajectory: one simulation from the node (x0 at the start), the node rows' resets off
        reset = np.zeros(len(h))
        reset[0] = 1.0
        start = np.asarray(x0, float) if base is None else base.X[r0]
        rows_steps, ends, need, at_rows, at_ends, padded = self._steps_from(m)
        Xs, _ = k.run_record(theta, h, lines, reset, np.zeros(1, int), start[None, :], rows_steps, False)
        X = Xs if base is None else np.vstack([base.X[:r0], Xs])
        nf = len(self.free)
        if not np.all(np.isfinite(X)) or np.abs(X[:, 3:]).max() > 50:
            nan = np.full((nf, nf), np.nan)
            return Evaluation(X, np.zeros((0, 6, 6)), np.zeros((0, 6, nf)), np.zeros((0, nf, nf)),
                              np.zeros((0, 6, 6)), np.zeros((0, 6, nf)), nan)
        # the intervals from node m: sensitivities, their share of the normal equations, continuity
        _, S = k.run_record(theta, h, lines, g.reset[s0:], g.node_step[m:] - s0, X[self.node_row[m:]], need, True)
        key = theta.tobytes()
        if key not in self._scales:
            self._scales[key] = parameter_scale(theta)[self.free]
        ts = self._scales[key]
        cols = self._cols
        scale = np.concatenate([xs, ts])
        J = np.zeros((len(at_rows) + 1, len(self.out_idx), len(cols)))  # the last row: zeros (padding)
        J[:-1] = S[np.ix_(at_rows, self.out_idx, cols)] * self._w_col * scale  # type: ignore[index]
        Jn = J[padded].reshape(len(padded), -1, len(cols))  # per node its rows' Jacobians stacked
        H = np.matmul(Jn.transpose(0, 2, 1), Jn)
        Hss, Hsp, Hpp = H[:, :6, :6], H[:, :6, 6:], H[:, 6:, 6:]
        Se = S[at_ends][:, :6, :]  # type: ignore[index]
        Gx = Se[:, :, :6] * xs[None, :] / xs[:, None]
        Gp = Se[:, :, 6 + self.free] * ts / xs[:, None]
        if base is not None:
            Hss, Hsp, Hpp = (np.concatenate([a[:m], x]) for a, x in ((base.Hss, Hss), (base.Hsp, Hsp), (base.Hpp, Hpp)))
            Gx, Gp = np.concatenate([base.Gx[:m], Gx]), np.concatenate([base.Gp[:m], Gp])
        return Evaluation(X, Hss, Hsp, Hpp, Gx, Gp, self._eliminate(Hss, Hsp, Hpp, Gx, Gp) / np.outer(ts, ts))

    def _eliminate(self, Hss: np.ndarray, Hsp: np.ndarray, Hpp: np.ndarray, Gx: np.ndarray,
                   Gp: np.ndarray) -> np.ndarray:
        """F = H_pp - B^T A^-1 B (relative parameters), A the time-ordered banded KKT matrix."""
        from scipy.linalg.lapack import dgbsv

        N, nf, u = len(Hss), Hpp.shape[1], self._half_band
        H = Hss.copy()
        d = np.einsum("kii->ki", H)
        d += 1e-12 * np.maximum(d, 0.0)  # multiple._fisher_from's whisper of damping
        minus = -np.ones(6 * (N - 1))
        band = np.zeros((3 * u + 1, self.n_kkt))  # LAPACK's banded LU keeps u more rows for its pivoting
        band.ravel()[self._band_at] = np.concatenate([H.ravel(), Gx.ravel(), Gx.ravel(), minus, minus])
        B = np.zeros((self.n_kkt, nf))
        B[self._B_state_rows] = Hsp.reshape(6 * N, nf)
        B[self._B_constraint_rows] = Gp.reshape(6 * (N - 1), nf)
        _, _, AinvB, info = dgbsv(u, u, band, B)
        if info != 0:
            return np.full((nf, nf), np.nan)
        F = Hpp.sum(axis=0) - B.T @ AinvB
        return 0.5 * (F + F.T)


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
    """1-sigma relative to |theta| of each free parameter from the Fisher information; |theta| floored at a
    tenth of the default's magnitude (`parameter_scale`): a coefficient an identification left at zero (at
    its physical bound) has no relative error, and a design for it (`--params`) saw an infinite one."""
    scale = parameter_scale(theta)[[NAMES.index(n) for n in free_names]]
    try:
        C = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        return np.full(len(free_names), np.inf)
    d = np.diag(C)
    return np.where(d > 0, np.sqrt(np.abs(d)), np.inf) / scale


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
    info = DesignInformation(t, free_names, dict(cfg.noise_std), h_max=OPTIMISATION_H_MAX, node_s=cfg.node_s)
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

    # relative information; the scale floored as relative_std's: with a coefficient at zero (a design for
    # an identified model, --params) the relative information was singular, every point scored alike and
    # the optimiser stopped where it started. Once per parameter set: crit runs thousands of times
    scales = [parameter_scale(th)[fidx] for th in samples]

    def crit(F: np.ndarray, thf: np.ndarray) -> float:
        if not np.all(np.isfinite(F)):
            return 1e3
        Fr = F * thf[:, None] * thf[None, :]
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

    def evaluate(z: np.ndarray, base: list[Evaluation] | None = None, from_row: int = 0) -> tuple[float, list]:
        U = _levels_to_rows(z, nseg, rows_per_seg, lim)
        evs = [info.evaluate(U, th, x0, base[i] if base else None, from_row) for i, th in enumerate(samples)]
        return sum(crit(ev.F, sc) + penalty(ev.X) for ev, sc in zip(evs, scales)) / len(samples), evs

    # the last point evaluated: L-BFGS-B asks for the finite-difference columns of the gradient right after
    # the value at the same point, and each column changes one level: the columns reuse its evaluation
    # before that level's segment (DesignInformation), the same numbers as a whole evaluation
    last: dict = {}

    def objective(z: np.ndarray) -> float:
        if "z" in last and np.array_equal(z, last["z"]):
            return last["J"]
        J, evs = evaluate(z)
        last.update(z=np.array(z), J=J, evs=evs)
        return J

    def columns(_fun: Callable, points: Iterable[np.ndarray]) -> list[float]:
        out = []
        for zp in points:
            changed = np.flatnonzero(zp != last.get("z", np.full_like(zp, np.nan)))
            if len(changed) == 1:
                out.append(evaluate(zp, last["evs"], int(changed[0]) // 4 * rows_per_seg)[0])
            else:
                out.append(evaluate(zp)[0])
        return out

    history: list[float] = []
    it = [0]

    def callback(zk: np.ndarray) -> None:
        it[0] += 1
        history.append(objective(zk))
        if progress:
            progress(it[0], history[-1])

    res = minimize(objective, z0, method="L-BFGS-B", bounds=[(-1.0, 1.0)] * len(z0), callback=callback,
                   options=dict(maxiter=cfg.iterations, eps=1e-3, maxfun=cfg.iterations * (len(z0) + 1) * 2,
                                workers=columns))
    z = res.x
    U = _levels_to_rows(z, nseg, rows_per_seg, lim)
    rs_all, trajs, first_F = [], [], None
    report = DesignInformation(t, free_names, dict(cfg.noise_std), node_s=cfg.node_s)  # the estimator's step
    for th in samples:
        ev = report.evaluate(U, th, x0)
        F, X = ev.F, ev.X
        first_F = F if first_F is None else first_F
        rs_all.append(relative_std(F, th, free_names) if np.all(np.isfinite(F)) else np.full(len(free_names), np.inf))
        trajs.append(X)
    rs_all = np.array(rs_all)
    L = U[::rows_per_seg]
    piece = Piece("piecewise", nseg * cfg.segment_s, {"segment_s": cfg.segment_s, "table": L}, "designed")
    exp = Experiment(f"designed_{cfg.duration_s:.0f}s", (piece,), area, 0.0, cfg.start_speed_mps, 20.0,
                     description=f"{cfg.criterion}-optimal piecewise-constant inputs for "
                                 f"{', '.join(free_names)} (fixed: {', '.join(cfg.fixed)}), robust over "
                                 f"{len(samples)} parameter sets within +-{100 * cfg.robust_spread:.0f} %")
    return DesignResult(exp, free_names, first_F, rs_all[0], float(res.fun),
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
