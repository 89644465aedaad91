"""Open-loop prediction on held-out data: how far a model's track drifts from the boat's in a few seconds.

A model is for predicting the boat: the MPC looks seconds ahead, the EKF bridges a GNSS outage with
it. So an identification result is scored, as practitioners score lake models, by its open-loop
prediction of held-out data, in metres and degrees an operator can read (not a fit percentage, which
reads 97.7 % for a model twice as wrong as one at 99.0 %).

Windows start every `every_s` seconds on every measurement row of the held-out records whose
segment lasts `horizon_s` longer. Each window starts from a state taken from the data alone (the
same for every model compared, so the comparison measures the dynamics, not an observer):
position and heading from a cubic fitted to the fixes over +-1 s; u, v from the fitted ground
velocity rotated by the fitted heading; r from the fitted heading's rate. The model is then run
open-loop with the record's inputs (and, for a lake model, its own current and wind), and the
position and heading errors are taken at the fixes nearest `horizons_s` after the start.

`PredictionScore.position_m` is the RMS over windows of the position error at each horizon. Paired
comparisons (`improvement`) use the same windows for both models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, VesselGeometry, VesselParameters, geometry_tuple
from lotsen.model.angles import wrap_angle
from lotsen.sysid.data import IdRecord, Segment, split_segments
from lotsen.sysid.kernels import step_kernels
from lotsen.sysid.sensitivity import make_grid

HORIZONS_S = (2.0, 5.0, 10.0)
FIT_HALF_WINDOW_S = 1.0  # the initial state's cubic fit: +-1 s of fixes (17 at 8 Hz)


@dataclass
class PredictionScore:
    """Errors of open-loop predictions over held-out windows (module docstring)."""

    horizons_s: tuple[float, ...]
    n_windows: int
    position_m: dict[float, float]  # RMS over windows of the position error at each horizon
    heading_deg: dict[float, float]  # RMS of the heading error
    position_errors_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))  # windows x horizons
    heading_errors_deg: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 0)))
    stable: bool = True  # every prediction stayed finite

    @property
    def horizon_s(self) -> float:
        return self.horizons_s[-1]

    @property
    def position_at_horizon_m(self) -> float:
        return self.position_m[self.horizon_s]

    @property
    def heading_at_horizon_deg(self) -> float:
        return self.heading_deg[self.horizon_s]

    def to_json_dict(self) -> dict:
        return {"horizons_s": list(self.horizons_s), "windows": self.n_windows, "stable": self.stable,
                "position_rms_m": {f"{h:g}": _round(v, 4) for h, v in self.position_m.items()},
                "heading_rms_deg": {f"{h:g}": _round(v, 2) for h, v in self.heading_deg.items()}}


def _round(v: float, n: int) -> float | None:
    return round(v, n) if math.isfinite(v) else None


def improvement(model: PredictionScore, baseline: PredictionScore) -> float:
    """1 - RMS position error at the horizon of `model` / that of `baseline` (same windows): 0.4 means
    the model's 10-s prediction is 40 % closer to the boat."""
    b = baseline.position_at_horizon_m
    if not math.isfinite(b) or b <= 0:
        return 0.0
    return 1.0 - model.position_at_horizon_m / b


