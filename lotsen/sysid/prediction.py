"""Open-loop prediction on held-out data: how far a model's track drifts from the boat's in a few seconds.

A model is for predicting the boat: the MPC looks seconds ahead, the EKF bridges a GNSS outage with
it. So an identification result is scored, as practitioners score lake models, by its open-loop
prediction of held-out data, in metres and degrees an operator can read (not a fit percentage, which
reads 97.7 % for a model twice as wrong as one at 99.0 %).

Windows start every `every_s` seconds on every measurement row of the held-out records whose
segment lasts `horizon_s` longer. Each window starts from a state taken from the data alone (the
same for every model compared, so the comparison measures the dynamics, not an observer):
position and heading from a cubic fitted to the fixes over +-1 s; u, v from the fitted ground
velocity rotated by the fitted heading; r from the gyro less its offset over the record (its
integral less the heading's change). The model is then run
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
from lotsen.sysid.sensitivity import StepGrid, make_grid

HORIZONS_S = (2.0, 5.0, 10.0)
FIT_HALF_WINDOW_S = 1.0  # the initial state's cubic fit: +-1 s of fixes (17 at 8 Hz)
R_HALF_WINDOW_S = 0.25  # the yaw rate's line through the gyro's samples


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
    # per window: the predicted minus measured position at the last horizon (north, east) and the speed
    # at the window's start: a drift common to all windows is a current or wind the model lacks
    error_ne_m: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 2)))
    start_speed_mps: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    def drift(self) -> tuple[float, float, float] | None:
        """(speed m/s, towards deg, its z score): the mean of the windows' position errors at the
        horizon over the horizon, earth frame, when it stands out of their spread (windows overlap and
        the current drifts slowly, so blocks of ten windows count as one), else None."""
        e = self.error_ne_m
        if len(e) < 10 or not np.all(np.isfinite(e)):
            return None
        mean = e.mean(axis=0)
        blocks = [b.mean(axis=0) for b in np.array_split(e, max(len(e) // 10, 1))]
        se = np.std(blocks, axis=0, ddof=1) / math.sqrt(len(blocks)) if len(blocks) >= 3 else np.std(e, axis=0)
        z = float(np.hypot(*(mean / np.maximum(se, 1e-9))))
        # the model predicts where the boat would go without the current: the water moved it the other way
        v = -mean / self.horizon_s
        return float(np.hypot(*v)), float(math.degrees(math.atan2(v[1], v[0])) % 360.0), z

    def speed_dependence(self) -> tuple[float, float, float] | None:
        """(median speed, RMS error per metre travelled at the horizon of the windows starting slower,
        of those starting faster): a model that explains the boat misses about alike per metre."""
        s, e = self.start_speed_mps, self.position_errors_m[:, -1] if len(self.position_errors_m) else None
        if e is None or len(s) < 10 or not np.all(np.isfinite(e)):
            return None
        rel = e / np.maximum(s * self.horizon_s, 0.5)  # per metre travelled (at least 0.5 m)
        med = float(np.median(s))
        lo, hi = rel[s <= med], rel[s > med]
        if len(lo) < 3 or len(hi) < 3:
            return None
        return med, float(np.sqrt(np.mean(lo ** 2))), float(np.sqrt(np.mean(hi ** 2)))

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


def windows_of(score: PredictionScore, idx: np.ndarray) -> PredictionScore:
    """The score on the windows `idx` only (their RMS errors recomputed)."""
    idx = np.asarray(idx, int)
    pe, he = score.position_errors_m[idx], score.heading_errors_deg[idx]
    pos = {h: float(np.sqrt(np.mean(pe[:, j] ** 2))) if len(idx) else math.nan for j, h in enumerate(score.horizons_s)}
    hdg = {h: float(np.sqrt(np.mean(he[:, j] ** 2))) if len(idx) else math.nan for j, h in enumerate(score.horizons_s)}
    ne = score.error_ne_m[idx] if len(score.error_ne_m) else score.error_ne_m
    sp = score.start_speed_mps[idx] if len(score.start_speed_mps) else score.start_speed_mps
    return PredictionScore(score.horizons_s, len(idx), pos, hdg, pe, he, bool(np.all(np.isfinite(pe))), ne, sp)


def stacked(parts: Sequence[tuple[PredictionScore, np.ndarray]], n_windows: int) -> PredictionScore:
    """One score from the windows `idx` of each (score, idx) in `parts`, in window order: the
    held-out errors of a choice made window by window on other data (judge.cross_checked)."""
    first = parts[0][0]
    nh = len(first.horizons_s)
    pe, he = np.zeros((n_windows, nh)), np.zeros((n_windows, nh))
    ne, sp = np.zeros((n_windows, 2)), np.zeros(n_windows)
    for sc, idx in parts:
        pe[idx], he[idx] = sc.position_errors_m[idx], sc.heading_errors_deg[idx]
        if len(sc.error_ne_m):
            ne[idx], sp[idx] = sc.error_ne_m[idx], sc.start_speed_mps[idx]
    whole = PredictionScore(first.horizons_s, n_windows, {}, {}, pe, he, True, ne, sp)
    return windows_of(whole, np.arange(n_windows))


def _round(v: float, n: int) -> float | None:
    return round(v, n) if math.isfinite(v) else None


def improvement(model: PredictionScore, baseline: PredictionScore) -> float:
    """1 - RMS position error at the horizon of `model` / that of `baseline` (same windows): 0.4 means
    the model's 10-s prediction is 40 % closer to the boat."""
    b = baseline.position_at_horizon_m
    if not math.isfinite(b) or b <= 0:
        return 0.0
    return 1.0 - model.position_at_horizon_m / b


