"""Equation-error estimate: a start for the output-error estimate that depends on the data only.

The output-error estimate (lotsen.sysid.multiple) is a local search. On a boat built like the model
its start hardly matters; on a real hull (a 6-DOF plant whose resistance, lift and propellers are
not the grey box's) Gauss-Newton from the documented defaults wandered to the parameter bounds and
stopped unconverged, and two records of the same hull ended in different places. Here the
equations of motion themselves are fitted, which is a linear least-squares problem in almost every
coefficient and so has one answer whatever the start:

    seed eq. (22) on the velocity relative to the water, nu_r = nu - R(psi)^T c:
    m11 u_r' - m22 v_r r + X_u u_r - X_|u|u |u_r| u_r                               = tau_X + tau_wind,X
    m22 v_r' + m11 u_r r + Y_v v_r + Y_r r - (Y_|u|v |u_r| + Y_|v|v |v_r| + Y_|r|v |r|) v_r = tau_Y + ...
    m33 r' - (m11 - m22) u_r v_r + N_v v_r - N_|v|v |v_r| v_r + N_r r - N_|r|r |r| r = tau_N + ...
    tau = mu_az A(kappa) + C_N B(kappa) + mu_t C      (the model's own thruster code, lotsen.model.array_tau)

The motion comes from the record alone: smoothing splines through the fixes (north, east), the
heading and the gyro (less its offset, from the heading's change) give u, v, r and their rates at the
fixes. Every column is then low-pass filtered alike (a filter commutes with the linear combination,
so the equation holds for the filtered columns while the noise of the differentiated positions is
cut). For a given kappa (and, on a lake, current and air velocity) the rest is a bounded linear least
squares (scipy's lsq_linear within the physical ranges), weighted per equation by its own residual
spread; kappa, the current and the air velocity are found around it by a small bounded search.

The result is biased (errors in the regressors, the smoothing), so it is a start, not an answer:
the output-error estimate takes it from here (and keeps the better of it and the caller's start).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy.interpolate import make_smoothing_spline
from scipy.ndimage import gaussian_filter1d
from scipy.optimize import least_squares, lsq_linear, minimize

from lotsen.model import VesselGeometry, VesselParameters
from lotsen.model.dynamics import array_tau
from lotsen.model.environment import apparent_wind_force, wind_drag_coefficients
from lotsen.sysid.data import IdRecord, Segment, split_segments
from lotsen.sysid.estimate import NAMES, IdentifiabilityError, SolverOptions, parameter_bounds, with_terms_off
from lotsen.sysid.parallel import SERIAL, Held, Map, map_held
from lotsen.sysid.sensitivity import ENV_NAMES

FILTER_SIGMA_S = 0.5  # the common low-pass of every column (Gaussian, standard deviation)
# the splines' smoothing: lambda = 1 / (dt (2 pi f_c)^4) passes motion below f_c and cuts above it (a
# smoothing spline's gain is 1 / (1 + lambda dt omega^4)); a 13 kg boat's motion lies below 1 Hz.
# (Generalised cross-validation chose about the same and took 8 s per series in scipy's Python loop.)
SMOOTHING_CUTOFF_HZ = 1.0
NW_MIN_BANDWIDTH_S = 10.0  # the sandwich's Newey-West bandwidth, at least
BATCHES = 8  # stretches of the record for the batch-means spread
EDGE_S = 1.5  # spline ends left out
KAPPA_RANGE = (1e-3, 0.3)
N_WIND = 4  # k_X, k_Y, k_N, k_Nv of lotsen.model.environment.apparent_wind_force
# the wind's drag coefficients within this many times the nominal hull's: with a weak wind the apparent
# wind is the boat's own motion and unbounded coefficients turn into hull damping (seen: 16 x nominal)
WIND_COEFFICIENT_MAX = 4.0
K_WIND_MAX = WIND_COEFFICIENT_MAX * np.array([*wind_drag_coefficients(), 0.2 * wind_drag_coefficients()[1]])
# and the drag along and across the hull at least a quarter of the nominal hull's: a hull above water has
# drag, and without this floor a wind of 0.5 m/s with large coefficients mimics hull damping in place of a
# 4 m/s wind with the hull's own (the yaw moments may take either sign)
K_WIND_MIN = np.array([0.25, 0.25, -1.0, -1.0]) * np.abs(K_WIND_MAX) / WIND_COEFFICIENT_MAX * np.array([1, 1, 4, 4])
# and a prior: the nominal hull's along and across drag +- half of it, the yaw moments 0 +- the nominal
# (on a hull record, without it one record found 5 m/s with its drag, the other 1.1 m/s with 11x it)
K_WIND_MEAN = np.array([*wind_drag_coefficients()[:2], 0.0, 0.0])
K_WIND_PRIOR_STD = np.array([0.5 * wind_drag_coefficients()[0], 0.5 * wind_drag_coefficients()[1],
                             wind_drag_coefficients()[2], 0.1 * wind_drag_coefficients()[1]])


def _walk_rows(dt: float) -> float:
    """How many filtered data rows count as one independent row (the common filter correlates ~2 s)."""
    return math.sqrt(max(2.0 * math.sqrt(math.pi) * FILTER_SIGMA_S / dt, 1.0))


@dataclass
class MotionSamples:
    """The motion at the fixes, from splines: time, heading, ground velocity (body) and rates, inputs."""

    t: np.ndarray
    psi: np.ndarray
    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    u_dot: np.ndarray
    v_dot: np.ndarray
    r_dot: np.ndarray
    inputs: np.ndarray  # n x 5, the reconstructed inputs at t
    segment: np.ndarray  # the segment of each sample (filtering stays within a segment)

    def subset(self, rows: np.ndarray) -> "MotionSamples":
        return MotionSamples(*(getattr(self, f.name)[rows] for f in fields(self)))


def _spline(t: np.ndarray, y: np.ndarray):  # type: ignore[no-untyped-def]
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.125
    return make_smoothing_spline(t, y, lam=1.0 / (dt * (2.0 * math.pi * SMOOTHING_CUTOFF_HZ) ** 4))


def _spline_through(series: tuple[np.ndarray, np.ndarray]):  # type: ignore[no-untyped-def]
    """_spline(t, y) as a task of the parallel map."""
    return _spline(*series)


def motion_samples(segments: Sequence[Segment], gyro_bias: Sequence[float] | None = None,
                   parallel: Map = SERIAL) -> MotionSamples:
    """The motion at every fix of every segment (module docstring); `gyro_bias` per segment. The splines
    (north, east, heading, gyro per segment: independent fits, each ~35 ms on a 10-min record) are
    fitted on `parallel`'s workers."""
    # first what each segment's splines go through, then all of them fitted at once
    series: list[tuple[np.ndarray, np.ndarray]] = []
    plan: list[tuple[int, Segment, np.ndarray, dict[str, int]]] = []
    for q, seg in enumerate(segments):
        names = seg.output_names
        iN, iE = names.index("north"), names.index("east")
        fix = np.isfinite(seg.outputs[:, iN]) & np.isfinite(seg.outputs[:, iE])
        if fix.sum() < 30:
            continue
        tf = seg.t[fix]
        keep = np.concatenate([[True], np.diff(tf) > 1e-6])  # splines need increasing abscissae
        rows = np.flatnonzero(fix)[keep]
        tf = seg.t[rows]
        through = {"north": (tf, seg.outputs[rows, iN]), "east": (tf, seg.outputs[rows, iE])}
        if "psi" in names:
            ip = names.index("psi")
            okp = np.isfinite(seg.outputs[:, ip])
            tp = seg.t[okp]
            kp = np.concatenate([[True], np.diff(tp) > 1e-6])
            through["psi"] = (tp[kp], np.unwrap(seg.outputs[okp, ip])[kp])
        if "r" in names:
            ir = names.index("r")
            okr = np.isfinite(seg.outputs[:, ir])
            tr = seg.t[okr]
            kr = np.concatenate([[True], np.diff(tr) > 1e-6])
            b = 0.0 if gyro_bias is None else float(gyro_bias[q])
            through["r"] = (tr[kr], seg.outputs[okr, ir][kr] - b)
        plan.append((q, seg, rows, {name: len(series) + k for k, name in enumerate(through)}))
        series.extend(through.values())
    splines = list(parallel(_spline_through, series))
    parts: list[tuple[np.ndarray, ...]] = []
    for q, seg, rows, at in plan:
        tf = seg.t[rows]
        sN, sE = splines[at["north"]], splines[at["east"]]
        dN, dE, aN, aE = sN.derivative(1)(tf), sE.derivative(1)(tf), sN.derivative(2)(tf), sE.derivative(2)(tf)
        if "psi" in at:
            sp = splines[at["psi"]]
            psi = sp(tf)
            r_psi = sp.derivative(1)(tf)
        else:  # course over ground as the heading
            psi = np.unwrap(np.arctan2(dE, dN))
            r_psi = np.gradient(psi, tf)
        if "r" in at:
            sr = splines[at["r"]]
            r, r_dot = sr(tf), sr.derivative(1)(tf)
        else:
            r, r_dot = r_psi, np.gradient(r_psi, tf)
        c, s = np.cos(psi), np.sin(psi)
        u, v = c * dN + s * dE, -s * dN + c * dE
        # d/dt of R(psi)^T [N', E']: the rotation of the body frame adds r v, -r u
        u_dot = c * aN + s * aE + r * v
        v_dot = -s * aN + c * aE - r * u
        inside = (tf >= tf[0] + EDGE_S) & (tf <= tf[-1] - EDGE_S)
        U = seg.inputs[rows]
        parts.append((tf[inside], psi[inside], u[inside], v[inside], r[inside], u_dot[inside], v_dot[inside],
                      r_dot[inside], U[inside], np.full(int(inside.sum()), q)))
    if not parts:
        raise ValueError("no segment with enough fixes for the equation-error start")
    cols = [np.concatenate([p[i] for p in parts]) for i in range(len(parts[0]))]
    return MotionSamples(*cols[:8], np.vstack([p[8] for p in parts]), cols[9])


