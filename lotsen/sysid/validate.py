"""Validation on held-out data: simulation fit per output and residual analysis.

The model is simulated over the validation data in windows of `window_s` (the model is open-loop
unstable at speed, so a free-run over minutes measures the instability, not the parameters), each
window starting from an initial state estimated on that window with the parameters held fixed.
    fit = 100 (1 - ||y - yhat|| / ||y - mean(y)||)   per output, over finite samples (NRMSE fit)
Residual analysis (Ljung): autocorrelation of each output's residual (white if within
+-1.96/sqrt(N) for lags >= 1) and cross-correlation with each input (independent if within).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, VesselGeometry, VesselParameters
from lotsen.sysid.data import INPUT_COLUMNS, IdRecord
from lotsen.model.angles import wrap_angle
from lotsen.sysid.estimate import NAMES, SolverOptions, build_problem, estimate


@dataclass
class OutputFit:
    t: np.ndarray
    y: np.ndarray  # measured (n x ny), NaN where missing
    yhat: np.ndarray  # simulated
    output_names: tuple[str, ...]
    fit_percent: dict[str, float]
    window_starts: np.ndarray = field(default_factory=lambda: np.zeros(0))


@dataclass
class ResidualAnalysis:
    lags: np.ndarray
    autocorr: dict[str, np.ndarray]
    crosscorr: dict[str, dict[str, np.ndarray]]  # output -> input -> values at lags -L..L
    bound: float
    whiteness_fraction_outside: dict[str, float]
    independence_fraction_outside: dict[str, float]


def fit_percent(y: np.ndarray, yhat: np.ndarray, is_angle: bool = False) -> float:
    ok = np.isfinite(y) & np.isfinite(yhat)
    if ok.sum() < 2:
        return float("nan")
    yy, yh = y[ok], yhat[ok]
    if is_angle:
        e = wrap_angle(yy - yh)
        yy = np.unwrap(yy)
    else:
        e = yy - yh
    den = np.linalg.norm(yy - yy.mean())
    return float(100.0 * (1.0 - np.linalg.norm(e) / den)) if den > 0 else float("nan")


def simulate_fit(params: VesselParameters, records: Sequence[IdRecord], window_s: float = 10.0,
                 gap_s: float = 1.0, geometry: VesselGeometry = DEFAULT_GEOMETRY) -> OutputFit:
    """Simulate the grey-box model over `records` (window initial states estimated, theta fixed)."""
    prob = build_problem(records, window_s, gap_s, None, geometry)
    res = estimate(prob, params, dict(zip(NAMES, params.to_vector())), SolverOptions(max_iterations=20))
    X = prob.sim.simulate(params.to_vector(), res.x0s)
    yhat = X[:, prob.out_idx]
    names = prob.windows[0].output_names
    y = np.vstack([w.outputs for w in prob.windows])
    t = np.concatenate([w.t for w in prob.windows])
    if prob.psi_col is not None:
        yhat[:, prob.psi_col] = wrap_angle(yhat[:, prob.psi_col])
    fits = {n: fit_percent(y[:, j], yhat[:, j], n == "psi") for j, n in enumerate(names)}
    starts = np.array([w.t[0] for w in prob.windows])
    return OutputFit(t, y, yhat, names, fits, starts)


def _xcorr(a: np.ndarray, b: np.ndarray, max_lag: int) -> np.ndarray:
    a = a - a.mean()
    b = b - b.mean()
    n = len(a)
    den = np.sqrt(np.sum(a * a) * np.sum(b * b))
    if den == 0:
        return np.zeros(2 * max_lag + 1)
    out = np.empty(2 * max_lag + 1)
    for i, lag in enumerate(range(-max_lag, max_lag + 1)):
        if lag >= 0:
            out[i] = np.sum(a[lag:] * b[:n - lag]) / den
        else:
            out[i] = np.sum(a[:n + lag] * b[-lag:]) / den
    return out


def residual_analysis(fit: OutputFit, inputs: np.ndarray | None = None, max_lag: int = 25) -> ResidualAnalysis:
    """Autocorrelation of each output's residuals (over the rows where that output is measured:
    asynchronous outputs have their own rows) and cross-correlation with the inputs held there.

    The lag range shrinks to fit a short record (at most a third of the fewest samples of an
    output); an output with fewer than 6 samples is left out."""
    E_all = fit.y - fit.yhat
    if "psi" in fit.output_names:
        j = fit.output_names.index("psi")
        E_all[:, j] = wrap_angle(E_all[:, j])
    counts = {name: int(np.isfinite(fit.y[:, j]).sum()) for j, name in enumerate(fit.output_names)}
    usable = [name for name, c in counts.items() if c >= 6]
    n_min = min((counts[name] for name in usable), default=0)
    L = max(0, min(max_lag, n_min // 3))
    bound = 1.96 / np.sqrt(max(n_min, 1))
    lags = np.arange(0, L + 1)
    auto, cross, white, indep = {}, {}, {}, {}
    for j, name in enumerate(fit.output_names):
        if name not in usable:
            continue
        ok = np.isfinite(fit.y[:, j])
        e = E_all[ok, j]
        c = _xcorr(e, e, L)[L:]
        auto[name] = c
        white[name] = float(np.mean(np.abs(c[1:]) > bound)) if L else 0.0
        if inputs is not None:
            U = inputs[ok]
            cross[name] = {INPUT_COLUMNS[i]: _xcorr(e, U[:, i], L) for i in range(5) if np.std(U[:, i]) > 0}
            vals = [np.mean(np.abs(v) > bound) for v in cross[name].values()]
            indep[name] = float(np.mean(vals)) if vals else 0.0
    return ResidualAnalysis(lags, auto, cross, float(bound), white, indep)


def inputs_at_outputs(records: Sequence[IdRecord], window_s: float = 10.0, gap_s: float = 1.0) -> np.ndarray:
    """Inputs (held) at each row of the windows that `simulate_fit` produces, for cross-correlation."""
    from lotsen.sysid.data import split_segments, split_windows

    segs = [s for r in records for s in split_segments(r, gap_s)]
    return np.vstack([w.inputs for w in split_windows(segs, window_s)])