def improvement_interval(model: PredictionScore, baseline: PredictionScore, n_blocks: int = 10,
                         z: float = 2.0, horizons: str = "last") -> tuple[float, float]:
    """A rough +-z sigma range of `improvement` from its spread over consecutive blocks of windows
    (windows overlap, so single windows are not independent). `horizons="all"`: of the improvement
    averaged over every horizon (2, 5, 10 s), a steadier figure where gusts scatter the 10-s errors."""
    cols = [-1] if horizons == "last" else list(range(model.position_errors_m.shape[1]))
    a, b = model.position_errors_m[:, cols], baseline.position_errors_m[:, cols]
    n = len(a)
    k = min(n_blocks, n // 3)

    def gain(ia: np.ndarray, ib: np.ndarray) -> float:
        den = np.sqrt(np.mean(ib ** 2, axis=0))
        return float(np.mean(np.where(den > 0, 1.0 - np.sqrt(np.mean(ia ** 2, axis=0)) / np.where(den > 0, den, 1.0),
                                      0.0)))

    mid = gain(a, b)
    if k < 3 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return mid, mid
    vals = np.array([gain(a[idx], b[idx]) for idx in np.array_split(np.arange(n), k)])
    half = z * float(np.std(vals, ddof=1)) / math.sqrt(k)
    return mid - half, mid + half


@dataclass
class _Window:
    seg: Segment
    x0: np.ndarray
    meas_rows: np.ndarray  # rows of `seg` at the horizons
    gyro_row: int


def _near(seg: Segment, t0: float, half_s: float) -> tuple[np.ndarray, slice]:
    """The rows within +-half_s of t0: the mask over a slice of the (sorted) stamps that holds them, so a
    window's fits look at their few rows, not at the whole record's (290 windows of a 10-min record)."""
    rows = slice(*np.searchsorted(seg.t, [t0 - 2.0 * half_s, t0 + 2.0 * half_s], side="left"))
    return np.abs(seg.t[rows] - t0) <= half_s, rows


def _cubic_at(seg: Segment, col: int, t0: float, unwrap: bool = False) -> np.ndarray | None:
    """A cubic through the column's own rows within +-FIT_HALF_WINDOW_S of t0 (value and slope at t0 last)."""
    near, rows = _near(seg, t0, FIT_HALF_WINDOW_S)
    w = near & np.isfinite(seg.outputs[rows, col])
    if w.sum() < 8:
        return None
    tt = seg.t[rows][w] - t0
    if tt.min() > -0.5 * FIT_HALF_WINDOW_S or tt.max() < 0.5 * FIT_HALF_WINDOW_S:
        return None  # the fit would extrapolate
    y = seg.outputs[rows][w, col]
    return np.polyfit(tt, np.unwrap(y) if unwrap else y, 3)


def _initial_state(seg: Segment, k: int, gyro_bias: float) -> np.ndarray | None:
    """The state at row k from the data alone: a cubic over +-FIT_HALF_WINDOW_S of each output's own
    rows (fixes for north and east, the heading's rows; outputs are asynchronous in a run log) for
    north, east and the (unwrapped) heading; r from the gyro over +-R_HALF_WINDOW_S less its offset
    (`gyro_bias`, from the record's heading), else from the heading's slope (0.015 rad/s noisier:
    8 degrees after 10 s)."""
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
    if "r" in names:
        ir = names.index("r")
        near, rows = _near(seg, t0, R_HALF_WINDOW_S)
        w = near & np.isfinite(seg.outputs[rows, ir])
        if w.sum() >= 2:
            cr = np.polyfit(seg.t[rows][w] - t0, seg.outputs[rows][w, ir], 1)
            r = float(cr[-1]) - gyro_bias
    return np.array([cN[-1], cE[-1], wrap_angle(p0), u, v, r])


def gyro_offset(seg: Segment) -> float:
    """The yaw-rate output's constant offset over a segment from the data alone: (integral of r - the
    heading's change) / duration (0 without both outputs)."""
    names = seg.output_names
    if "r" not in names or "psi" not in names:
        return 0.0
    ir, ip = names.index("r"), names.index("psi")
    okr, okp = np.isfinite(seg.outputs[:, ir]), np.isfinite(seg.outputs[:, ip])
    if okr.sum() < 2 or okp.sum() < 2:
        return 0.0
    tr, r = seg.t[okr], seg.outputs[okr, ir]
    tp, psi = seg.t[okp], np.unwrap(seg.outputs[okp, ip])
    t0, t1 = max(tr[0], tp[0]), min(tr[-1], tp[-1])
    w = (tr >= t0) & (tr <= t1)
    if t1 - t0 <= 1.0 or w.sum() < 2:
        return 0.0
    integral = float(np.sum(0.5 * (r[w][1:] + r[w][:-1]) * np.diff(tr[w])))
    change = float(np.interp(tr[w][-1], tp, psi) - np.interp(tr[w][0], tp, psi))
    return (integral - change) / float(tr[w][-1] - tr[w][0])


def _windows(segments: Sequence[Segment], horizons_s: Sequence[float], every_s: float) -> list[_Window]:
    H = max(horizons_s)
    out: list[_Window] = []
    for seg in segments:
        if not {"north", "east", "psi"} <= set(seg.output_names):
            continue
        iN, iE = seg.output_names.index("north"), seg.output_names.index("east")
        meas = np.flatnonzero(np.isfinite(seg.outputs[:, iN]) & np.isfinite(seg.outputs[:, iE]))  # the fixes
        if len(meas) < 2:
            continue
        tm = seg.t[meas]
        next_start = seg.t[0] + FIT_HALF_WINDOW_S
        bias = gyro_offset(seg)
        for q, k in enumerate(meas):
            t0 = seg.t[k]
            if t0 < next_start or t0 + H > tm[-1]:
                continue
            x0 = _initial_state(seg, int(k), bias)
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


@dataclass(frozen=True)
class PredictionWindows:
    """The windows of some records and what depends on their data alone (the steps, the start states, the
    measured outputs at the horizons): made once for all the models scored on them (`score_windows`)."""

    horizons_s: tuple[float, ...]
    windows: list[_Window]
    grid: StepGrid | None = None
    x0: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    need: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # the steps at the horizons, sorted
    order: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # their windows' order
    Y: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))  # the outputs at the horizons
    H: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # the heading at each horizon's fix


