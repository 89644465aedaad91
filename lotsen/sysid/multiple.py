"""Multiple shooting over the whole record: the output-error estimate that reaches the record's bound.

Every gap-free segment is cut at measurement rows into shooting intervals of about `node_s`
seconds. Each interval is simulated from its own node state s_i (RK4, h <= `h_max`, each step with the
step average of the input as the record's input kind defines it: held for commands, piecewise linear
for achieved values; lotsen.sysid.data) with forward sensitivities d x / d[s_i, theta]
(lotsen.sysid.sensitivity, the model's own equations through CasADi). The unknowns are all node
states and the free parameters; the problem is

    min  1/2 sum_k || W^1/2 (y_k - h(x_k(s, theta))) ||^2      (psi residuals wrapped)
    s.t. c_i = x_i(t_{i+1}; s_i, theta) - s_{i+1} = 0            (continuity, exactly)

so at the solution the trajectory is one simulation of the model over each segment, from an
estimated initial state: the least-squares (maximum-likelihood, Gaussian noise) estimate of the
whole record, whose covariance is the Cramer-Rao bound of the record with the initial state free.
Short intervals keep every simulation well conditioned although the vessel is open-loop unstable
(the sway-yaw pole reaches +1.4 1/s): the data, not a long simulation, carry the trajectory.

Solver: constrained Gauss-Newton (Bock's generalised Gauss-Newton) with Levenberg-Marquardt
damping. Each iteration solves the KKT system of the linearised problem,

    [ H + mu D   C^T ] [dz]   [ -J^T e ]
    [ C          0   ] [lam] = [ -c     ]      H = J^T J, z = (node states, parameters),

exploiting its structure: the node-state / multiplier part A is block-banded (6 x 6 blocks) and is
factorised by a sparse LU (scipy SuperLU); the parameters are eliminated through the Schur
complement  F = H_pp - B^T A^-1 B  (a dense n_free x n_free matrix). The cost per iteration is
linear in the record length. Steps are accepted on the exact-penalty merit function
1/2 |e|^2 + nu |c|_1 with a ratio test; mu adapts as in Levenberg-Marquardt.

Uncertainty: at the solution, F (mu = 0) is the Fisher information of the parameters with every
node state eliminated under the continuity constraints, i.e. of the whole record with its initial
state free; covariance = s^2 F^-1 with s^2 the a-posteriori noise factor. By default the noise
standard deviation of each output is re-estimated from its residuals (two passes), so that the
intervals hold when the assumed sensor noise is wrong. `record_fisher` evaluates the same F at
given parameters (the Cramer-Rao bound for experiment design and Monte-Carlo checks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from lotsen.errors import LotsenError
from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselGeometry, VesselParameters, geometry_tuple
from lotsen.sysid.data import (
    OUTPUT_STATE_INDEX, IdRecord, Segment, check_excitation, check_record, split_segments, step_input_lines,
)
from lotsen.sysid.estimate import (
    DEFAULT_NOISE_STD, NAMES, EstimationError, IdentifiabilityError, IdentificationResult, SolverOptions,
    check_scale_fixed, identifiability, parameter_bounds, parameter_scale, starting_point, with_terms_off,
)
from lotsen.model.environment import wind_drag_coefficients
from lotsen.sysid.kernels import step_kernels
from lotsen.sysid.parallel import SERIAL, Held, Map, map_held, ordered_sum
from lotsen.sysid.sensitivity import ENV_NAMES, NTHETA, NTHETA_LAKE
from lotsen.sysid.shooting_blocks import BlockCall, ShootingBlock, block_scores, cut_blocks, linearise_block

# continuity defects below this (noise units) are negligible: the trajectory is one simulation
CONTINUITY_TOL = 1e-3
# node-state scale (noise-like units: the continuity defects are compared with the measurement noise)
X_SCALE = np.array([0.01, 0.01, 0.01, 0.01, 0.01, 0.003])
# the lake model (`lake=True`): the gust factor's scale, and the environment's start, scale and prior
GUST_SCALE = 0.05
_K_WIND = np.array([*wind_drag_coefficients(), 0.1 * wind_drag_coefficients()[1]])  # k_Nv: a 0.1 m arm
ENV_START = np.array([0.0, 0.0, 0.0, 0.0, *_K_WIND[:3], 0.0])
ENV_SCALE = np.array([0.05, 0.05, 2.0, 2.0, *_K_WIND])
# priors that keep the problem regular in calm air (no wind: the drag coefficients are undetermined)
# and break the near-degeneracy of drag coefficient and wind speed (k W^2): coefficients within
# `wind_coefficient_spread` (relative) of the nominal hull's (WindCoefficients: areas measured on the
# hull, C_X, C_Y, C_N from the literature), wind and current within 10 and 1 m/s. Measured on a lake
# record (docs/sysid.md): with a 30 % or 5 % spread the estimate falls into a wrong basin (wind too
# weak, drag too high, Y_v/Y_vv/N_v absorbing the difference); with 1 % it finds the truth's basin.
ENV_PRIOR_STD = np.array([1.0, 1.0, 10.0, 10.0, *_K_WIND])  # the coefficients' x wind_coefficient_spread
ENV_LO = np.array([-1.0, -1.0, -30.0, -30.0, 0.0, 0.0, -1.0, -1.0])
ENV_HI = np.array([1.0, 1.0, 30.0, 30.0, 1.0, 1.0, 1.0, 1.0])
# The yaw-rate output's offset (`gyro_bias=True`): r_measured = r + b, one b per record and block of
# SolverOptions.gyro_offset_block_s (60 s), since a MEMS gyro's bias wanders (temperature). A gyro
# bias calibrated "at rest" is wrong by the yaw rate the boat had then (on a lake the wind turns a
# drifting boat: 0.02-0.06 rad/s on the lake records, 7-20 x the gyro noise), and the stack's records
# carry the estimator's bias error. Unmodelled, the offset contradicts the heading's slope, and the
# fit bends the yaw coefficients to share the difference (m33 1-2 % off at 4-5 sigma on lake records).
# One offset for a 10-min record whose bias walks (lotsen's simulator: 0.0002 rad/s/sqrt(s)) leaves
# the walk in r: per minute, the core coefficients' errors fell 0-13 % (docs/sysid.md).
# Scale, weak prior and bounds in rad/s.
GYRO_BIAS_SCALE = 0.01
GYRO_BIAS_PRIOR_STD = 0.2
GYRO_BIAS_LIMIT = 0.5


@dataclass
class ShootingGrid:
    """Integration steps of all shooting intervals of all segments, flattened.

    Step j integrates over h[j] with the input line U[j] = [u0, du] (lotsen.sysid.data.step_input_lines);
    reset[j] = 1 marks the first,
    zero-length step of an interval, which loads its node state. Node i starts at step
    node_step[i]; if it has a successor in its segment (has_next[i]) its interval ends after
    step end_step[i]. Measurement k (row meas_row[k] of segment meas_seg[k]) is reached after
    step meas_step[k] and belongs to node meas_node[k].
    """

    h: np.ndarray
    U: np.ndarray  # n_steps x 10
    reset: np.ndarray
    node_step: np.ndarray
    node_time: np.ndarray
    node_seg: np.ndarray
    has_next: np.ndarray
    end_step: np.ndarray
    meas_step: np.ndarray
    meas_node: np.ndarray
    meas_t: np.ndarray
    Y: np.ndarray  # n_meas x ny (NaN where not measured)
    output_names: tuple[str, ...]

    @property
    def n_steps(self) -> int:
        return len(self.h)

    @property
    def n_nodes(self) -> int:
        return len(self.node_step)


def build_grid(segments: Sequence[Segment], node_s: float = 2.0, h_max: float = 0.0625) -> ShootingGrid:
    """Shooting intervals of about `node_s` seconds, starting at measurement rows."""
    hs, Us, resets, node_step, node_time, node_seg, has_next, end_step = [], [], [], [], [], [], [], []
    meas_step, meas_node, meas_t, Ys = [], [], [], []
    names = segments[0].output_names
    offset = 0
    for si, seg in enumerate(segments):
        t, n = seg.t, len(seg.t)
        measured = np.isfinite(seg.outputs).any(axis=1)
        mrows = np.flatnonzero(measured)
        # node rows: measurement rows about node_s apart; no interval shorter than node_s / 2 at the end
        nodes = [int(mrows[0])]
        tm = t[mrows]
        while True:
            k = int(np.searchsorted(tm, t[nodes[-1]] + node_s - 1e-9))
            if k >= len(mrows) or t[mrows[-1]] - tm[k] < 0.5 * node_s:
                break
            nodes.append(int(mrows[k]))
        is_node = np.zeros(n, bool)
        is_node[nodes] = True
        dt = np.diff(t)
        m = np.zeros(n, int)
        m[:-1] = np.maximum(1, np.ceil(dt / h_max - 1e-9).astype(int))
        m[:-1][dt == 0] = 0
        count = m + is_node
        start = np.concatenate([[0], np.cumsum(count)[:-1]])
        total = int(count.sum())
        step_row = np.repeat(np.arange(n), count)
        j_in_row = np.arange(total) - start[step_row]
        rs = is_node[step_row] & (j_in_row == 0)
        hh = np.where(rs, 0.0, np.append(dt, 0.0)[step_row] / np.maximum(m[step_row], 1))
        hs.append(hh)
        # the reconstructed input's line over each step (held: the row's value; docs/sysid.md, "Data")
        sub = np.maximum(j_in_row - is_node[step_row], 0)
        Us.append(step_input_lines(seg, step_row, sub / np.maximum(m[step_row], 1)))
        resets.append(rs.astype(float))
        # the step after which row k's state is reached
        row_step = np.where(is_node, start, start - 1)
        node_idx = np.cumsum(is_node) - 1  # interval of each row
        base = len(node_step)
        for q, r in enumerate(nodes):
            node_step.append(offset + start[r])
            node_time.append(t[r])
            node_seg.append(si)
            nxt = q + 1 < len(nodes)
            has_next.append(nxt)
            end_step.append(offset + start[nodes[q + 1]] - 1 if nxt else -1)
        meas_step.append(offset + row_step[mrows])
        meas_node.append(base + node_idx[mrows])
        meas_t.append(t[mrows])
        Ys.append(seg.outputs[mrows])
        offset += total
    return ShootingGrid(np.concatenate(hs), np.vstack(Us), np.concatenate(resets), np.array(node_step, int),
                        np.array(node_time), np.array(node_seg, int), np.array(has_next, bool),
                        np.array(end_step, int), np.concatenate(meas_step), np.concatenate(meas_node),
                        np.concatenate(meas_t), np.vstack(Ys), names)


class ShootingSimulator:
    """All intervals simulated from their node states, CHUNK steps per compiled call
    (lotsen.sysid.kernels): the memory is bounded whatever the record length."""

    def __init__(self, grid: ShootingGrid, geometry: VesselGeometry = DEFAULT_GEOMETRY, lake: bool = False) -> None:
        self.g = grid
        self.k = step_kernels(geometry_tuple(geometry), lake=lake)
        # steps whose state is needed: measurements and interval ends
        ends = grid.end_step[grid.has_next]
        self.need = np.unique(np.concatenate([grid.meas_step, ends]))
        self._meas_pos = np.searchsorted(self.need, grid.meas_step)
        self._end_pos = np.searchsorted(self.need, ends)

    def run(self, theta: np.ndarray, nodes: np.ndarray, sens: bool) -> tuple[np.ndarray, ...]:
        """(X at measurements, X at interval ends[, S at measurements, S at ends]); S: n x nx x (nx + ntheta)."""
        g = self.g
        X_need, S_need = self.k.run_record(theta, g.h, g.U, g.reset, g.node_step, nodes, self.need, sens)
        out = (X_need[self._meas_pos], X_need[self._end_pos])
        if sens:
            out += (S_need[self._meas_pos], S_need[self._end_pos])
        return out


def initial_nodes(grid: ShootingGrid, segments: Sequence[Segment]) -> np.ndarray:
    """Node states from the data: positions, heading (unwrapped) and r interpolated, u and v from a
    local line fit of the positions (+-0.5 s) rotated into the body frame."""
    names = grid.output_names
    Y, tm = grid.Y, grid.meas_t
    X = np.zeros((grid.n_nodes, 6))
    seg_of_meas = grid.node_seg[grid.meas_node]
    for si in range(len(segments)):
        sel = seg_of_meas == si
        nsel = grid.node_seg == si
        tn = grid.node_time[nsel]
        t = tm[sel]
        y = Y[sel]
        cols: dict[str, np.ndarray] = {}
        for j, name in enumerate(names):
            ok = np.isfinite(y[:, j])
            if not ok.any():
                continue
            v = y[ok, j]
            if name == "psi":
                v = np.unwrap(v)
            cols[name] = np.interp(tn, t[ok], v)
            X[nsel, OUTPUT_STATE_INDEX[name]] = cols[name]
        if "psi" not in cols:
            X[nsel, 2] = 0.0
        if "u" not in cols or "v" not in cols:
            iN, iE = names.index("north"), names.index("east")
            ok = np.isfinite(y[:, iN]) & np.isfinite(y[:, iE])
            tt, yn, ye = t[ok], y[ok, iN], y[ok, iE]
            vel = np.zeros((len(tn), 2))
            for q, t0 in enumerate(tn):
                w = np.abs(tt - t0) <= 0.5
                if w.sum() >= 3:
                    vel[q, 0] = np.polyfit(tt[w] - t0, yn[w], 1)[0]
                    vel[q, 1] = np.polyfit(tt[w] - t0, ye[w], 1)[0]
            psi = X[nsel, 2]
            if "psi" not in cols:  # course over ground as the heading
                psi = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
                X[nsel, 2] = psi
            X[nsel, 3] = np.cos(psi) * vel[:, 0] + np.sin(psi) * vel[:, 1]
            X[nsel, 4] = -np.sin(psi) * vel[:, 0] + np.cos(psi) * vel[:, 1]
    return X


@dataclass
class _Lin:
    """The problem linearised at one point (scaled variables, unit-weight residuals)."""

    e: np.ndarray  # weighted measurement residuals, n_meas x ny (0 where not measured)
    c: np.ndarray  # scaled continuity defects, n_con x 6
    # the measurements' part of the normal equations (H_ss, H_sp, H_pp, g_s, g_p; the priors' are added
    # by `normal_blocks`), summed over the blocks of intervals in their order
    normal: tuple[np.ndarray, ...] | None = None
    calls: list[BlockCall] | None = None  # where each block was linearised (the sandwich's scores)
    Gx: np.ndarray | None = None  # n_con x 6 x nz  d c_i / d sigma_i
    Gp: np.ndarray | None = None  # n_con x 6 x nf
    pg: np.ndarray | None = None  # prior residuals of the gust factors (n_nodes), lake model
    pt: np.ndarray | None = None  # prior residuals of the free parameters (0 without a prior)
    jt: np.ndarray | None = None  # their derivatives d pt / d p (scaled)

    @property
    def measurement_cost(self) -> float:
        return 0.5 * float(np.sum(self.e * self.e))

    @property
    def cost(self) -> float:
        c = self.measurement_cost
        for p in (self.pg, self.pt):
            if p is not None:
                c += 0.5 * float(np.sum(p * p))
        return c

    @property
    def l1(self) -> float:
        return float(np.sum(np.abs(self.c)))


class MultipleShootingProblem:
    """Residuals, Jacobians and the structured KKT solves of one data set. The shooting intervals are
    linearised in blocks (lotsen.sysid.shooting_blocks) on `parallel`'s workers (lotsen.sysid.parallel;
    the built-in map: here, one after another)."""

    def __init__(self, records: Sequence[IdRecord], options: SolverOptions = SolverOptions(),
                 parallel: Map = SERIAL) -> None:
        node_s, gap_s, noise_std, geometry = options.node_s, options.gap_s, options.noise_std, options.geometry
        h_max, lake, gust_std = options.h_max, options.lake, options.gust_std
        wind_coefficient_spread = options.wind_coefficient_spread
        gyro_bias = lake if options.gyro_bias is None else options.gyro_bias
        segs: list[Segment] = []
        seg_record: list[int] = []
        for q, r in enumerate(records):
            check_record(r)
            pieces = split_segments(r, gap_s)
            segs.extend(pieces)
            seg_record.extend([q] * len(pieces))
        if not segs:
            raise EstimationError("no usable data: no gap-free piece with at least 8 measurement rows after every "
                                  "input column has a value")
        names = segs[0].output_names
        if any(s.output_names != names for s in segs):
            raise EstimationError("all data files must have the same output columns")
        self.segments = segs
        self.lake = lake
        self.gust_std = gust_std
        self.nz = 8 if lake else 6
        self.xscale = np.append(X_SCALE, [GUST_SCALE, GUST_SCALE]) if lake else X_SCALE
        self.prior_mean = np.concatenate([np.zeros(NTHETA), ENV_START]) if lake else np.zeros(NTHETA)
        env_std = ENV_PRIOR_STD.copy()
        env_std[4:] *= wind_coefficient_spread
        self.prior_std = np.concatenate([np.full(NTHETA, np.inf), env_std]) if lake else np.full(NTHETA, np.inf)
        # the kernel's parameters (vessel [+ environment]); measurement parameters follow them
        self.n_kernel = NTHETA_LAKE if lake else NTHETA
        # the yaw-rate offsets: per record, one per block of about options.gyro_offset_block_s
        self.n_records = len(records)
        starts = [float(r.t[0]) for r in records]
        blocks = [max(1, int(round(r.duration_s / options.gyro_offset_block_s))) if options.gyro_offset_block_s > 0
                  else 1 for r in records]
        self.bias_record = np.repeat(np.arange(len(records)), blocks) if gyro_bias and "r" in names \
            else np.zeros(0, int)
        self.n_bias = len(self.bias_record)
        self._bias_slots = (np.array(starts), np.array([max(r.duration_s / b, 1e-9) for r, b in zip(records, blocks)]),
                            np.concatenate([[0], np.cumsum(blocks)[:-1]]).astype(int), np.array(blocks))
        self.prior_mean = np.concatenate([self.prior_mean, np.zeros(self.n_bias)])
        self.prior_std = np.concatenate([self.prior_std, np.full(self.n_bias, GYRO_BIAS_PRIOR_STD)])
        self.grid = build_grid(segs, node_s, h_max)
        self.seg_record = np.array(seg_record, int)
        self.geometry, self.parallel = geometry, parallel
        noise = dict(DEFAULT_NOISE_STD)
        noise.update(noise_std or {})
        self.noise = {n: float(noise[n]) for n in names}
        self.names = names
        self.out_idx = [OUTPUT_STATE_INDEX[n] for n in names]
        self.psi_col = names.index("psi") if "psi" in names else None
        self.mask = np.isfinite(self.grid.Y)
        self.Y = np.where(self.mask, self.grid.Y, 0.0)
        g = self.grid
        self.con = np.flatnonzero(g.has_next)  # node i with a successor i + 1
        self.n_nodes = g.n_nodes
        self.n_con = len(self.con)
        self.meas_bounds = np.searchsorted(g.meas_node, np.arange(self.n_nodes + 1))
        self.meas_bias = self.bias_slot(self.seg_record[g.node_seg[g.meas_node]], g.meas_t)
        self.r_col = names.index("r") if "r" in names else None
        self._pattern_cache: dict = {}
        self.blocks = [Held(self._block(n0, n1)) for n0, n1 in cut_blocks(g.node_step, g.n_steps)]
        # the last linearisation with sensitivities and where it was made (point, free parameters, noise):
        # a search that ends where the next one starts (the misfit check, the final covariance) asks for
        # it again
        self._last_sens: tuple[tuple, _Lin] | None = None

    @property
    def sim(self) -> ShootingSimulator:
        """The whole grid in one simulator, in this process (the design's trajectory)."""
        if "sim" not in self._pattern_cache:
            self._pattern_cache["sim"] = ShootingSimulator(self.grid, self.geometry, self.lake)
        return self._pattern_cache["sim"]

    def _block(self, n0: int, n1: int) -> ShootingBlock:
        """Nodes [n0, n1) with their steps and rows (lotsen.sysid.shooting_blocks.ShootingBlock)."""
        g = self.grid
        s0 = int(g.node_step[n0])
        s1 = int(g.node_step[n1]) if n1 < g.n_nodes else g.n_steps
        m0, m1 = int(self.meas_bounds[n0]), int(self.meas_bounds[n1])
        with_next = np.flatnonzero(g.has_next[n0:n1]) + n0
        meas, ends = g.meas_step[m0:m1] - s0, g.end_step[with_next] - s0
        need = np.unique(np.concatenate([meas, ends]))
        return ShootingBlock(geometry_tuple(self.geometry), self.lake, n0, n1, g.h[s0:s1], g.U[s0:s1],
                             g.reset[s0:s1], g.node_step[n0:n1] - s0, need, np.searchsorted(need, meas),
                             np.searchsorted(need, ends), self.Y[m0:m1], self.mask[m0:m1],
                             self.meas_bounds[n0:n1 + 1] - m0, self.meas_bias[m0:m1],
                             tuple(self.out_idx), self.psi_col, self.r_col)

    def bias_slot(self, record: np.ndarray, t: np.ndarray) -> np.ndarray:
        """The yaw-rate offset (its index) of record `record` at time `t` (per element)."""
        t0, length, first, n = self._bias_slots
        k = np.floor((np.asarray(t, float) - t0[record]) / length[record]).astype(int)
        return first[record] + np.clip(k, 0, n[record] - 1)

    def initial_gyro_bias(self) -> np.ndarray:
        """Per record, the yaw-rate offset from the data alone: (integral of the measured r - the
        heading's change) / duration over its segments. A start for the estimate, no more."""
        b = np.zeros(self.n_records)
        if not self.n_bias or self.psi_col is None:
            return b
        num, den = np.zeros(self.n_records), np.zeros(self.n_records)
        for seg, q in zip(self.segments, self.seg_record):
            ip, ir = self.psi_col, self.r_col
            okp, okr = np.isfinite(seg.outputs[:, ip]), np.isfinite(seg.outputs[:, ir])
            if okp.sum() < 2 or okr.sum() < 2:
                continue
            tp, psi = seg.t[okp], np.unwrap(seg.outputs[okp, ip])
            tr, r = seg.t[okr], seg.outputs[okr, ir]
            t0, t1 = max(tp[0], tr[0]), min(tp[-1], tr[-1])
            if t1 - t0 <= 0:
                continue
            w = (tr >= t0) & (tr <= t1)
            if w.sum() < 2:
                continue
            int_r = float(np.sum(0.5 * (r[w][1:] + r[w][:-1]) * np.diff(tr[w])))
            dpsi = float(np.interp(tr[w][-1], tp, psi) - np.interp(tr[w][0], tp, psi))
            num[q] += int_r - dpsi
            den[q] += float(tr[w][-1] - tr[w][0])
        ok = den > 0
        b[ok] = num[ok] / den[ok]
        return np.clip(b, -GYRO_BIAS_LIMIT, GYRO_BIAS_LIMIT)

    @property
    def sqrt_w(self) -> np.ndarray:
        return np.array([1.0 / self.noise[n] for n in self.names])

    @property
    def n_measurements(self) -> int:
        return int(self.mask.sum())

    def linearise(self, theta: np.ndarray, nodes: np.ndarray, free: np.ndarray, tscale: np.ndarray,
                  sens: bool) -> _Lin:
        """The problem linearised at (theta, nodes) for the `free` parameters (scaled by `tscale`), with the
        Jacobians and normal equations when `sens`. Not to be changed by the caller: the last one with
        sensitivities is kept and handed out again for the same point and noise."""
        at = (theta.tobytes(), nodes.shape, nodes.tobytes(), free.tobytes(), tscale.tobytes(),
              tuple(self.noise.items()))
        if self._last_sens is not None and self._last_sens[0] == at:
            return self._last_sens[1]
        nk = self.n_kernel
        fk = free[free < nk]  # the kernel's parameters; the measurement parameters (gyro offsets) follow them
        fb = free[free >= nk] - nk
        calls = [BlockCall(theta[:nk], theta[nk:nk + self.n_bias], nodes[b.value.n0:b.value.n1], self.sqrt_w, sens,
                           fk, fb, tscale[fk], tscale[nk + fb], self.xscale, X_SCALE) for b in self.blocks]
        parts = map_held(self.parallel, linearise_block, self.blocks, calls)
        e = np.concatenate([p.e for p in parts])
        Xe = np.concatenate([p.X_end for p in parts])
        c = (Xe[:, :6] - nodes[self.con + 1, :6]) / X_SCALE
        lin = _Lin(e, c)
        if not (np.all(np.isfinite(e)) and np.all(np.isfinite(c))):
            lin.e = np.full_like(e, np.inf)
            return lin
        jt = tscale[free] / self.prior_std[free]
        if np.any(jt > 0):
            lin.pt = (theta[free] - self.prior_mean[free]) / self.prior_std[free]
            lin.jt = jt
        if self.lake:  # along: 1 +- gust_std; across: 0 +- gust_std (both relative to the mean wind)
            lin.pg = np.column_stack([nodes[:, 6] - 1.0, nodes[:, 7]]) / self.gust_std
        if sens:
            lin.Gx = np.concatenate([p.Gx for p in parts])
            lin.Gp = np.concatenate([p.Gp for p in parts])
            lin.normal = (np.concatenate([p.Hss for p in parts]), np.concatenate([p.Hsp for p in parts]),
                          ordered_sum(p.Hpp for p in parts), np.concatenate([p.gs for p in parts]),
                          ordered_sum(p.gp for p in parts))
            lin.calls = calls
            self._last_sens = (at, lin)
        return lin

    # -- the structured KKT system -------------------------------------------------------------
    def normal_blocks(self, lin: _Lin) -> tuple[np.ndarray, ...]:
        """H_ss (n_nodes x 6 x 6), H_sp (n_nodes x 6 x nf), H_pp, g_s (n_nodes x 6), g_p: the measurements'
        (from the linearisation with sensitivities) and the priors'."""
        if lin.normal is None:
            raise ValueError("normal_blocks needs a linearisation with sensitivities")
        Hss, Hsp, Hpp, gs, gp = (a.copy() for a in lin.normal)
        if lin.pg is not None:  # the gust factors' prior: independent per interval
            jg = self.xscale[6] / self.gust_std
            for q in (6, 7):
                Hss[:, q, q] += jg * jg
                gs[:, q] += jg * lin.pg[:, q - 6]
        if lin.pt is not None:
            Hpp[np.diag_indices_from(Hpp)] += lin.jt ** 2
            gp += lin.jt * lin.pt
        return Hss, Hsp, Hpp, gs, gp

    def _pattern(self) -> tuple[np.ndarray, np.ndarray]:
        """Row/column indices of A = [[H_ss, C_s^T], [C_s, 0]] (fixed for the problem)."""
        if "A" in self._pattern_cache:
            return self._pattern_cache["A"]
        N, nc, nz = self.n_nodes, self.n_con, self.nz
        ns = nz * N
        i6 = np.arange(6)
        iz = np.arange(nz)
        rr, cc = [], []
        # H_ss blocks
        base = (np.arange(N) * nz)[:, None, None]
        rr.append((base + iz[None, :, None] + 0 * iz[None, None, :]).ravel())
        cc.append((base + 0 * iz[None, :, None] + iz[None, None, :]).ravel())
        # C_s: constraint q (rows ns + 6q ..) -> node con[q] (G_x, 6 x nz) and node con[q] + 1 (-I on its state)
        rq = (ns + np.arange(nc) * 6)[:, None, None]
        cq = (self.con * nz)[:, None, None]
        Gr = (rq + i6[None, :, None] + 0 * iz[None, None, :]).ravel()
        Gc = (cq + 0 * i6[None, :, None] + iz[None, None, :]).ravel()
        Ir = (ns + np.arange(nc)[:, None] * 6 + i6[None, :]).ravel()
        Ic = ((self.con + 1)[:, None] * nz + i6[None, :]).ravel()
        rr += [Gr, Gc, Ir, Ic]
        cc += [Gc, Gr, Ic, Ir]
        self._pattern_cache["A"] = (np.concatenate(rr), np.concatenate(cc))
        return self._pattern_cache["A"]

    def _csc_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Where A's entries (in `_pattern`'s order) stand in its CSC form, and the form's row indices and
        column pointers: fixed for the problem, found once by converting the entries' positions. None if
        an entry repeated (the conversion would sum, not move, it)."""
        if "csc" not in self._pattern_cache:
            rows, cols = self._pattern()
            n = self.nz * self.n_nodes + 6 * self.n_con
            pos = sp.csc_matrix((np.arange(len(rows), dtype=float), (rows, cols)), shape=(n, n))
            self._pattern_cache["csc"] = (pos.data.astype(np.intp), pos.indices, pos.indptr) \
                if pos.nnz == len(rows) else None
        return self._pattern_cache["csc"]

    def factor_A(self, Hss: np.ndarray, Gx: np.ndarray, Ds: np.ndarray, mu: float):  # type: ignore[no-untyped-def]
        H = Hss.copy()
        idx = np.arange(self.nz)
        H[:, idx, idx] += mu * Ds
        nc = self.n_con
        data = np.concatenate([H.ravel(), Gx.ravel(), Gx.ravel(), -np.ones(6 * nc), -np.ones(6 * nc)])
        n = self.nz * self.n_nodes + 6 * nc
        layout = self._csc_layout()
        if layout is None:
            A = sp.csc_matrix((data, self._pattern()), shape=(n, n))
        else:  # the same matrix as converting the entries each time (their values moved, not summed)
            order, indices, indptr = layout
            A = sp.csc_matrix((data[order], indices, indptr), shape=(n, n))
        return spla.splu(A, permc_spec="COLAMD", options={"SymmetricMode": False})

    def coupling(self, Hsp: np.ndarray, Gp: np.ndarray) -> np.ndarray:
        """B: the node states' and the continuity constraints' coupling to the parameters."""
        nf = Hsp.shape[2]
        return np.vstack([Hsp.reshape(self.n_nodes * self.nz, nf), Gp.reshape(self.n_con * 6, nf)])

    def reduced(self, lu, Hsp: np.ndarray, Gp: np.ndarray, Hpp: np.ndarray, rhs_w: np.ndarray | None,
                rhs_p: np.ndarray | None) -> tuple[np.ndarray, ...]:
        """F = H_pp - B^T A^-1 B and, with right-hand sides, the eliminated rhs and A^-1 (B, r_w)."""
        nf = Hpp.shape[0]
        B = self.coupling(Hsp, Gp)
        R = B if rhs_w is None else np.column_stack([B, rhs_w])
        Z = lu.solve(R)
        AinvB = Z[:, :nf]
        F = Hpp - B.T @ AinvB
        F = 0.5 * (F + F.T)
        if rhs_w is None:
            return F, AinvB
        r = rhs_p - B.T @ Z[:, nf]
        return F, AinvB, Z[:, nf], r


@dataclass
class MultipleShootingResult:
    """Extra information of a multiple-shooting estimate (kept in IdentificationResult.details)."""

    nodes: np.ndarray
    node_time: np.ndarray
    noise_std: dict[str, float]
    continuity_max: float
    n_nodes: int
    n_steps: int
    passes: int
    # per output: the normalised autocorrelation of its residuals at lags 1..K measurements
    residual_autocorr: dict[str, np.ndarray] | None = None
    environment: "EnvironmentEstimate | None" = None  # the lake model's current, wind and gusts
    # the yaw-rate output's offsets (rad/s), if estimated: per record and block of
    # SolverOptions.gyro_offset_block_s in time order, with the record (index) of each
    gyro_bias: np.ndarray | None = None
    gyro_bias_std: np.ndarray | None = None
    gyro_bias_record: np.ndarray | None = None
    # lake model: how far each coefficient moved, in its own sigma, when the gusts were cut into
    # longer intervals (estimate_lake_averaged); already part of the covariance
    gust_interval_shift: dict[str, float] | None = None
    fixed_test: "FixedValueTest | None" = None  # do the fixed coefficients agree with the record?
    # records of interval means: how far each coefficient moved, in its own sigma before the spread was
    # added, with the other reconstruction of the inputs within their intervals (estimators.reconstruction_spread)
    reconstruction_shift: dict[str, float] | None = None


@dataclass
class _Factored:
    """The damped KKT matrix of one linearisation and damping, factorised: A's LU, the coupling B, the
    reduced matrix F = H_pp + mu D_p - B^T A^-1 B and A^-1 B. A step's trials at one damping (the bounds'
    active set, the second-order correction) solve with it again instead of factorising anew."""

    lu: object
    B: np.ndarray
    F: np.ndarray
    AinvB: np.ndarray


def _factor(prob: MultipleShootingProblem, lin: _Lin, blocks: tuple, Ds: np.ndarray, Dp: np.ndarray,
            mu: float) -> _Factored:
    Hss, Hsp, Hpp = blocks[:3]
    lu = prob.factor_A(Hss, lin.Gx, Ds, mu)
    F, AinvB = prob.reduced(lu, Hsp, lin.Gp, Hpp + mu * np.diag(Dp), None, None)
    return _Factored(lu, prob.coupling(Hsp, lin.Gp), F, AinvB)


def _solve_step(prob: MultipleShootingProblem, fac: _Factored, gs: np.ndarray, gp: np.ndarray, c: np.ndarray,
                active: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The damped Gauss-Newton step for the gradients (gs, gp) and the defects c; `active` (per free
    parameter) holds those at a bound fixed."""
    rhs_w = np.concatenate([-gs.ravel(), -c.ravel()])
    Ainv_rw = fac.lu.solve(rhs_w)  # type: ignore[attr-defined]
    r = -gp - fac.B.T @ Ainv_rw
    F, AinvB = fac.F, fac.AinvB
    nf = len(gp)
    if nf:
        keep = np.ones(nf, bool) if active is None else ~active
        dp = np.zeros(nf)
        if keep.any():
            Fk, rk = F[np.ix_(keep, keep)], r[keep]
            try:
                dp[keep] = np.linalg.solve(Fk, rk)
            except np.linalg.LinAlgError:
                dp[keep] = np.linalg.lstsq(Fk, rk, rcond=None)[0]
    else:
        dp = np.zeros(0)
    w = Ainv_rw - AinvB @ dp
    ns = prob.nz * prob.n_nodes
    ds = w[:ns].reshape(prob.n_nodes, prob.nz)
    lam = w[ns:]
    return ds, dp, lam