def _filtered(x: np.ndarray, seg: np.ndarray, dt: float) -> np.ndarray:
    """The common low-pass of every column of `x` (FILTER_SIGMA_S), within each segment. The samples of a
    segment are one run (motion_samples concatenates them in order): each run is filtered in place of
    the output, no copy of it in and out (a 10-min lake record's regressors are ~10 MB, filtered ~2000
    times; the copies cost a million page faults, 2 s of system CPU). The same numbers either way."""
    out = np.empty(x.shape)
    sig = FILTER_SIGMA_S / dt
    edges = np.flatnonzero(np.diff(seg)) + 1
    if np.all(np.diff(seg[np.concatenate([[0], edges])]) > 0) if len(edges) else True:  # runs, in order
        for a, b in zip(np.concatenate([[0], edges]), np.concatenate([edges, [len(seg)]])):
            gaussian_filter1d(x[a:b], sig, axis=0, mode="nearest", output=out[a:b])
        return out
    for q in np.unique(seg):
        m = seg == q
        out[m] = gaussian_filter1d(x[m], sig, axis=0, mode="nearest")
    return out


#: a lake's current varies slowly (wind-driven, seiches): piecewise linear in time with a knot every this
#: many seconds, neighbouring knots tied by a random walk of CURRENT_WALK_MPS per knot interval
CURRENT_KNOT_S = 90.0
CURRENT_WALK_MPS = 0.02
WIND_PRIOR_MPS = 6.0  # the air's velocity: 0 +- this, per earth axis
# filtered regressor groups a _Regression keeps: per kind of what they depend on, and of the record's own
# columns one per stretch (the record and BATCHES stretches)
REGRESSOR_MEMO = 4
REGRESSOR_MEMO_RECORD = 16