def prediction_windows(records: Sequence[IdRecord], horizons_s: Sequence[float] = HORIZONS_S,
                       every_s: float = 2.0, gap_s: float = 1.0) -> PredictionWindows:
    """The windows of `records` at `horizons_s` (module docstring), ready to score models on."""
    horizons = tuple(float(h) for h in sorted(horizons_s))
    # a short held-out record: the horizons that fit in it (a 12-s record holds out 2.4 s)
    segments = [s for r in records for s in split_segments(r, gap_s)]  # once: it copies the records
    longest = max((s.duration_s for s in segments), default=0.0)
    fits = tuple(h for h in horizons if h <= longest - 2.0 * FIT_HALF_WINDOW_S)
    horizons = fits or horizons
    wins = _windows(segments, horizons, every_s)
    if not wins:
        return PredictionWindows(horizons, wins)
    grid = make_grid([w.seg for w in wins], 0.0625)
    # the sample steps of the rows at the horizons (the grid numbers every row of every window)
    row_base = np.concatenate([[0], np.cumsum([len(w.seg.t) for w in wins])[:-1]])
    need_rows = (row_base[:, None] + np.array([w.meas_rows for w in wins])).ravel()
    need = grid.sample_step[need_rows]
    order = np.argsort(need, kind="stable")
    ip = wins[0].seg.output_names.index("psi")
    Y = np.array([[w.seg.outputs[r] for r in w.meas_rows] for w in wins])
    # the heading at each horizon's fix: its own rows, interpolated (asynchronous outputs)
    H = np.array([[_heading_at(w.seg, ip, w.seg.t[r]) for r in w.meas_rows] for w in wins])
    return PredictionWindows(horizons, wins, grid, np.array([w.x0 for w in wins]), need[order], order, Y, H)