def _quad(prob: MultipleShootingProblem, blocks: tuple, ds: np.ndarray, dp: np.ndarray) -> float:
    """d^T H d for the Gauss-Newton Hessian blocks."""
    Hss, Hsp, Hpp, _, _ = blocks
    q = np.einsum("ki,kil,kl->", ds, Hss, ds)
    q += 2.0 * np.einsum("ki,kil,l->", ds, Hsp, dp)
    q += dp @ Hpp @ dp
    return float(q)


@dataclass(frozen=True)
class ShootingStart:
    """Where a multiple-shooting search starts beyond the coefficients (None: from the data): the node
    states, the lake model's environment (ENV_NAMES order) and the yaw-rate offsets (per record and block)."""

    nodes: np.ndarray | None = None
    environment: Sequence[float] | None = None
    gyro_bias: Sequence[float] | None = None


def estimate_multiple_shooting(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                               fixed: Mapping[str, float] | None = None, options: SolverOptions = SolverOptions(),
                               start: ShootingStart = ShootingStart(),
                               progress: Callable[[int, float], None] | None = None,
                               problem: MultipleShootingProblem | None = None,
                               parallel: Map = SERIAL) -> IdentificationResult:
    """Multiple-shooting Gauss-Newton estimate of the free parameters (module docstring).

    `fixed` maps parameter names to known values (must include one of SCALE_GROUP). With
    `estimate_noise` (default) the noise std of each output is re-estimated from its residuals and
    the estimate refined once with those weights; otherwise `noise_std` (or the defaults) is used and
    the covariance is scaled by max(1, s^2). `max_iterations` is per pass; `total_iterations`, when
    given, caps both passes together (the refinement gets what the first pass left).

    `lake`: estimate with the parameters a constant earth-frame current, the wind (earth-frame air
    velocity and drag coefficients, lotsen.model.environment.apparent_wind_force) and a gust factor
    per shooting interval (prior 1 +- `gust_std`); the covariance is then also inflated for the
    residuals' autocorrelation (`autocorrelation_factor`). Results in `details.environment`.

    `gyro_bias` (default: with `lake`): estimate an offset of the yaw-rate output per record and block
    of `gyro_offset_block_s` (r_measured = r + b; GYRO_BIAS_SCALE), started from `gyro_bias0` or from
    the data (`MultipleShootingProblem.initial_gyro_bias`). Results in `details.gyro_bias`.

    `parallel`: the map the shooting intervals' blocks run on (lotsen.sysid.parallel), unless `problem`
    is given (then its own).
    """
    prob, search, theta, nodes, total_it, converged, passes = _shooting_search(records, theta0, fixed, options, start,
                                                                              progress, problem, parallel)
    free, tscale, estimate_noise = search.free, search.tscale, options.estimate_noise
    lin = prob.linearise(theta, nodes, free, tscale, True)
    blocks = prob.normal_blocks(lin)
    F_rel = _fisher_from(prob, lin, blocks)
    cost = 2.0 * lin.measurement_cost  # V = sum of squared weighted residuals
    m = prob.n_measurements
    p_eff = len(free) + 6 * len(prob.segments) + (prob.n_nodes if prob.lake else 0)
    # the noise factor on the effective number of independent residuals (sum_j m_j / tau_j)
    s2 = float(np.sum(np.sum(lin.e ** 2, axis=0) * _weight_correlation_times(prob, lin))) / max(m - p_eff, 1)
    factor = s2 if estimate_noise else max(1.0, s2)
    # honest intervals for correlated residuals (gusts, a model that is not the hull's): the sandwich
    # covariance F^-1 M F^-1, the score's covariance M estimated from the residuals (Newey-West),
    # expressed as the equivalent information. With white residuals (every output's correlation time
    # below WHITE_CORRELATION_TIME) s^2 F^-1 is exact and the sandwich only adds its own sampling noise
    # (0.87-1.21 of the bound on 60-s records of a boat equal to its model)
    if prob.lake or float(np.max(residual_correlation_times(prob, lin))) > WHITE_CORRELATION_TIME:
        F_rel, factor = sandwich_information(prob, lin, blocks, F_rel), 1.0
    res = _result(prob, search, theta, nodes, _Fit(F_rel, factor, cost, s2, total_it, converged, passes, lin))
    if options.test_fixed:
        res.details.fixed_test = fixed_value_test(prob, theta, nodes, free, tscale, options.test_fixed)
    return res