@dataclass
class CurrentPath:
    """An earth-frame current piecewise linear in time (knots `t`, values north and east)."""

    t: np.ndarray
    north: np.ndarray
    east: np.ndarray

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """North, east and their rates at the times `t`."""
        if len(self.t) == 1:
            z = np.zeros_like(t)
            return z + self.north[0], z + self.east[0], z, z
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        dt = np.diff(self.t)[k]
        sN, sE = np.diff(self.north)[k] / dt, np.diff(self.east)[k] / dt
        return (self.north[k] + sN * (t - self.t[k]), self.east[k] + sE * (t - self.t[k]), sN, sE)

    @property
    def mean(self) -> tuple[float, float]:
        return float(np.mean(self.north)), float(np.mean(self.east))


@dataclass
class EquationErrorResult:
    params: VesselParameters
    environment: np.ndarray | None  # lake: current (2), air velocity (2), wind coefficients (ENV_NAMES)
    residual_std: np.ndarray  # per equation (X, Y, N), in N / N / N m
    cost: float
    std: dict[str, float]  # 1-sigma of the estimated coefficients (inf: at a bound)
    free_names: tuple[str, ...]
    current_path: CurrentPath | None = None  # lake: the current over the record
    # the motion samples it was fitted on and the gyro offsets they were taken with (another fit of the
    # same records takes them as they are: the splines are the data's alone)
    motion: MotionSamples | None = field(default=None, repr=False)
    motion_gyro_bias: list[float] | None = field(default=None, repr=False)


#: a parameter's regressor column: its rows in the three equations (X, Y, N) such that
#: sum_j theta_j col_j = 0 (+ thrust on the right); None where the column is zero in that equation
Column = tuple["np.ndarray | None", "np.ndarray | None", "np.ndarray | None"]
WIND_COLUMNS = tuple(ENV_NAMES[4:4 + N_WIND])  # the wind's drag coefficients, the last columns


def _unit_thrust(ms: MotionSamples, nu: tuple[np.ndarray, ...], kappa: float, geometry: VesselGeometry,
                 **unit: float) -> Column:
    """The thrusters' forces per unit of one thrust coefficient (the model's own code), moved to the left."""
    th = dict.fromkeys(NAMES, 0.0)
    th.update(m11=1.0, m22=1.0, m33=1.0, kappa=kappa, **unit)
    tau = array_tau(nu, tuple(ms.inputs[:, i] for i in range(5)), [th[n] for n in NAMES], geometry)
    return tuple(-t for t in tau)  # type: ignore[return-value]


def _record_columns(ms: MotionSamples, geometry: VesselGeometry) -> dict[str, Column]:
    """The columns that depend on the record alone, whatever kappa, current and wind: the yaw rate's and
    the thrust's (with the housing force off, C_N = 0, the thrust depends on neither kappa nor the
    water's velocity)."""
    r = ms.r
    ar = np.abs(r)
    nu = (ms.u, ms.v, r)  # with C_N = 0 neither the velocity nor kappa enters the thrust
    return {"m33": (None, None, ms.r_dot), "Y_r": (None, r, None), "N_r": (None, None, r),
            "N_rr": (None, None, -ar * r), "mu_az": _unit_thrust(ms, nu, 0.0, geometry, mu_az=1.0),
            "mu_t": _unit_thrust(ms, nu, 0.0, geometry, mu_t=1.0)}


def _relative_motion(ms: MotionSamples, current: "tuple[float, float] | CurrentPath"
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The velocity relative to the water nu_r = nu - R(psi)^T c and its rate (u_r, v_r, u_r', v_r'); the
    current: constant (north, east) or a CurrentPath (piecewise linear in time)."""
    u, v, r = ms.u, ms.v, ms.r
    c, s = np.cos(ms.psi), np.sin(ms.psi)
    if isinstance(current, CurrentPath):
        cN, cE, dN, dE = current.at(ms.t)
    else:
        cN, cE, dN, dE = current[0], current[1], 0.0, 0.0
    uc, vc = cN * c + cE * s, -cN * s + cE * c
    # nu_r' = nu' - r [v_c, -u_c] - R^T c' (the current turns with the body frame and drifts in time)
    return u - uc, v - vc, ms.u_dot - r * vc - (dN * c + dE * s), ms.v_dot + r * uc - (-dN * s + dE * c)


def _water_columns(ms: MotionSamples, current: "tuple[float, float] | CurrentPath") -> dict[str, Column]:
    """The columns of the velocity relative to the water (seed eq. 22 on nu_r, the module docstring)."""
    ur, vr, urd, vrd = _relative_motion(ms, current)
    r = ms.r
    au, av, ar = np.abs(ur), np.abs(vr), np.abs(r)
    return {
        "m11": (urd, ur * r, -ur * vr), "m22": (-vr * r, vrd, ur * vr),
        "X_u": (ur, None, None), "X_uu": (-au * ur, None, None), "X_uuu": (-ur * ur * ur, None, None),
        "Y_v": (None, vr, None), "Y_uv": (None, -au * vr, None), "Y_vv": (None, -av * vr, None),
        "Y_rv": (None, -ar * vr, None), "N_v": (None, None, vr), "N_vv": (None, None, -av * vr),
    }


def _housing_column(ms: MotionSamples, current: "tuple[float, float] | CurrentPath", kappa: float,
                    geometry: VesselGeometry) -> dict[str, Column]:
    """C_N's column: the housing force per unit C_N (on the inflow kappa n and the water's velocity)."""
    ur, vr, _, _ = _relative_motion(ms, current)
    return {"C_N": _unit_thrust(ms, (ur, vr, ms.r), kappa, geometry, C_N=1.0)}


def _wind_columns(ms: MotionSamples, wind: tuple[float, float]) -> dict[str, Column]:
    """tau_wind = sum_k k_j basis_j: the unit coefficients' forces at the air velocity `wind`, moved to
    the left."""
    cols: dict[str, Column] = {}
    for name, unit in zip(WIND_COLUMNS, np.eye(N_WIND)):
        f = apparent_wind_force(ms.psi, ms.u, ms.v, wind[0], wind[1], *unit, cos=np.cos, sin=np.sin, sqrt=np.sqrt)
        cols[name] = tuple(-np.broadcast_to(x, ms.u.shape) for x in f)  # type: ignore[assignment]
    return cols


def _free_names(theta_fixed: Mapping[int, float], wind: tuple[float, float] | None) -> tuple[list[int], list[str]]:
    """The free parameters' indices and the names of the regression's columns (wind coefficients last)."""
    free = [i for i, n in enumerate(NAMES) if i not in theta_fixed and n != "kappa"]
    return free, [NAMES[i] for i in free] + (list(WIND_COLUMNS) if wind is not None else [])


def _right_side(cols: Mapping[str, Column], theta_fixed: Mapping[int, float], n: int) -> np.ndarray:
    """b (3 x n): the fixed parameters' columns moved to the right."""
    b = np.zeros((3, n))
    for i, val in theta_fixed.items():
        if NAMES[i] != "kappa":
            for e, x in enumerate(cols[NAMES[i]]):
                if x is not None:
                    b[e] -= val * x
    return b