def prediction_score(params: VesselParameters, records: Sequence[IdRecord],
                     horizons_s: Sequence[float] = HORIZONS_S, every_s: float = 2.0, gap_s: float = 1.0,
                     geometry: VesselGeometry = DEFAULT_GEOMETRY,
                     environment: Sequence[float] | None = None) -> PredictionScore:
    """Open-loop prediction errors of `params` on `records` (module docstring). `environment`: the
    lake model's ENV_NAMES values (current, wind, drag coefficients) to predict with; None: calm water."""
    return score_windows(params, prediction_windows(records, horizons_s, every_s, gap_s), geometry, environment)


def score_windows(params: VesselParameters, pw: PredictionWindows, geometry: VesselGeometry = DEFAULT_GEOMETRY,
                  environment: Sequence[float] | None = None) -> PredictionScore:
    """`prediction_score` on windows already made (`prediction_windows`)."""
    horizons, wins = pw.horizons_s, pw.windows
    nh = len(horizons)
    if not wins or pw.grid is None:
        nan = {h: math.nan for h in horizons}
        return PredictionScore(horizons, 0, nan, dict(nan), np.zeros((0, nh)), np.zeros((0, nh)), True)
    lake = environment is not None
    grid = pw.grid
    k = step_kernels(geometry_tuple(geometry), lake=lake)
    theta = np.array(params.to_vector(), float)
    x0 = pw.x0
    if lake:
        theta = np.concatenate([theta, np.asarray(environment, float)])
        x0 = np.column_stack([x0, np.ones(len(x0)), np.zeros(len(x0))])  # steady wind: gust factors 1, 0
    X_sorted, _ = k.run_record(theta, grid.h, grid.U.T, grid.reset, grid.window_start_step, x0, pw.need, False)
    X = np.empty_like(X_sorted)
    X[pw.order] = X_sorted
    X = X.reshape(len(wins), nh, -1)
    names = wins[0].seg.output_names
    iN, iE = names.index("north"), names.index("east")
    Y, H = pw.Y, pw.H
    dpos = np.hypot(X[:, :, 0] - Y[:, :, iN], X[:, :, 1] - Y[:, :, iE])
    dpsi = np.degrees(np.abs(wrap_angle(X[:, :, 2] - H)))
    stable = bool(np.all(np.isfinite(dpos)) and np.all(np.isfinite(dpsi)))
    dpos = np.where(np.isfinite(dpos), dpos, np.inf)
    dpsi = np.where(np.isfinite(dpsi), dpsi, 180.0)
    pos = {h: float(np.sqrt(np.mean(dpos[:, j] ** 2))) for j, h in enumerate(horizons)}
    hdg = {h: float(np.sqrt(np.mean(dpsi[:, j] ** 2))) for j, h in enumerate(horizons)}
    err_ne = np.column_stack([X[:, -1, 0] - Y[:, -1, iN], X[:, -1, 1] - Y[:, -1, iE]])
    speed = np.hypot(x0[:, 3], x0[:, 4])
    return PredictionScore(horizons, len(wins), pos, hdg, dpos, dpsi, stable, err_ne, speed)