def shooting_point(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                   fixed: Mapping[str, float] | None = None, options: SolverOptions = SolverOptions(),
                   start: ShootingStart = ShootingStart(), progress: Callable[[int, float], None] | None = None,
                   parallel: Map = SERIAL) -> tuple[VesselParameters, ShootingStart]:
    """The point `estimate_multiple_shooting` ends at, without its intervals: the coefficients, and where
    a next search starts from there (the node states, the lake model's environment, the yaw-rate
    offsets). For a stage whose answer only starts the next one (the lake's steady-wind stages, the
    reconstruction spread's one step): neither the covariance (on a lake the sandwich's second simulation
    of every block) nor the sensitivities at the last point are computed."""
    prob, _, theta, nodes, _, _, _ = _shooting_search(records, theta0, fixed, options, start, progress, None, parallel)
    nk = prob.n_kernel
    environment = theta[NTHETA:nk].copy() if prob.lake else None
    bias = theta[nk:nk + prob.n_bias].copy() if prob.n_bias else None
    return VesselParameters.from_vector(theta[:NTHETA]), ShootingStart(nodes, environment, bias)


def _shooting_search(records: Sequence[IdRecord], theta0: VesselParameters, fixed: Mapping[str, float] | None,
                     options: SolverOptions, start: ShootingStart, progress: Callable[[int, float], None] | None,
                     problem: MultipleShootingProblem | None, parallel: Map
                     ) -> tuple[MultipleShootingProblem, _Search, np.ndarray, np.ndarray, int, bool, int]:
    """The search of `estimate_multiple_shooting` (its docstring): the problem, the search, where it ended
    (the parameters with the environment and the offsets, the node states), the iterations, whether it
    converged and the noise passes run."""
    max_iterations, total_iterations, tol = options.max_iterations, options.total_iterations, options.tol
    estimate_noise, misfit_check = options.estimate_noise, options.misfit_check
    nodes0, env0, gyro_bias0 = start.nodes, start.environment, start.gyro_bias
    fixed = with_terms_off(dict(fixed or {}), theta0, options.terms)  # optional model terms off unless in `terms`
    unknown = [n for n in fixed if n not in NAMES]
    if unknown:
        raise LotsenError(f"cannot fix unknown parameter(s) {', '.join(unknown)} (known: {', '.join(NAMES)})")
    check_scale_fixed(fixed)
    prob = problem
    if prob is None:
        prob = MultipleShootingProblem(records, options, parallel)
        check_excitation(prob.segments)
    theta, free, free_names, tscale = starting_point(theta0, fixed)
    lo, hi = parameter_bounds()
    nodes = initial_nodes(prob.grid, prob.segments) if nodes0 is None else np.array(nodes0, float)
    if prob.lake:
        theta = np.concatenate([theta, ENV_START if env0 is None else np.asarray(env0, float)])
        free = np.concatenate([free, NTHETA + np.arange(len(ENV_NAMES))])
        tscale = np.concatenate([tscale, ENV_SCALE])
        lo, hi = np.concatenate([lo, ENV_LO]), np.concatenate([hi, ENV_HI])
        if nodes.shape[1] == 6:
            nodes = np.column_stack([nodes, np.ones(len(nodes)), np.zeros(len(nodes))])
    if prob.n_bias:
        if gyro_bias0 is None:  # every block of a record from the record's offset
            b0 = prob.initial_gyro_bias()[prob.bias_record]
        else:
            b0 = np.asarray(gyro_bias0, float)
        if nodes0 is None:  # the nodes' r from the measured r, less its offset
            nodes[:, 5] -= b0[prob.bias_slot(prob.seg_record[prob.grid.node_seg], prob.grid.node_time)]
        theta = np.concatenate([theta, b0])
        free = np.concatenate([free, prob.n_kernel + np.arange(prob.n_bias)])
        tscale = np.concatenate([tscale, np.full(prob.n_bias, GYRO_BIAS_SCALE)])
        lo = np.concatenate([lo, np.full(prob.n_bias, -GYRO_BIAS_LIMIT)])
        hi = np.concatenate([hi, np.full(prob.n_bias, GYRO_BIAS_LIMIT)])
    history: list[float] = []
    search = _Search(free, free_names, tscale, lo, hi, tol, history, progress, fixed)
    total_it = 0
    converged = False
    passes = 2 if estimate_noise else 1
    misfit = False
    for pass_no in range(passes):
        budget = max_iterations if total_iterations is None else min(max_iterations, total_iterations - total_it)
        if budget <= 0:
            break
        if misfit_check and pass_no == 0:
            # a model that cannot explain the record crawls for a hundred iterations towards no physical
            # answer: after `misfit_check` iterations with the track's errors still correlated over a
            # second (the verdict's own test), stop; the estimate is then judged (refused as physical,
            # perhaps predictive) without the rest of the work
            theta, nodes, it, converged = _gauss_newton(prob, search, theta, nodes, min(misfit_check, budget),
                                                        total_it)
            total_it += it
            budget -= it
            ac = residual_autocorr(prob.linearise(theta, nodes, free, tscale, False).e, prob.mask, prob.names)
            vals = [float(ac[n][7]) for n in ("north", "east") if n in ac and len(ac[n]) >= 8]
            misfit = bool(vals) and float(np.mean(vals)) > MISFIT_TRACK_AUTOCORR
            if misfit:
                # converged or stalled or crawling, the model does not explain the track: no physical
                # answer will come of more iterations (a record it explains goes on)
                converged = False
                break
            if converged and passes == 1:
                break
        if not (misfit_check and pass_no == 0 and converged) and budget > 0:
            theta, nodes, it, converged = _gauss_newton(prob, search, theta, nodes, budget, total_it)
            total_it += it
        if pass_no + 1 < passes:
            lin = prob.linearise(theta, nodes, free, tscale, False)
            e2 = np.sum(lin.e ** 2, axis=0)
            m = prob.mask.sum(axis=0)
            p_eff = len(free) + 6 * len(prob.segments) + (prob.n_nodes if prob.lake else 0)
            dof = max(1.0 - p_eff / max(prob.n_measurements, 1), 0.05)
            changed = False
            taus = _weight_correlation_times(prob, lin)
            for j, n in enumerate(prob.names):
                if m[j] > 0:
                    s2 = e2[j] / (m[j] * dof) * taus[j]
                    if abs(s2 - 1.0) > 0.02:
                        changed = True
                    prob.noise[n] *= math.sqrt(max(s2, 1e-12))
            if not changed:
                break
    return prob, search, theta, nodes, total_it, converged, passes