@dataclass
class _Filtered:
    """A group of regressor columns computed for one value of what they depend on: as computed (for the
    right-hand side) and filtered (the free parameters' columns, where not zero)."""

    raw: dict[str, Column]
    filtered: dict[str, Column]


def _filter_group(cols: dict[str, Column], wanted: set[str], seg: np.ndarray, dt: float) -> _Filtered:
    """`cols` with the wanted columns' rows filtered, all in one pass (each column is filtered alone, so
    the numbers are those of filtering the whole regressor matrix); a row that is zero stays zero."""
    pieces = [(name, e) for name in cols if name in wanted for e, x in enumerate(cols[name])
              if x is not None and np.any(x)]
    out = {name: [None, None, None] for name in cols if name in wanted}
    if pieces:
        f = _filtered(np.column_stack([cols[name][e] for name, e in pieces]), seg, dt)
        for k, (name, e) in enumerate(pieces):
            out[name][e] = f[:, k]
    return _Filtered(cols, {name: tuple(x) for name, x in out.items()})  # type: ignore[misc]


@dataclass(frozen=True)
class _Regression:
    """The linear part of the fit on the record's motion samples: for given kappa, current and air
    velocity, the bounded linear least squares of every other coefficient. What a worker keeps
    (lotsen.sysid.parallel.Held): the searches around it send kappa, current and wind only."""

    ms: MotionSamples
    theta_fixed: Mapping[int, float]
    geometry: VesselGeometry
    dt: float
    lo: np.ndarray
    hi: np.ndarray
    # the column groups already filtered, by what they depend on (`regressors`); each process fills its
    # own (a worker's Held copy starts empty: __getstate__)
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    def __getstate__(self) -> dict:
        return {**self.__dict__, "memo": {}}

    def _kept(self, key: tuple, make: Callable[[], Any]) -> Any:
        """make() for `key` (its kind first), computed once: the newest few per kind are kept."""
        kept = self.memo.setdefault(key[0], OrderedDict())
        if key in kept:
            kept.move_to_end(key)
            return kept[key]
        value = kept[key] = make()
        while len(kept) > (REGRESSOR_MEMO_RECORD if key[0] in ("rows", "record") else REGRESSOR_MEMO):
            kept.popitem(last=False)
        return value

    def regressors(self, kappa: float, current: Any, wind: tuple[float, float] | None,
                   rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list[int], MotionSamples]:
        """The filtered regression at (kappa, current, wind), n x 3 x p and n x 3, and the samples: to the
        last digit the common low-pass of the whole regression's A and b, the columns side by side (the
        filter acts on each column alone; tests/sysid/test_parallel.py builds that A and b to check it),
        each column group filtered once per value of what it depends on (the record alone; the current;
        kappa and the current; the air's velocity): the searches vary kappa, current and wind one at a
        time, the stretches re-solve with the record's, kappa's search keeps the current.
        `rows`: only these (contiguous) samples."""
        rk = None if rows is None else rows.tobytes()
        mx = self._kept(("rows", rk), lambda: self.ms if rows is None else self.ms.subset(rows))
        free, names = _free_names(self.theta_fixed, wind)
        wanted, seg, dt, geometry = set(names), mx.segment, self.dt, self.geometry
        ck = np.asarray([current.t, current.north, current.east] if isinstance(current, CurrentPath)
                        else current, float).tobytes()
        keyed = [(("record", rk), lambda: _record_columns(mx, geometry)),
                 (("water", rk, ck), lambda: _water_columns(mx, current)),
                 (("housing", rk, ck, kappa), lambda: _housing_column(mx, current, kappa, geometry))]
        if wind is not None:
            keyed.append((("air", rk, np.asarray(wind, float).tobytes()), lambda: _wind_columns(mx, wind)))
        groups = [(key, self._kept(key, lambda make=make: _filter_group(make(), wanted, seg, dt)))  # type: ignore[misc]
                  for key, make in keyed]
        Af = np.zeros((len(mx.u), 3, len(names)))
        for _, g in groups:
            for j, name in enumerate(names):
                for e, x in enumerate(g.filtered.get(name, ())):
                    if x is not None:
                        Af[:, e, j] = x
        # b from the groups that hold a fixed parameter's column (_right_side over them)
        fixed = {NAMES[i] for i in self.theta_fixed}
        holders = [(key, g) for key, g in groups if fixed & g.raw.keys()]
        raw = {name: col for _, g in holders for name, col in g.raw.items()}
        bf = self._kept(("b", rk, *(key for key, _ in holders)),
                        lambda: _filtered(_right_side(raw, self.theta_fixed, len(mx.u)).T, seg, dt))
        return Af, bf, free, mx

    def solve(self, kappa: float, current: Any, wind: tuple[float, float] | None,
              weights: np.ndarray, rows: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, list[int], np.ndarray, np.ndarray]:
        """The bounded linear least squares at (kappa, current, wind): (weighted residuals 3 x n,
        coefficients, free indices, residual std per equation, the filtered weighted regressors);
        `rows`: only these (contiguous) samples."""
        lo, hi, dt = self.lo, self.hi, self.dt
        Af, bf, free, mx = self.regressors(kappa, current, wind, rows)
        n = len(mx.u)
        Af = Af.transpose(1, 0, 2) * weights[:, None, None]
        bf = bf.T * weights[:, None]
        nw = Af.shape[2] - len(free)
        lo_f = np.concatenate([lo[free], K_WIND_MIN[:nw]])
        hi_f = np.concatenate([hi[free], K_WIND_MAX[:nw]])
        Am, bm = Af.reshape(3 * n, -1), bf.ravel()
        norms = np.linalg.norm(Am, axis=0)
        dead = [NAMES[i] for j, i in enumerate(free) if norms[j] <= 1e-9 * norms.max()]
        if dead and rows is None:  # a coefficient the record never exercised (a bow thruster never run)
            raise IdentifiabilityError(f"the record holds no information on {', '.join(dead)} (nothing in it "
                                       "moves the boat through them): fix those parameters (--fix NAME=VALUE) "
                                       "or record data that excite them")
        colscale = np.maximum(norms, 1e-12)
        # the bounded problem on a triangular factor of the normal equations: the same minimiser, p rows
        # instead of 3 n (|A x - b|^2 = |R x - q|^2 + const with R^T R = A^T A, R^T q = A^T b)
        As = Am / colscale
        G = As.T @ As
        h = As.T @ bm
        if nw:  # the wind's drag near the nominal hull's (K_WIND_PRIOR): drag and wind speed trade as k W^2
            pw = np.arange(len(free), len(free) + nw)
            kp = K_WIND_MEAN[:nw] * colscale[pw]
            sp = K_WIND_PRIOR_STD[:nw] * colscale[pw] / _walk_rows(dt)
            G[pw, pw] += 1.0 / sp ** 2
            h[pw] += kp / sp ** 2
        G[np.diag_indices_from(G)] += 1e-12 * np.trace(G)
        R = np.linalg.cholesky(G).T
        q = np.linalg.solve(R.T, h)
        sol = lsq_linear(R, q, bounds=(lo_f * colscale, hi_f * colscale), method="bvls")
        x = sol.x / colscale
        res = (bm - Am @ x).reshape(3, n)
        return res, x, free, np.sqrt(np.mean(res ** 2, axis=1)) / weights, Af



