"""The shooting intervals in blocks: each block simulated and linearised on its own, on any core.

Given the parameters, every shooting interval is simulated from its own node state, independently of
the others (lotsen.sysid.multiple). A block is a run of consecutive intervals (about the same number
of integration steps in each block); `linearise_block` turns it into its share of the Gauss-Newton
system: the weighted residuals of its measurement rows, the states at its intervals' ends with their
sensitivities (the continuity constraints), and its part of the normal equations (per node H_ss, H_sp,
g_s; the block's sums of H_pp and g_p). The blocks are cut by the record alone, never by the number of
workers, and multiple.py sums their parts in the blocks' order: the same answer with 1 and N workers.

These functions run in worker processes (lotsen.sysid.parallel.map_held): module-level, their inputs
picklable; the block's data (`ShootingBlock`) are sent to a worker once and kept there. Their array
inputs are taken C-contiguous first: numpy's einsum sums in an order that follows its operands'
strides, and a strided view arrives in a worker as a contiguous copy (a sandwich covariance differed
in the 13th digit between 1 and 2 workers before).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lotsen.model.angles import wrap_angle
from lotsen.sysid.kernels import step_kernels

#: a block has at least this many integration steps (a 60-s record is one block: the split's overhead
#: would cost more than it gains) ...
MIN_BLOCK_STEPS = 1024
#: ... and a record is cut into at most this many: a 10-min record into 8 (two per worker on a
#: four-core Raspberry Pi)
MAX_BLOCKS = 8


@dataclass(frozen=True)
class ShootingBlock:
    """Nodes [n0, n1) of a grid (lotsen.sysid.multiple.ShootingGrid) with their steps and measurement
    rows, indices local to the block."""

    geometry: tuple[float, ...]
    lake: bool
    n0: int
    n1: int
    h: np.ndarray
    U: np.ndarray
    reset: np.ndarray
    node_step: np.ndarray  # local step of each node's reset
    need: np.ndarray  # local steps whose state is needed (sorted): measurements and interval ends
    meas_pos: np.ndarray  # per measurement row: its position in `need`
    end_pos: np.ndarray  # per interval with a successor: the position of its end in `need`
    Y: np.ndarray  # measurement rows (0 where not measured)
    mask: np.ndarray
    meas_bounds: np.ndarray  # local node k's rows are meas_bounds[k]:meas_bounds[k + 1]
    meas_bias: np.ndarray  # each row's yaw-rate offset (its index in BlockCall.gyro_bias)
    out_idx: tuple[int, ...]  # the state of each output column
    psi_col: int | None
    r_col: int | None


@dataclass(frozen=True)
class BlockCall:
    """Where to linearise: the kernel's parameters, the gyro offsets per record, the block's node states,
    and for the sensitivities the free parameters (the kernel's, then the offsets') and the scales."""

    theta: np.ndarray  # the kernel's parameters (vessel [+ environment])
    gyro_bias: np.ndarray  # the yaw-rate offsets (empty: none estimated)
    nodes: np.ndarray  # the block's node states, n1 - n0 x nz
    sqrt_w: np.ndarray  # per output, 1 / noise std
    sens: bool = False
    free_kernel: np.ndarray | None = None  # indices into theta
    free_bias: np.ndarray | None = None  # indices into gyro_bias
    scale_kernel: np.ndarray | None = None  # their scales (tscale)
    scale_bias: np.ndarray | None = None
    xscale: np.ndarray | None = None  # node-state scale (nz)
    con_scale: np.ndarray | None = None  # continuity defects' scale (6)


@dataclass
class BlockLinearisation:
    """The block's share (module docstring); the normal-equation parts only with the sensitivities."""

    e: np.ndarray  # weighted residuals of its rows (0 where not measured)
    X_end: np.ndarray  # the state at the end of each interval with a successor
    Gx: np.ndarray | None = None  # d (scaled end state) / d (scaled node state), per interval with a successor
    Gp: np.ndarray | None = None  # d (scaled end state) / d (scaled free parameters)
    Hss: np.ndarray | None = None  # per node: J_x^T J_x over its rows
    Hsp: np.ndarray | None = None  # per node: J_x^T J_p
    Hpp: np.ndarray | None = None  # the block's J_p^T J_p
    gs: np.ndarray | None = None  # per node: J_x^T e
    gp: np.ndarray | None = None  # the block's J_p^T e


def cut_blocks(node_step: np.ndarray, n_steps: int) -> list[tuple[int, int]]:
    """Node ranges [n0, n1) of about equal steps (MIN_BLOCK_STEPS, MAX_BLOCKS): the record alone decides."""
    n_nodes = len(node_step)
    count = int(max(1, min(MAX_BLOCKS, n_steps // MIN_BLOCK_STEPS, n_nodes)))
    cuts = np.searchsorted(node_step, np.arange(1, count) * n_steps / count)
    edges = np.unique(np.concatenate([[0], np.clip(cuts, 1, n_nodes - 1), [n_nodes]])) if n_nodes > 1 else \
        np.array([0, n_nodes])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:])]