def _fisher_from(prob: MultipleShootingProblem, lin: _Lin, blocks: tuple) -> np.ndarray:
    Hss, Hsp, Hpp, _, _ = blocks
    if Hpp.shape[0] == 0:
        return np.zeros((0, 0))
    Ds = np.maximum(np.einsum("kii->ki", Hss), 0.0)
    lu = prob.factor_A(Hss, lin.Gx, Ds, 1e-12)  # a whisper of damping: motionless data keep A regular
    F, _ = prob.reduced(lu, Hsp, lin.Gp, Hpp, None, None)
    return F


def sandwich_information(prob: MultipleShootingProblem, lin: _Lin, blocks: tuple, F: np.ndarray) -> np.ndarray:
    """The information equivalent to the sandwich covariance F^-1 M F^-1 (scaled parameters).

    The least-squares covariance F^-1 assumes white residuals of the weighted noise level. Gusts a
    piecewise-constant factor does not follow, the wind direction's wander and a wandering gyro bias
    leave residuals correlated over seconds: F^-1 is then too small, by a different factor for
    every parameter direction. Each measurement row k contributes the score s_k = J_k^T e_k, with
    J_k = d e_k / d p the residuals' total derivative, every node state eliminated under continuity
    (d s / d p = -A^-1 B, as in F = H_pp - B^T A^-1 B). The score's covariance is estimated from the
    residuals themselves, with the lagged products Bartlett-weighted (Newey & West 1987; within each
    segment): M_data = sum_L w_L (G_L + G_L^T), G_L = sum_k s_k s_{k+L}^T, w_L = 1 - L / (K + 1).
    The bandwidth K is twice the longest residual correlation time (`residual_correlation_times`;
    gusts 3-10 s, a wandering gyro bias longer), at most a tenth of the rows: the scores sum to zero
    at the optimum, so a bandwidth near the record's length shrinks M towards zero. The priors keep
    their own information: M = F - F_data + M_data, with F_data = sum_k J_k^T J_k the information of
    the measurements; white residuals at the weighted noise level give M_data ~ F_data and the
    sandwich reduces to F^-1.
    """
    if blocks[2].shape[0] == 0:
        return F
    M = score_covariance(prob, lin, blocks, F)
    try:
        Finv = np.linalg.inv(F)
    except np.linalg.LinAlgError:
        Finv = np.linalg.pinv(F)
    cov = Finv @ M @ Finv
    cov = 0.5 * (cov + cov.T)
    try:
        out = np.linalg.inv(cov)
    except np.linalg.LinAlgError:
        out = np.linalg.pinv(cov)
    return 0.5 * (out + out.T)