@dataclass(frozen=True)
class _LakeFit:
    """The lake search's unknowns besides the linear coefficients, packed in one vector z: log kappa, the
    air velocity (north, east) and the current's knots (north, then east), with the random walk between
    knots and the air's prior as extra residual rows."""

    knots: np.ndarray
    kappa0: float
    kappa_fixed: bool
    walk_weight: float

    def kappa_of(self, lk: float) -> float:
        lo, hi = math.log(KAPPA_RANGE[0]), math.log(KAPPA_RANGE[1])
        return self.kappa0 if self.kappa_fixed else math.exp(min(max(lk, lo), hi))

    def unpack(self, z: np.ndarray) -> tuple[float, CurrentPath, tuple[float, float]]:
        n_knots = len(self.knots)
        cur = CurrentPath(self.knots, z[3:3 + n_knots], z[3 + n_knots:])
        return self.kappa_of(z[0]), cur, (float(z[1]), float(z[2]))

    def residual(self, reg: _Regression, z: np.ndarray, w: np.ndarray) -> np.ndarray:
        k, cur, wind = self.unpack(z)
        res = reg.solve(k, cur, wind, w)[0].ravel()
        walk = np.concatenate([np.diff(cur.north), np.diff(cur.east)]) / CURRENT_WALK_MPS * self.walk_weight
        # a weak prior on the air's velocity: in calm air its drag is hardly seen and the wind's
        # speed would wander (23 m/s on a windless record); a lake wind is a few m/s
        air = np.array(wind) / WIND_PRIOR_MPS * self.walk_weight
        return np.concatenate([res, walk, air])

    def unprojected(self, reg: _Regression, zz: np.ndarray, xx: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """The weighted, filtered residual at (zz, xx): the coefficients held."""
        Af, bf, _, _ = reg.regressors(*self.unpack(zz))
        return (bf.T - np.einsum("nep,p->en", Af, xx)) * weights[:, None]


# -- the independent solves, as the workers run them (lotsen.sysid.parallel.map_held) ----------------
def _lake_residual(reg: _Regression, task: tuple[_LakeFit, np.ndarray, np.ndarray]) -> np.ndarray:
    fit, z, w = task
    return fit.residual(reg, z, w)


def _unprojected(reg: _Regression, task: tuple[_LakeFit, np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    fit, zz, xx, weights = task
    return fit.unprojected(reg, zz, xx, weights)


def _kappa_cost(reg: _Regression, task: tuple[float, np.ndarray]) -> float:
    kappa, weights = task
    return float(np.sum(reg.solve(kappa, (0.0, 0.0), None, weights)[0] ** 2))


def _stretch(reg: _Regression, task: tuple) -> np.ndarray:
    """A stretch of the record re-solved with kappa, current and wind held: its coefficients."""
    kappa, current, wind, weights, blk = task
    return reg.solve(kappa, current, wind, weights, blk)[1]


def _lake_stretch(reg: _Regression, task: tuple) -> np.ndarray:
    """A stretch of a lake record with its own current and wind, re-solved as offsets from the record's
    (priors as the record's), so that their uncertainty enters the stretches' spread: its coefficients."""
    kappa, current, wind, weights, blk, walk_weight = task

    def res_b(dz: np.ndarray) -> np.ndarray:
        cur = CurrentPath(current.t, current.north + dz[0], current.east + dz[1])
        wd = (wind[0] + dz[2], wind[1] + dz[3])
        r = reg.solve(kappa, cur, wd, weights, blk)[0].ravel()
        return np.concatenate([r, dz[:2] / CURRENT_WALK_MPS * walk_weight, dz[2:] / WIND_PRIOR_MPS * walk_weight])

    dz = least_squares(res_b, np.zeros(4), x_scale=np.array([0.02, 0.02, 1.0, 1.0]), diff_step=1e-3,
                       xtol=1e-3, ftol=1e-4, max_nfev=12).x
    cur = CurrentPath(current.t, current.north + dz[0], current.east + dz[1])
    return reg.solve(kappa, cur, (wind[0] + dz[2], wind[1] + dz[3]), weights, blk)[1]


def estimate_equation_error(records: Sequence[IdRecord], fixed: Mapping[str, float],
                            theta0: VesselParameters, options: SolverOptions = SolverOptions(),
                            gyro_bias: Sequence[float] | None = None, env0: Sequence[float] | None = None,
                            hold: "EquationErrorResult | None" = None, parallel: Map = SERIAL) -> EquationErrorResult:
    """The equation-error estimate (module docstring) of every parameter not in `fixed` (kappa by a
    bounded search); `lake`: with a current that varies slowly (CurrentPath), an air velocity and the
    wind's drag coefficients (started from `env0`, ENV_NAMES order). `theta0` supplies the fixed
    coefficients' values where `fixed` does not and kappa's start. `hold`: another fit of the same
    records, whose motion samples are taken and, on a lake, whose kappa, current and wind are kept (only
    the linear part is solved again: the optional terms' trial). Of `options` it takes the geometry, the gap that splits a record, `lake`
    and the optional `terms` to estimate. `parallel`: the map its independent solves run on
    (lotsen.sysid.parallel; the same answer with any number of workers)."""
    geometry, gap_s, lake, terms = options.geometry, options.gap_s, options.lake, options.terms
    segs = [s for r in records for s in split_segments(r, gap_s)]
    per_segment_bias = None
    if gyro_bias is not None:
        rec_of_seg = [q for q, r in enumerate(records) for _ in split_segments(r, gap_s)]
        per_segment_bias = [gyro_bias[q] for q in rec_of_seg]
    if hold is not None and hold.motion is not None and hold.motion_gyro_bias == per_segment_bias:
        ms = hold.motion  # the same records and offsets: the same splines
    else:
        ms = motion_samples(segs, per_segment_bias, parallel)
    dt = float(np.median(np.diff(ms.t))) if len(ms.t) > 1 else 0.125
    lo, hi = parameter_bounds()
    fixed = with_terms_off(fixed, theta0, terms)  # the optional model terms off unless in `terms`
    theta_fixed = {NAMES.index(n): float(v) for n, v in fixed.items()}
    kappa_fixed = "kappa" in fixed
    last: tuple = ()

    reg = _Regression(ms, theta_fixed, geometry, dt, lo, hi)
    shared = Held(reg)  # what the workers keep: the motion samples

    def on_workers(task: Callable[[_Regression, Any], Any], arguments: Sequence[Any]) -> list:
        """task(reg, a) for each a, on `parallel`'s workers (independent solves: the candidates, the
        finite differences' columns, the stretches)."""
        return map_held(parallel, task, [shared] * len(arguments), list(arguments))

    def solve(kappa: float, current: Any, wind: tuple[float, float] | None,
              weights: np.ndarray, rows: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray, list[int], np.ndarray]:
        """_Regression.solve; the last call's filtered regressors and residuals kept for the sandwich."""
        nonlocal last
        res, x, free, rstd, Af = reg.solve(kappa, current, wind, weights, rows)
        last = (Af, res)
        return res, x, free, rstd

    weights = np.array([1.0, 1.0, 10.0])  # N, N, N m: the moment's arm about 0.1 m
    kappa0 = float(fixed.get("kappa", theta0.kappa))
    lk_lo, lk_hi = math.log(KAPPA_RANGE[0]), math.log(KAPPA_RANGE[1])
    lk0 = math.log(min(max(kappa0, KAPPA_RANGE[0]), KAPPA_RANGE[1]))

    def kappa_of(lk: float) -> float:
        return kappa0 if kappa_fixed else math.exp(min(max(lk, lk_lo), lk_hi))

    if lake:
        # the current's knots over the record (one path for all segments, in the record's time)
        span = max(float(ms.t[-1] - ms.t[0]), 1.0)
        n_knots = max(1, int(math.ceil(span / CURRENT_KNOT_S)) + 1)
        knots = np.linspace(float(ms.t[0]), float(ms.t[-1]), n_knots) if n_knots > 1 else np.array([float(ms.t[0])])
        env = np.asarray(env0, float)[:4] if env0 is not None else np.zeros(4)
        # the random walk between knots, as rows beside the data's (which are correlated over ~2 s
        # by the common filter: as many independent rows as that leaves, per knot interval)
        walk_weight = _walk_rows(dt)
        fit = _LakeFit(knots, kappa0, kappa_fixed, walk_weight)
        unpack = fit.unpack

        def residual(z: np.ndarray, w: np.ndarray) -> np.ndarray:
            return fit.residual(reg, z, w)

        def residuals(zs: Sequence[np.ndarray], w: np.ndarray) -> list[np.ndarray]:
            return on_workers(_lake_residual, [(fit, z, w) for z in zs])

        def start(wind: tuple[float, float]) -> np.ndarray:
            return np.concatenate([[lk0, wind[0], wind[1]], np.full(n_knots, env[0]), np.full(n_knots, env[1])])

        zlo = np.concatenate([[lk_lo, -30.0, -30.0], np.full(2 * n_knots, -1.0)])
        zhi = np.concatenate([[lk_hi, 30.0, 30.0], np.full(2 * n_knots, 1.0)])
        scale = np.concatenate([[0.5, 1.0, 1.0], np.full(2 * n_knots, 0.02)])
        held = hold is not None and hold.current_path is not None and len(hold.current_path.t) == n_knots
        if held:  # another fit's kappa, wind and current (the optional terms' trial): the linear part only
            z = np.concatenate([[math.log(min(max(hold.params.kappa, KAPPA_RANGE[0]), KAPPA_RANGE[1]))],  # type: ignore[union-attr]
                                hold.environment[2:4], hold.current_path.north, hold.current_path.east])  # type: ignore[union-attr,index]
        else:
            # the wind's direction is the search's hardest part: a grid of air velocities (eight
            # directions, two speeds) for the best start, then a bounded Gauss-Newton search over all of it
            cands = [start((env[2], env[3]))] + [start((w * math.cos(a), w * math.sin(a)))
                                                 for a in np.arange(8) * math.pi / 4 for w in (2.0, 4.5)]
            z = cands[int(np.argmin([float(np.sum(r ** 2)) for r in residuals(cands, weights)]))]
        for _ in range(2):  # the second pass with each equation weighted by its own residual spread
            if not held:
                # the finite differences' columns on the workers (scipy's own differences: it hands the
                # map the points, `residuals` evaluates them as `residual` would)
                sol = least_squares(residual, np.clip(z, zlo, zhi), bounds=(zlo, zhi), x_scale=scale,
                                    args=(weights,), diff_step=1e-3, xtol=1e-4, ftol=1e-5, max_nfev=30,
                                    workers=lambda _f, zs, w=weights: residuals(list(zs), w))
                z = sol.x
            _, _, _, rstd = solve(*unpack(z), weights)
            weights = 1.0 / np.maximum(rstd, 1e-9)
        kappa, current, wind = unpack(z)

        def nonlinear_sensitivity(xx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """-d residual / d z by differences (the current's knots and the air's velocity; kappa's
            own interval comes from its profile), and those parameters' priors' information."""
            sel = np.arange(1, len(z)) if not kappa_fixed else np.arange(1, len(z))
            steps, points = [], [z]
            for j in sel:
                h = 1e-3 * scale[j] * 10
                zp = z.copy()
                zp[j] += h
                steps.append(h)
                points.append(zp)
            r0, *rs = on_workers(_unprojected, [(fit, zz, xx, weights) for zz in points])
            cols = [-(r - r0) / h for r, h in zip(rs, steps)]
            Dz = np.stack(cols, axis=-1)
            info = np.zeros((len(sel), len(sel)))
            info[:2, :2] = np.eye(2) * (walk_weight / WIND_PRIOR_MPS) ** 2
            Dw = np.diff(np.eye(n_knots), axis=0) * walk_weight / CURRENT_WALK_MPS
            for off in (2, 2 + n_knots):
                info[off:off + n_knots, off:off + n_knots] += Dw.T @ Dw
            return Dz, info
    else:
        current, wind = (0.0, 0.0), None
        kappa = kappa0
        for _ in range(2):  # the second pass with each equation weighted by its own residual spread
            if not kappa_fixed:
                def cost(lk: float) -> float:
                    return float(np.sum(solve(kappa_of(lk), current, wind, weights)[0] ** 2))

                grid = np.linspace(lk_lo, lk_hi, 13)
                g0 = grid[int(np.argmin(on_workers(_kappa_cost, [(kappa_of(g), weights) for g in grid])))]
                opt = minimize(lambda zz: cost(float(zz[0])), np.array([g0]), method="Nelder-Mead",
                               options={"xatol": 1e-3, "maxiter": 100})
                kappa = kappa_of(float(opt.x[0]))
            _, _, _, rstd = solve(kappa, current, wind, weights)
            weights = 1.0 / np.maximum(rstd, 1e-9)
    res, x, free, rstd = solve(kappa, current, wind, weights)  # the final weights' regression
    total = float(np.sum(res ** 2))
    Dz, prior_info = nonlinear_sensitivity(x) if lake else (None, None)
    cov = _sandwich(*last, ms.segment, Dz, prior_info, dt)
    # the spread between stretches of the record (batch means): the effective values of a hull that is
    # not the grey box depend on what each stretch asked of it (speeds, turns, the wind's gusts), which
    # no residual correlation within the record shows; each stretch re-solved with kappa, current and
    # wind held, the variance of their mean taken where it exceeds the sandwich's
    stretches = [blk for blk in np.array_split(np.arange(len(ms.t)), BATCHES) if len(blk) > 50]
    if len(stretches) >= 3:
        if lake:
            # on a lake each stretch has its own current and wind too: re-solved as offsets from the
            # record's (priors as the record's), so their uncertainty enters the stretches' spread
            xs = np.array(on_workers(_lake_stretch, [(kappa, current, wind, weights, blk, walk_weight)
                                                     for blk in stretches]))[:, :len(free)]
        else:
            xs = np.array(on_workers(_stretch, [(kappa, current, wind, weights, blk) for blk in stretches]))[:, :len(free)]
        batch_var = np.var(xs, axis=0, ddof=1) / len(stretches)
        d = np.diag(cov)[:len(free)].copy()
        finite = np.isfinite(d)
        d[finite] = np.maximum(d[finite], batch_var[finite])
        cov[np.arange(len(free)), np.arange(len(free))] = d
    solve(kappa, current, wind, weights)  # `last` back to the whole record (kappa's profile below)
    kappa_std = math.inf
    if not kappa_fixed:
        profiled: dict[float, tuple] = {}

        def at(k: float) -> tuple:
            """The solve at kappa k, once: the slope's two kappas are the curvature's outer two."""
            if k not in profiled:
                profiled[k] = solve(k, current, wind, weights)
            return profiled[k]

        kappa_std = _profile_std(lambda k: float(np.sum(at(k)[0] ** 2)), kappa,
                                 float(np.median(np.diag(cov)[:len(free)]
                                                 / np.maximum(_naive_var(last[0])[:len(free)], 1e-300))),
                                 3 * len(ms.t) - len(x))
        if math.isfinite(kappa_std):
            # kappa is profiled (the rest re-solved at each kappa), so its uncertainty moves the others
            # along the profile: the delta method adds (dx/dkappa)(dx/dkappa)^T var(kappa). Without it
            # C_N, which trades with kappa, was 6.7 of its sigma apart between two records of one hull
            dx = _profile_slope(lambda k: at(k)[1][:len(free)], kappa)
            d = cov[:len(free), :len(free)]
            fin = np.isfinite(np.diag(d))
            d[np.ix_(fin, fin)] += np.outer(dx[fin], dx[fin]) * kappa_std ** 2
    std = {NAMES[i]: float(math.sqrt(cov[j, j])) if math.isfinite(cov[j, j]) else math.inf
           for j, i in enumerate(free)}
    if not kappa_fixed:
        std["kappa"] = kappa_std
    theta = np.array(theta0.to_vector(), float)
    for i, val in theta_fixed.items():
        theta[i] = val
    theta[free] = x[:len(free)]
    theta[NAMES.index("kappa")] = kappa
    theta = np.clip(theta, lo, hi)
    env_out = None
    if lake:
        cm = current.mean  # type: ignore[union-attr]
        env_out = np.array([cm[0], cm[1], wind[0], wind[1], *x[len(free):]])  # type: ignore[index]
    return EquationErrorResult(VesselParameters.from_vector(theta), env_out, rstd, total, std,
                               tuple(NAMES[i] for i in free) + (() if kappa_fixed else ("kappa",)),
                               current if lake else None, ms, per_segment_bias)


def _naive_var(Af: np.ndarray) -> np.ndarray:
    """Diagonal of (A^T A)^-1 (the white-noise covariance per unit residual variance)."""
    A = Af.reshape(-1, Af.shape[-1])
    try:
        return np.diag(np.linalg.inv(A.T @ A))
    except np.linalg.LinAlgError:
        return np.full(A.shape[1], np.inf)


def _sandwich(Af: np.ndarray, res: np.ndarray, segment: np.ndarray, Dz: np.ndarray | None = None,
              prior_info: np.ndarray | None = None, dt: float = 0.125) -> np.ndarray:
    """Covariance of the regression's coefficients robust to correlated residuals: G^-1 M G^-1 with the
    per-sample scores' covariance M by Newey-West (Bartlett weights up to twice the residuals'
    correlation time, within segments). The columns are filtered (FILTER_SIGMA_S), so residuals stay
    correlated over seconds whatever the model. A coefficient at its bound gets the interval of the
    unconstrained local fit: the values the data support around it (on a real hull a bound-held
    coefficient of one record and a free one of another were 0.2 of that sigma apart, reported as
    disagreeing for want of an interval), and its freedom widens the others'. `Dz` (3 x n x q): the residual's sensitivity to
    the nonlinear parameters found around the regression (a lake's current and wind), with their
    priors' information `prior_info` (q x q): their uncertainty then widens the coefficients' (without
    it two lake records of one hull agreed on 12 of 17 coefficients within 3 sigma)."""
    A = Af  # 3 x n x k
    k = A.shape[-1]
    if Dz is not None:
        A = np.concatenate([A, Dz], axis=-1)
    S = np.einsum("enk,en->nk", A, res)  # per sample: the three equations' scores summed
    G = np.einsum("enk,enl->kl", A, A)
    if prior_info is not None:
        G[k:, k:] += prior_info
    r = res.sum(axis=0)
    r = r - r.mean()
    tau = 1.0
    v = float(r @ r)
    for lag in range(1, min(400, len(r) // 5)):
        rho = float(r[:-lag] @ r[lag:]) / v if v > 0 else 0.0
        if rho < 0.05:
            break
        tau += 2.0 * rho
    # at least NW_MIN_BANDWIDTH_S: the misfit of a hull that is not the grey box (a gust's force the wind
    # model does not follow) stays correlated over seconds though the lag-by-lag correlation is small
    L = int(max(1, min(max(round(2.0 * tau), round(NW_MIN_BANDWIDTH_S / dt)), len(S) // 10)))
    M = S.T @ S
    for lag in range(1, L + 1):
        same = (segment[lag:] == segment[:-lag]).astype(float)
        Gl = (S[:-lag] * same[:, None]).T @ S[lag:]
        M += (1.0 - lag / (L + 1.0)) * (Gl + Gl.T)
    if prior_info is not None:
        M[k:, k:] += prior_info
    try:
        Gi = np.linalg.inv(G)
    except np.linalg.LinAlgError:
        Gi = np.linalg.pinv(G)
    sub = (Gi @ M @ Gi)[:k, :k]
    return 0.5 * (sub + sub.T)


def _kappa_steps(kappa: float, h: float) -> tuple[float, float, float]:
    """Three kappas spaced h in log kappa around `kappa`, shifted inwards at an end of KAPPA_RANGE (an
    estimate at its bound still has the curvature and slope of the values the data allow)."""
    lo, hi = math.log(KAPPA_RANGE[0]), math.log(KAPPA_RANGE[1])
    mid = min(max(math.log(kappa), lo + h), hi - h)
    return math.exp(mid - h), math.exp(mid), math.exp(mid + h)


def _profile_slope(x_of, kappa: float, h: float = 0.05) -> np.ndarray:  # type: ignore[no-untyped-def]
    """d x / d kappa of the profiled coefficients x(kappa), by a central difference in log kappa."""
    km, _, kp = _kappa_steps(kappa, h)
    return (np.asarray(x_of(kp)) - np.asarray(x_of(km))) / (kp - km)


def _profile_std(cost_of, kappa: float, inflation: float, dof: int) -> float:  # type: ignore[no-untyped-def]
    """kappa's 1-sigma from the curvature of the profiled weighted cost (the rest re-solved at each
    kappa), in log kappa, with the regression's own residual variance and the sandwich's inflation."""
    h = 0.05
    km, k0, kp = _kappa_steps(kappa, h)
    c0, cp, cm = cost_of(k0), cost_of(kp), cost_of(km)
    curv = (cp - 2 * c0 + cm) / (h * h)
    s2 = c0 / max(dof, 1)
    if curv <= 0 or not math.isfinite(curv):
        return math.inf
    return kappa * math.sqrt(2.0 * s2 * max(inflation, 1.0) / curv)