def improvement_interval(model: PredictionScore, baseline: PredictionScore, n_blocks: int = 10) -> tuple[float, float]:
    """A rough 2-sigma range of `improvement` from its spread over consecutive blocks of windows
    (windows overlap, so single windows are not independent)."""
    a, b = model.position_errors_m[:, -1], baseline.position_errors_m[:, -1]
    n = len(a)
    k = min(n_blocks, n // 3)
    if k < 3 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        v = improvement(model, baseline)
        return v, v
    vals = []
    for idx in np.array_split(np.arange(n), k):
        den = math.sqrt(float(np.mean(b[idx] ** 2)))
        vals.append(1.0 - math.sqrt(float(np.mean(a[idx] ** 2))) / den if den > 0 else 0.0)
    vals = np.array(vals)
    mid = improvement(model, baseline)
    half = 2.0 * float(np.std(vals, ddof=1)) / math.sqrt(k)
    return mid - half, mid + half


@dataclass
class _Window:
    seg: Segment
    x0: np.ndarray
    meas_rows: np.ndarray  # rows of `seg` at the horizons
    gyro_row: int


def _cubic_at(seg: Segment, col: int, t0: float, unwrap: bool = False) -> np.ndarray | None:
    """A cubic through the column's own rows within +-FIT_HALF_WINDOW_S of t0 (value and slope at t0 last)."""
    w = (np.abs(seg.t - t0) <= FIT_HALF_WINDOW_S) & np.isfinite(seg.outputs[:, col])
    if w.sum() < 8:
        return None
    tt = seg.t[w] - t0
    if tt.min() > -0.5 * FIT_HALF_WINDOW_S or tt.max() < 0.5 * FIT_HALF_WINDOW_S:
        return None  # the fit would extrapolate
    y = seg.outputs[w, col]
    return np.polyfit(tt, np.unwrap(y) if unwrap else y, 3)


def _initial_state(seg: Segment, k: int, gyro_bias: float) -> np.ndarray | None:
    """The state at row k from the data alone: a cubic over +-FIT_HALF_WINDOW_S of each output's own
    rows (fixes for north and east, the heading's rows; outputs are asynchronous in a run log) for
    north, east and the (unwrapped) heading; r from the heading's slope."""
    names = seg.output_names
    if not {"north", "east", "psi"} <= set(names):
        return None
    t0 = seg.t[k]
    cN, cE = _cubic_at(seg, names.index("north"), t0), _cubic_at(seg, names.index("east"), t0)
    cp = _cubic_at(seg, names.index("psi"), t0, unwrap=True)
    if cN is None or cE is None or cp is None:
        return None
    p0 = float(cp[-1])
    vN, vE = float(cN[-2]), float(cE[-2])
    u = math.cos(p0) * vN + math.sin(p0) * vE
    v = -math.sin(p0) * vN + math.cos(p0) * vE
    r = float(cp[-2])
    return np.array([cN[-1], cE[-1], wrap_angle(p0), u, v, r])


def _windows(records: Sequence[IdRecord], horizons_s: Sequence[float], every_s: float,
             gap_s: float) -> list[_Window]:
    H = max(horizons_s)
    out: list[_Window] = []
    for rec in records:
        for seg in split_segments(rec, gap_s):
            if not {"north", "east", "psi"} <= set(seg.output_names):
                continue
            iN, iE = seg.output_names.index("north"), seg.output_names.index("east")
            meas = np.flatnonzero(np.isfinite(seg.outputs[:, iN]) & np.isfinite(seg.outputs[:, iE]))  # the fixes
            if len(meas) < 2:
                continue
            tm = seg.t[meas]
            next_start = seg.t[0] + FIT_HALF_WINDOW_S
            for q, k in enumerate(meas):
                t0 = seg.t[k]
                if t0 < next_start or t0 + H > tm[-1]:
                    continue
                x0 = _initial_state(seg, int(k), 0.0)
                if x0 is None:
                    continue
                rows = meas[np.searchsorted(tm, [t0 + h - 1e-9 for h in horizons_s])]
                end = int(rows[-1]) + 1
                sub = Segment(seg.t[k:end], seg.inputs[k:end], seg.outputs[k:end], seg.output_names, seg.source,
                              seg.first_row + int(k),
                              input_slopes=None if seg.input_slopes is None else seg.input_slopes[k:end])
                out.append(_Window(sub, x0, rows - k, int(k)))
                next_start = t0 + every_s
    return out


def _heading_at(seg: Segment, col: int, t: float) -> float:
    ok = np.isfinite(seg.outputs[:, col])
    if not ok.any():
        return math.nan
    tt, psi = seg.t[ok], np.unwrap(seg.outputs[ok, col])
    return float(np.interp(t, tt, psi))


def prediction_score(params: VesselParameters, records: Sequence[IdRecord],
                     horizons_s: Sequence[float] = HORIZONS_S, every_s: float = 2.0, gap_s: float = 1.0,
                     geometry: VesselGeometry = DEFAULT_GEOMETRY,
                     environment: Sequence[float] | None = None) -> PredictionScore:
    """Open-loop prediction errors of `params` on `records` (module docstring). `environment`: the
    lake model's ENV_NAMES values (current, wind, drag coefficients) to predict with; None: calm water."""
    horizons = tuple(float(h) for h in sorted(horizons_s))
    # a short held-out record: the horizons that fit in it (a 12-s record holds out 2.4 s)
    longest = max((s.duration_s for r in records for s in split_segments(r, gap_s)), default=0.0)
    fits = tuple(h for h in horizons if h <= longest - 2.0 * FIT_HALF_WINDOW_S)
    horizons = fits or horizons
    wins = _windows(records, horizons, every_s, gap_s)
    nh = len(horizons)
    if not wins:
        nan = {h: math.nan for h in horizons}
        return PredictionScore(horizons, 0, nan, dict(nan), np.zeros((0, nh)), np.zeros((0, nh)), True)
    lake = environment is not None
    grid = make_grid([w.seg for w in wins], 0.0625)
    k = step_kernels(geometry_tuple(geometry), lake=lake)
    theta = np.array(params.to_vector(), float)
    x0 = np.array([w.x0 for w in wins])
    if lake:
        theta = np.concatenate([theta, np.asarray(environment, float)])
        x0 = np.column_stack([x0, np.ones(len(x0)), np.zeros(len(x0))])  # steady wind: gust factors 1, 0
    # the sample steps of the rows at the horizons (the grid numbers every row of every window)
    row_base = np.concatenate([[0], np.cumsum([len(w.seg.t) for w in wins])[:-1]])
    need_rows = (row_base[:, None] + np.array([w.meas_rows for w in wins])).ravel()
    need = grid.sample_step[need_rows]
    order = np.argsort(need, kind="stable")
    X_sorted, _ = k.run_record(theta, grid.h, grid.U.T, grid.reset, grid.window_start_step, x0, need[order], False)
    X = np.empty_like(X_sorted)
    X[order] = X_sorted
    X = X.reshape(len(wins), nh, -1)
    names = wins[0].seg.output_names
    iN, iE, ip = names.index("north"), names.index("east"), names.index("psi")
    Y = np.array([[w.seg.outputs[r] for r in w.meas_rows] for w in wins])
    # the heading at each horizon's fix: its own rows, interpolated (asynchronous outputs)
    H = np.array([[_heading_at(w.seg, ip, w.seg.t[r]) for r in w.meas_rows] for w in wins])
    dpos = np.hypot(X[:, :, 0] - Y[:, :, iN], X[:, :, 1] - Y[:, :, iE])
    dpsi = np.degrees(np.abs(wrap_angle(X[:, :, 2] - H)))
    stable = bool(np.all(np.isfinite(dpos)) and np.all(np.isfinite(dpsi)))
    dpos = np.where(np.isfinite(dpos), dpos, np.inf)
    dpsi = np.where(np.isfinite(dpsi), dpsi, 180.0)
    pos = {h: float(np.sqrt(np.mean(dpos[:, j] ** 2))) for j, h in enumerate(horizons)}
    hdg = {h: float(np.sqrt(np.mean(dpsi[:, j] ** 2))) for j, h in enumerate(horizons)}
    return PredictionScore(horizons, len(wins), pos, hdg, dpos, dpsi, stable)