def score_covariance(prob: MultipleShootingProblem, lin: _Lin, blocks: tuple, F: np.ndarray) -> np.ndarray:
    """M of `sandwich_information`: the covariance of the score, estimated from the residuals
    (Newey-West over the measurement rows, every node state eliminated) plus the priors' information."""
    Hss, Hsp, Hpp, _, _ = blocks
    nf = Hpp.shape[0]
    Ds = np.maximum(np.einsum("kii->ki", Hss), 0.0)
    lu = prob.factor_A(Hss, lin.Gx, Ds, 1e-12)
    _, AinvB = prob.reduced(lu, Hsp, lin.Gp, Hpp, None, None)
    g = prob.grid
    dsdp = -AinvB[: prob.nz * prob.n_nodes].reshape(prob.n_nodes, prob.nz, nf)
    parts = map_held(prob.parallel, block_scores, prob.blocks,
                     [(call, dsdp[b.value.n0:b.value.n1]) for b, call in zip(prob.blocks, lin.calls or [])])
    S = np.concatenate([p[0] for p in parts])
    F_data = ordered_sum(p[1] for p in parts)
    seg = g.node_seg[g.meas_node]
    tau = float(np.max(residual_correlation_times(prob, lin)))
    L = int(max(1, min(round(2.0 * tau), len(S) // 10)))
    M = S.T @ S
    for lag in range(1, L + 1):
        same = (seg[lag:] == seg[:-lag]).astype(float)
        G = (S[:-lag] * same[:, None]).T @ S[lag:]
        M += (1.0 - lag / (L + 1.0)) * (G + G.T)
    M = F - F_data + M
    return 0.5 * (M + M.T)


#: `misfit_check`: the track's lag-1 s residual autocorrelation above which a model that has not
#: converged is taken not to explain the record (lotsen.sysid.judge.MAX_TRACK_AUTOCORR: 0.5)
MISFIT_TRACK_AUTOCORR = 0.5
#: residuals whose correlation time (in samples) stays below this are white (sensor noise alone)
WHITE_CORRELATION_TIME = 1.5
#: a fixed coefficient whose robust score statistic exceeds this chi-square quantile contradicts the data
FIXED_TEST_LEVEL = 0.999


@dataclass
class FixedValueTest:
    """Whether the coefficients held at given values agree with the record (a robust score test)."""

    tested: tuple[str, ...]
    statistic: float  # the Lagrange-multiplier statistic, chi-square with len(tested) degrees of freedom
    threshold: float  # its FIXED_TEST_LEVEL quantile
    z: dict[str, float]  # per coefficient: its efficient score in its own standard deviations

    @property
    def contradicted(self) -> list[str]:
        """The tested coefficients the data pull away from their fixed values (|z| > 3), worst first
        (all of them when only the joint statistic exceeds its threshold)."""
        if self.statistic <= self.threshold:
            return []
        named = sorted((n for n in self.tested if abs(self.z[n]) > 3.0), key=lambda n: -abs(self.z[n]))
        return named or sorted(self.tested, key=lambda n: -abs(self.z[n]))


def fixed_value_test(prob: MultipleShootingProblem, theta: np.ndarray, nodes: np.ndarray, free: np.ndarray,
                     tscale: np.ndarray, tested: Sequence[str]) -> FixedValueTest | None:
    """The robust score (Lagrange-multiplier) test of the coefficients `tested`, held fixed in an
    estimate that ended at (`theta`, `nodes`) with `free` estimated. At that estimate the gradient of
    the cost along the free coefficients is zero; along a fixed one it is the data's pull away from
    the fixed value. Its efficient part (the free ones' adjustment removed) has the covariance
    B M B^T with M = s^2 F the score's covariance under the null;
    LM = g^T (B M B^T)^-1 g is chi-square with one degree per tested coefficient when the fixed values
    are right. A value fixed wrongly (a default 10-30 % off a hull's) is then misfit, not a confident
    answer: the free ones bent to make up for it."""
    idx = np.array([NAMES.index(n) for n in tested if n in NAMES], dtype=int)
    if not len(idx):
        return None
    from scipy.stats import chi2

    nk = prob.n_kernel
    aug = np.concatenate([free, idx])
    order = np.concatenate([aug[aug < nk], aug[aug >= nk]])  # the order of linearise's columns
    lin = prob.linearise(theta, nodes, aug, tscale, True)
    blocks = prob.normal_blocks(lin)
    Hss, Hsp, Hpp, gs, gp = blocks
    Ds = np.maximum(np.einsum("kii->ki", Hss), 0.0)
    lu = prob.factor_A(Hss, lin.Gx, Ds, 1e-12)
    rhs_w = np.concatenate([-gs.ravel(), -lin.c.ravel()])
    F, _, _, r = prob.reduced(lu, Hsp, lin.Gp, Hpp, rhs_w, -gp)
    # the score's covariance under the null: right fixed values and a model that explains the record,
    # i.e. white residuals at the (re-estimated) noise level, so M = s^2 F. (The sandwich's M would
    # count the misfit that wrong fixed values cause as noise and hide them: 2.7 sigma each for four
    # coefficients 7-15 % off; a record whose residuals are correlated anyway is refused as physical
    # for that by the verdict's track test.)
    s2 = max(float(np.sum(lin.e ** 2)) / max(prob.n_measurements - len(order), 1), 1e-12)
    M = s2 * F
    t = np.isin(order, idx)
    p = ~t
    try:
        K = F[np.ix_(t, p)] @ np.linalg.inv(F[np.ix_(p, p)])
    except np.linalg.LinAlgError:
        K = F[np.ix_(t, p)] @ np.linalg.pinv(F[np.ix_(p, p)])
    B = np.zeros((int(t.sum()), len(order)))
    B[:, np.flatnonzero(t)] = np.eye(int(t.sum()))
    B[:, np.flatnonzero(p)] = -K
    g = B @ r
    V = B @ M @ B.T
    V = 0.5 * (V + V.T)
    try:
        lm = float(g @ np.linalg.solve(V, g))
    except np.linalg.LinAlgError:
        lm = float(g @ np.linalg.pinv(V) @ g)
    names = [NAMES[i] for i in order[t]]
    z = {n: float(g[j] / math.sqrt(V[j, j])) if V[j, j] > 0 else 0.0 for j, n in enumerate(names)}
    return FixedValueTest(tuple(names), lm, float(chi2.ppf(FIXED_TEST_LEVEL, len(names))), z)


def residual_correlation_times(prob: MultipleShootingProblem, lin: _Lin, max_lag: int = 200) -> np.ndarray:
    """Per output, the integrated autocorrelation time 1 + 2 sum_k rho_k of its residual sequence (on
    its own rows, summed while rho_k stays above 0.05), in samples: 1 for white residuals. A sequence
    of m residuals with correlation time tau carries the information of about m / tau independent
    ones. Outputs with fewer than 50 rows get 1 (too short to tell)."""
    taus = np.ones(lin.e.shape[1])
    for j in range(lin.e.shape[1]):
        r = lin.e[prob.mask[:, j], j]
        n = len(r)
        if n < 50:
            continue
        r = r - r.mean()
        v = float(r @ r) / n
        if v <= 0:
            continue
        tau = 1.0
        for k in range(1, min(max_lag, n // 5)):
            rho = float(r[:-k] @ r[k:]) / (n * v)
            if rho < 0.05:
                break
            tau += 2.0 * rho
        taus[j] = tau
    return taus


def _weight_correlation_times(prob: MultipleShootingProblem, lin: _Lin) -> np.ndarray:
    """The correlation time each output's weight accounts for: its residuals' (calm-water model), or
    1 with the lake model, which inflates the covariance by the worst one instead
    (`autocorrelation_factor`). An output whose errors stay correlated over tau samples carries the
    information of m / tau independent ones, so its noise variance is taken tau times its residual
    variance. On a record from the stack the heading is the estimator's fused heading and r the gyro
    less the estimator's bias, both correlated over tens of samples (tau ~50-100 and ~20-30 on the
    lab loop's experiments): weighted as independent they claim that much more information than they
    hold, and the coefficients chase their errors with intervals 5-25 times too narrow (lake boat,
    four experiments: m33 off by 2.3 % at 24 sigma, a random boat's Y_v by 15 % at 10 sigma)."""
    return np.ones(len(prob.names)) if prob.lake else residual_correlation_times(prob, lin)


def autocorrelation_factor(prob: MultipleShootingProblem, lin: _Lin, max_lag: int = 200) -> float:
    """Variance inflation for autocorrelated residuals: the largest over the outputs of the
    integrated autocorrelation (`residual_correlation_times`). White residuals give 1; slowly
    varying unmodelled forces (gusts the per-interval factor does not follow, wind direction
    wander) give more, and the least-squares covariance, which assumes white noise, is too small by
    about that factor."""
    return max(1.0, float(np.max(residual_correlation_times(prob, lin, max_lag))))


@dataclass
class EnvironmentEstimate:
    """The lake model's environment: values and 1-sigma (ENV_NAMES order), gust factors per interval."""

    values: dict[str, float]
    std: dict[str, float]
    gust_factor: np.ndarray
    autocorrelation_factor: float
    crosswind_factor: np.ndarray | None = None  # per interval, the wind's turn (radians, small)

    @property
    def current_ne(self) -> tuple[float, float]:
        return self.values["current_n"], self.values["current_e"]

    @property
    def wind_ne(self) -> tuple[float, float]:
        """Earth-frame velocity of the air (where it blows TO), mean over the record."""
        g = float(np.mean(self.gust_factor)) if len(self.gust_factor) else 1.0
        return g * self.values["wind_n"], g * self.values["wind_e"]


@dataclass
class _Search:
    """What one Gauss-Newton search carries through its passes: the free parameters (indices, names,
    scale, bounds), the tolerance, the cost's history, the progress callback and the fixed values."""

    free: np.ndarray
    free_names: tuple[str, ...]
    tscale: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    tol: float
    history: list[float]
    progress: Callable[[int, float], None] | None
    fixed: Mapping[str, float]


@dataclass
class _Fit:
    """The search's end: the (relative) information, the covariance factor, the cost, s^2, the
    iterations, convergence, the noise passes run and the last linearisation."""

    F_rel: np.ndarray
    factor: float
    cost: float
    s2: float
    iterations: int
    converged: bool
    passes: int
    lin: _Lin


def _result(prob: MultipleShootingProblem, search: _Search, theta: np.ndarray, nodes: np.ndarray,
            fit: _Fit) -> IdentificationResult:
    free, free_names, tscale, fixed, history = search.free, search.free_names, search.tscale, search.fixed, search.history
    F_rel, factor, cost, s2, iterations = fit.F_rel, fit.factor, fit.cost, fit.s2, fit.iterations
    converged, passes, lin = fit.converged, fit.passes, fit.lin
    F_rel = 0.5 * (F_rel + F_rel.T)
    try:
        cov_all = np.linalg.inv(F_rel) * factor
        if not np.all(np.isfinite(cov_all)):
            raise np.linalg.LinAlgError
    except np.linalg.LinAlgError:
        cov_all = np.linalg.pinv(F_rel) * factor
    nv = len(free_names)
    cov_rel = cov_all[:nv, :nv]  # the vessel parameters, the environment and the gyro bias marginalised
    ts = tscale[free][:nv]
    F_m = F_rel  # the information of the vessel parameters (the environment eliminated)
    if nv < len(free):
        try:
            F_m = np.linalg.inv(cov_rel / factor) if nv else np.zeros((0, 0))
        except np.linalg.LinAlgError:
            F_m = np.linalg.pinv(cov_rel / factor)
        F_m = 0.5 * (F_m + F_m.T)
    th = theta[free][:nv]
    rel_std = np.sqrt(np.clip(np.diag(cov_rel), 0, None)) * ts / np.maximum(np.abs(th), 1e-12)
    ident = identifiability(F_m / factor if factor > 0 else F_m, free_names, rel_std)
    D = np.diag(ts)
    cov = D @ cov_rel @ D
    Dinv = np.diag(1.0 / ts)
    fisher = Dinv @ F_m @ Dinv
    std = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(free_names)}
    g = prob.grid
    first = np.array([np.flatnonzero(g.node_seg == s)[0] for s in range(len(prob.segments))])
    res = IdentificationResult(VesselParameters.from_vector(theta[:NTHETA]), std,
                               {n: float(v) for n, v in fixed.items()}, free_names, cov, fisher, nodes[first, :6],
                               cost, prob.n_measurements, s2, iterations, converged, ident, "multiple", [], history)
    res.details = MultipleShootingResult(nodes, g.node_time, dict(prob.noise),
                                         float(np.max(np.abs(lin.c))) * 1.0 if lin.c.size else 0.0,
                                         g.n_nodes, g.n_steps, passes, residual_autocorr(lin.e, prob.mask, prob.names))
    sd_all = np.sqrt(np.clip(np.diag(cov_all), 0, None)) * tscale[free]
    if prob.n_bias:
        nk = prob.n_kernel
        res.details.gyro_bias = theta[nk:nk + prob.n_bias].copy()
        res.details.gyro_bias_std = sd_all[-prob.n_bias:].copy()
        res.details.gyro_bias_record = prob.bias_record.copy()
    if prob.lake:
        sd_env = sd_all[nv:nv + len(ENV_NAMES)]
        res.details.environment = EnvironmentEstimate(
            {n: float(v) for n, v in zip(ENV_NAMES, theta[NTHETA:])}, {n: float(v) for n, v in zip(ENV_NAMES, sd_env)},
            nodes[:, 6].copy(), autocorrelation_factor(prob, lin), nodes[:, 7].copy())
    return res


def residual_autocorr(e: np.ndarray, mask: np.ndarray, names: Sequence[str], max_lag: int = 40) -> dict[str, np.ndarray]:
    """Autocorrelation of each output's residual series (its measured rows in time order) at lags
    1..max_lag: near zero for white residuals (the model explains the motion up to sensor noise);
    large and slowly decaying when something the model lacks (current, wind, an actuator effect)
    drives the motion."""
    out: dict[str, np.ndarray] = {}
    for j, n in enumerate(names):
        r = e[mask[:, j], j]
        r = r - r.mean() if r.size else r
        denom = float(r @ r)
        lags = min(max_lag, max(r.size - 1, 0))
        out[n] = (np.array([float(r[:-k] @ r[k:]) / denom for k in range(1, lags + 1)])
                  if denom > 0 and lags else np.zeros(0))
    return out


def _gauss_newton(prob: MultipleShootingProblem, search: _Search, theta: np.ndarray, nodes: np.ndarray,
                  max_iterations: int, it_offset: int) -> tuple[np.ndarray, np.ndarray, int, bool]:
    free, tscale, lo, hi = search.free, search.tscale, search.lo, search.hi
    tol, history, progress = search.tol, search.history, search.progress
    lin = prob.linearise(theta, nodes, free, tscale, True)
    if not math.isfinite(lin.cost):
        raise EstimationError("the simulation with the initial parameters diverged within a shooting interval "
                              "(non-finite state); check the data units (radians, rev/s) and the initial guess")
    mu = 1e-4
    nu = 1.0
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):
        blocks = prob.normal_blocks(lin)
        Hss, _, Hpp, gs, gp = blocks
        Ds = np.maximum(np.einsum("kii->ki", Hss), 1e-9 * max(float(np.max(np.einsum("kii->ki", Hss))), 1.0))
        Dp = np.maximum(np.diag(Hpp).copy(), 1e-9 * max(float(np.max(np.diag(Hpp))) if len(Hpp) else 1.0, 1.0))
        merit0 = lin.cost + nu * lin.l1
        # Once the trajectory is continuous far below the noise, the defects' decrease is no longer
        # first order: a step of size d leaves a second-order remainder ~d^2 as large as the defects,
        # so the merit's predicted gain nu |c|_1 never materialises, the ratio test sees ~0.4 on every
        # step and the damping never relaxes (a crawl of ~1e-3 in chi^2 per iteration on a lab record
        # of four experiments). There the steps are judged on the measurement cost alone, with the
        # defects kept below the tolerance.
        continuous = lin.c.size == 0 or float(np.max(np.abs(lin.c))) < CONTINUITY_TOL
        accepted = False
        # bounds by an active set: a parameter at its bound whose step points outward is held there for
        # this step, and the others' step is computed without it (clipping the full step instead moves
        # the rest as if the bounded one had moved: on a hull whose best fit leans on a bound, such as
        # X_u at its floor, the damping then grows until the estimate crawls and never converges)
        th_f = theta[free]
        at_lo, at_hi = th_f <= lo[free] + 1e-12 * np.abs(lo[free]), th_f >= hi[free] - 1e-12 * np.abs(hi[free])
        factored: dict[float, _Factored] = {}  # per damping, for this linearisation
        for trial in range(14):
            if mu not in factored:
                factored[mu] = _factor(prob, lin, blocks, Ds, Dp, mu)
            fac = factored[mu]
            active = np.zeros(len(free), bool)
            for _ in range(len(free) + 1):
                ds, dp, lam = _solve_step(prob, fac, gs, gp, lin.c, active)
                out = ~active & ((at_lo & (dp < 0)) | (at_hi & (dp > 0)))
                if not out.any():
                    break
                active |= out
            alpha = 1.0 if trial < 6 else 0.5 ** (trial - 5)
            if lam.size:
                nu = max(nu, 1.2 * float(np.max(np.abs(lam))))
            merit0 = lin.cost + nu * lin.l1
            gd = float(np.sum(gs * ds) + gp @ dp)
            qd = _quad(prob, blocks, ds, dp)
            pred_cost = -(alpha * gd + 0.5 * alpha * alpha * qd)
            pred = pred_cost + nu * alpha * lin.l1
            th_new = theta.copy()
            th_new[free] = np.clip(theta[free] + alpha * dp * tscale[free], lo[free], hi[free])
            nodes_new = nodes + alpha * ds * prob.xscale[None, :]
            lin_new = prob.linearise(th_new, nodes_new, free, tscale, False)
            merit1 = lin_new.cost + nu * lin_new.l1
            if math.isfinite(merit1) and lin_new.l1 > max(lin.l1, 1e-12) and merit1 > merit0 - 1e-4 * pred:
                # second-order correction (Maratos effect): the step met the linearised continuity, but
                # the intervals' curvature left larger defects; one more solve with the same
                # factorisation, no gradient and the new defects, pulls the trajectory back together
                soc = _solve_step(prob, fac, 0.0 * gs, 0.0 * gp, lin_new.c, active)
                th_soc = th_new.copy()
                th_soc[free] = np.clip(th_new[free] + soc[1] * tscale[free], lo[free], hi[free])
                nodes_soc = nodes_new + soc[0] * prob.xscale[None, :]
                lin_soc = prob.linearise(th_soc, nodes_soc, free, tscale, False)
                merit_soc = lin_soc.cost + nu * lin_soc.l1
                if math.isfinite(merit_soc) and merit_soc < merit1:
                    th_new, nodes_new, lin_new, merit1 = th_soc, nodes_soc, lin_soc, merit_soc
            ared = merit0 - merit1
            if continuous and math.isfinite(merit1) and (lin_new.c.size == 0 or
                                                         float(np.max(np.abs(lin_new.c))) < CONTINUITY_TOL):
                pred, ared = pred_cost, lin.cost - lin_new.cost
            if math.isfinite(merit1) and pred > 0 and ared >= 1e-4 * pred:
                accepted = True
                break
            if math.isfinite(merit1) and pred <= 1e-14 * max(merit0, 1.0) and abs(ared) <= 1e-12 * max(merit0, 1.0):
                # nothing left to gain at any damping: converged
                break
            mu = max(mu * 4.0, 1e-6)
        if not accepted:
            converged = lin.l1 <= 1e-3 * max(1, prob.n_con)
            break
        rel = ared / max(merit0, 1e-300)
        theta, nodes = th_new, nodes_new
        # the sensitivities at the new point for the next iteration; after the last one, whoever goes on
        # from there computes them (the search's result, the next pass): a stage that only starts the
        # next search (shooting_point) never needs them, the trial's linearisation has the cost and defects
        lin = prob.linearise(theta, nodes, free, tscale, True) if it < max_iterations else lin_new
        history.append(2.0 * lin.cost)
        ratio = ared / pred
        mu = mu / 3.0 if ratio > 0.75 else (mu * 2.0 if ratio < 0.25 else mu)
        mu = max(mu, 1e-12)
        if progress:
            progress(it_offset + it, 2.0 * lin.cost)
        cmax = float(np.max(np.abs(lin.c))) if lin.c.size else 0.0
        # statistically converged: the last step changed chi^2 by < 1e-3 (parameters by ~0.03 sigma)
        # and the trajectory is continuous to 1e-3 of the noise
        if cmax < CONTINUITY_TOL and ((ared < 5e-4 and pred < 1e-3) or rel < tol):
            converged = True
            break
    return theta, nodes, it, converged


def record_fisher(records: Sequence[IdRecord], params: VesselParameters, free_names: Sequence[str],
                  options: SolverOptions = SolverOptions(), nodes: np.ndarray | None = None,
                  problem: MultipleShootingProblem | None = None) -> np.ndarray:
    """Fisher information (absolute units) of `free_names` from the whole record, every segment's
    initial state free, at `params` and the given noise: its inverse is the Cramer-Rao bound.

    The trajectory is the model's own at `params`: node states fitted to the data with the
    parameters held (`nodes` skips that fit, e.g. the true states of a simulation)."""
    prob = problem or MultipleShootingProblem(records, replace(options, lake=False, gyro_bias=False))
    theta = np.array(params.to_vector(), float)
    if nodes is None:
        all_fixed = dict(zip(NAMES, theta))
        res = estimate_multiple_shooting(records, params, all_fixed, replace(options, estimate_noise=False,
                                                                             max_iterations=30), problem=prob)
        nodes = res.details.nodes
    free = np.array([NAMES.index(n) for n in free_names], dtype=int)
    tscale = parameter_scale(theta)
    lin = prob.linearise(theta, nodes, free, tscale, True)
    F_rel = _fisher_from(prob, lin, prob.normal_blocks(lin))
    Dinv = np.diag(1.0 / tscale[free])
    return Dinv @ F_rel @ Dinv


def check_identifiable(result: IdentificationResult) -> None:
    """Raise IdentifiabilityError when the data leave a parameter direction undetermined."""
    if result.identifiability.unidentifiable:
        dirs = "; ".join(d for d in result.identifiability.directions if d.startswith("UNIDENTIFIABLE"))
        raise IdentifiabilityError(f"the data do not determine every parameter ({dirs}); fix those parameters "
                                   "(--fix NAME=VALUE) or record data that excite them")


def estimate_lake(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                  fixed: Mapping[str, float] | None = None, options: SolverOptions = SolverOptions(lake=True),
                  progress: Callable[[int, float], None] | None = None) -> IdentificationResult:
    """The lake model in stages (a homotopy): the current and a steady wind with the parameters held
    at `theta0`; then the parameters too (gust factors held at 1); then from there with the gust
    factors free (prior spread `options.gust_std`). Started with everything free, the first iterations,
    far from the parameters, explain the model error by wild gusts or a wrong wind and never recover."""
    options = replace(options, lake=True)
    steady = replace(options, gust_std=1e-3)
    all_fixed = {**theta0.to_dict(), **(fixed or {})}
    _, zero = shooting_point(records, theta0, all_fixed, steady, progress=progress)
    params, first = shooting_point(records, theta0, fixed, steady, zero, progress)
    return estimate_multiple_shooting(records, params, fixed, options, first, progress)


#: The lake model holds each gust factor constant over one shooting interval. How the gusts are cut
#: into intervals is a modelling choice the record cannot make; a second estimate with intervals this
#: many times longer shows how far the answer moves with that choice.
SECOND_GUST_INTERVAL_FACTOR = 1.5


def estimate_lake_two_gust_models(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                                  fixed: Mapping[str, float] | None = None,
                                  options: SolverOptions = SolverOptions(lake=True)
                                  ) -> tuple[IdentificationResult, IdentificationResult]:
    """`estimate_lake` twice from the same start: with `options.node_s` and with
    SECOND_GUST_INTERVAL_FACTOR x `options.node_s` gust intervals."""
    longer = replace(options, node_s=options.node_s * SECOND_GUST_INTERVAL_FACTOR)
    return estimate_lake(records, theta0, fixed, options), estimate_lake(records, theta0, fixed, longer)


def estimate_lake_averaged(records: Sequence[IdRecord], theta0: VesselParameters = DEFAULT_PARAMETERS,
                           fixed: Mapping[str, float] | None = None,
                           options: SolverOptions = SolverOptions(lake=True)) -> IdentificationResult:
    """The two gust models' estimates (`estimate_lake_two_gust_models`) averaged
    (`average_over_model_choice`). The sandwich covariance of one estimate sees the noise, not the
    bias of a gust model that is not the lake's:
    on 20 lake records one estimate's 3-sigma intervals held 86 % of the true values and it answered
    4 records wrongly; the average's held all of them and answered none wrongly (docs/sysid.md).
    Converged only when both are; twice the work."""
    return average_over_model_choice(*estimate_lake_two_gust_models(records, theta0, fixed, options))


def average_over_model_choice(first: IdentificationResult, second: IdentificationResult) -> IdentificationResult:
    """Two estimates of the same record under two equally defensible model choices, averaged with
    equal weights: the mean, and the covariance (P1 + P2) / 2 + (d/2)(d/2)^T with d their difference
    (the within-model spread plus the between-model spread). The details (environment, residuals,
    nodes) stay the first's; `gust_interval_shift` records d in the first's sigma."""
    names = first.free_names
    if tuple(second.free_names) != tuple(names):
        raise ValueError("the two estimates must have the same free coefficients")
    v1 = np.array([getattr(first.params, n) for n in names])
    d = np.array([getattr(second.params, n) for n in names]) - v1
    mean = v1 + d / 2.0
    cov = (np.asarray(first.covariance, float) + np.asarray(second.covariance, float)) / 2.0 + np.outer(d, d) / 4.0
    std = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(names)}
    shift = {n: float(d[i] / first.std[n]) if first.std[n] > 0 else math.inf for i, n in enumerate(names)}
    details = replace(first.details, gust_interval_shift=shift) if first.details is not None else None
    params = first.params.with_updates(**{n: float(v) for n, v in zip(names, mean)})
    return replace(first, params=params, covariance=cov, std=std,
                   converged=bool(first.converged and second.converged),
                   iterations=first.iterations + second.iterations, details=details)