def _residuals(block: ShootingBlock, call: BlockCall, Xm: np.ndarray) -> np.ndarray:
    e = block.Y - Xm[:, list(block.out_idx)]
    if len(call.gyro_bias) and block.r_col is not None:
        e[:, block.r_col] -= call.gyro_bias[block.meas_bias]
    if block.psi_col is not None:
        # a trial point whose simulation diverged has inf states: no warning, linearise rejects the point
        with np.errstate(invalid="ignore"):
            e[:, block.psi_col] = wrap_angle(e[:, block.psi_col])
    return np.where(block.mask, e, 0.0) * call.sqrt_w


def _simulate(block: ShootingBlock, call: BlockCall) -> tuple[np.ndarray, ...]:
    k = step_kernels(block.geometry, lake=block.lake)
    X, S = k.run_record(call.theta, block.h, block.U, block.reset, block.node_step, np.ascontiguousarray(call.nodes),
                        block.need, call.sens)
    if call.sens:
        return X[block.meas_pos], X[block.end_pos], S[block.meas_pos], S[block.end_pos]  # type: ignore[index]
    return X[block.meas_pos], X[block.end_pos]


def _jacobians(block: ShootingBlock, call: BlockCall, Sm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d e / d (scaled node state) and d e / d (scaled free parameters) per row (rows x outputs x ...)."""
    nz, xs = len(call.xscale), call.xscale  # type: ignore[arg-type]
    W = (call.sqrt_w[None, :] * block.mask)[:, :, None]
    Sy = Sm[:, list(block.out_idx), :]
    fk = call.free_kernel
    Jx = -Sy[:, :, :nz] * xs[None, None, :] * W  # type: ignore[index]
    Jp = -Sy[:, :, nz + fk] * call.scale_kernel[None, None, :] * W  # type: ignore[index,operator]
    fb = call.free_bias
    if fb is not None and len(fb):  # d e_r / d b_q = -1 on offset q's rows
        Jb = np.zeros((len(Sm), len(call.sqrt_w), len(fb)))
        Jb[:, block.r_col, :] = -(block.meas_bias[:, None] == fb[None, :]).astype(float) * call.scale_bias[None, :]  # type: ignore[index]
        Jp = np.concatenate([Jp, Jb * W], axis=2)
    return Jx, Jp


def linearise_block(block: ShootingBlock, call: BlockCall) -> BlockLinearisation:
    """The block's share of the linearised problem at `call` (module docstring)."""
    sim = _simulate(block, call)
    e = _residuals(block, call, sim[0])
    out = BlockLinearisation(e, sim[1])
    if not call.sens:
        return out
    Sm, Se = sim[2], sim[3]
    nz, xs, cs = len(call.xscale), call.xscale, call.con_scale  # type: ignore[arg-type]
    fk = call.free_kernel
    out.Gx = Se[:, :6, :nz] * xs[None, None, :] / cs[None, :, None]  # type: ignore[index]
    Gp = Se[:, :6, nz + fk] * call.scale_kernel[None, None, :] / cs[None, :, None]  # type: ignore[index,operator]
    nb = 0 if call.free_bias is None else len(call.free_bias)
    out.Gp = np.concatenate([Gp, np.zeros((len(Gp), 6, nb))], axis=2) if nb else Gp
    Jx, Jp = _jacobians(block, call, Sm)
    b = block.meas_bounds[:-1]
    # J^T J by matmul (per row for the node states, one BLAS product over all rows for the parameters): a
    # sixth less time per block than einsum's loops; the sums are grouped otherwise, so the estimate moves
    # by round-off only (lake record 2500: its file's numbers within 5e-12 relative)
    JxT = Jx.transpose(0, 2, 1)
    out.Hss = np.add.reduceat(JxT @ Jx, b, axis=0)
    out.Hsp = np.add.reduceat(JxT @ Jp, b, axis=0)
    Jp_rows = Jp.reshape(Jp.shape[0] * Jp.shape[1], Jp.shape[2])
    out.Hpp = Jp_rows.T @ Jp_rows
    out.gs = np.add.reduceat(np.einsum("kji,kj->ki", Jx, e), b, axis=0)
    out.gp = np.einsum("kji,kj->i", Jp, e)
    return out


def block_scores(block: ShootingBlock, call_and_dsdp: tuple[BlockCall, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per row the score s_k = J_k^T e_k of the free parameters with the node states eliminated
    (J_k = J_p + J_x d s / d p, `dsdp` per node of the block), and the block's sum of J_k^T J_k: the
    parts of the sandwich covariance (lotsen.sysid.multiple.score_covariance)."""
    call, dsdp = call_and_dsdp[0], np.ascontiguousarray(call_and_dsdp[1])
    sim = _simulate(block, call)
    e = _residuals(block, call, sim[0])
    Jx, Jp = _jacobians(block, call, sim[2])
    node_of_row = np.repeat(np.arange(len(block.meas_bounds) - 1), np.diff(block.meas_bounds))
    J = Jp + np.einsum("kjz,kzf->kjf", Jx, dsdp[node_of_row])
    return np.einsum("kjf,kj->kf", J, e), np.einsum("kjf,kjg->fg", J, J)
