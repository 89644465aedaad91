"""Identification data: one record of inputs and measured outputs, its segments, and loaders.

A record holds samples at times t_k (non-uniform allowed) of
    inputs  u_k = [alpha1, alpha2, n1, n2, nt]          (rad, rev/s)
    outputs y_k = [north, east, psi, r] (+ optionally u, v)  (m, m, rad, rad/s, m/s, m/s)
Conventions used by every estimator in this package (docs/sysid.md, "Data"):
  - inputs are held constant (zero-order hold) from t_k to t_{k+1}; a non-finite input value is
    replaced by the last finite one of the same column (at the start of a segment: by 0);
  - outputs are compared only where they are finite (a NaN entry simply has no residual);
  - a gap t_{k+1} - t_k > `gap_s` splits the record into separate segments, each with its own
    initial state; estimators may further cut segments into windows (`split_windows`).

Loaders live at the I/O boundary (`load_csv`, `load_record`); `LOADERS` maps a file suffix to a
loader so that a second source (the MCAP run logs) can be registered without touching callers.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from lotsen.errors import DataError

INPUT_COLUMNS = ("alpha1", "alpha2", "n1", "n2", "nt")
OUTPUT_COLUMNS = ("north", "east", "psi", "r")
OPTIONAL_OUTPUT_COLUMNS = ("u", "v")
REQUIRED_COLUMNS = ("t",) + INPUT_COLUMNS + OUTPUT_COLUMNS
# index of each output in the model state x = [N, E, psi, u, v, r]
OUTPUT_STATE_INDEX = {"north": 0, "east": 1, "psi": 2, "u": 3, "v": 4, "r": 5}
PSI_OUTPUT = "psi"


@dataclass
class IdRecord:
    """Samples of one experiment: t (K), inputs (K x 5), outputs (K x ny) with names."""

    t: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    output_names: tuple[str, ...] = OUTPUT_COLUMNS
    source: str = "<memory>"

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.inputs = np.asarray(self.inputs, dtype=float).reshape(len(self.t), 5)
        self.outputs = np.asarray(self.outputs, dtype=float).reshape(len(self.t), len(self.output_names))

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    def slice(self, t_start: float, t_end: float) -> "IdRecord":
        """Samples with t_start <= t < t_end (e.g. an estimation / validation split)."""
        m = (self.t >= t_start) & (self.t < t_end)
        return IdRecord(self.t[m], self.inputs[m], self.outputs[m], self.output_names, self.source)

    def to_csv_rows(self) -> tuple[list[str], list[list[float]]]:
        header = ["t", *INPUT_COLUMNS, *self.output_names]
        rows = [[float(self.t[k]), *map(float, self.inputs[k]), *map(float, self.outputs[k])]
                for k in range(len(self.t))]
        return header, rows


@dataclass
class Segment:
    """A gap-free piece of a record: inputs already held (finite everywhere)."""

    t: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    output_names: tuple[str, ...]
    source: str = "<memory>"
    first_row: int = 0  # row index of t[0] in the record (for messages)
    x0: np.ndarray | None = field(default=None)  # a given initial state (else estimated)

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0


def _hold_inputs(inputs: np.ndarray) -> np.ndarray:
    """Zero-order hold over non-finite entries (last finite value; 0 before the first)."""
    out = np.array(inputs, dtype=float)
    for j in range(out.shape[1]):
        col = out[:, j]
        bad = ~np.isfinite(col)
        if bad.any():
            idx = np.where(~bad, np.arange(len(col)), 0)
            np.maximum.accumulate(idx, out=idx)
            filled = col[idx]
            filled[~np.isfinite(filled)] = 0.0
            out[:, j] = filled
    return out


def split_segments(record: IdRecord, gap_s: float = 1.0, min_samples: int = 8) -> list[Segment]:
    """Cut a record where t_{k+1} - t_k > gap_s; drop pieces with fewer than `min_samples` finite outputs."""
    t = record.t
    if len(t) == 0:
        return []
    breaks = np.where(np.diff(t) > gap_s)[0] + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [len(t)]])
    segs = []
    for a, b in zip(starts, ends):
        y = record.outputs[a:b]
        if np.isfinite(y).any(axis=1).sum() < min_samples:
            continue
        segs.append(Segment(t[a:b].copy(), _hold_inputs(record.inputs[a:b]), y.copy(),
                            record.output_names, record.source, int(a)))
    return segs


def split_windows(segments: list[Segment], window_s: float | None) -> list[Segment]:
    """Cut segments into windows of at most `window_s` seconds (each gets its own initial state).

    The default model is open-loop unstable in straight motion above ~0.5 m/s (the sway-yaw pole
    reaches +1.4 1/s at full speed), so a simulation over a minute diverges from the data for any
    parameter error: output-error estimation then needs short windows. None = no cut.
    """
    if not window_s:
        return list(segments)
    out = []
    for s in segments:
        n = len(s.t)
        k = 0
        while k < n:
            k_end = int(np.searchsorted(s.t, s.t[k] + window_s, side="left"))
            k_end = max(k_end, k + 2)
            # a short tail joins the previous window rather than forming a tiny one
            if n - k_end < 0.3 * max(k_end - k, 1):
                k_end = n
            out.append(Segment(s.t[k:k_end], s.inputs[k:k_end], s.outputs[k:k_end], s.output_names,
                               s.source, s.first_row + k))
            k = k_end
    return out


# ----------------------------------------------------------------------------------------------
# loaders (I/O boundary)

def load_csv(path: str | Path) -> IdRecord:
    """Read `t,alpha1,alpha2,n1,n2,nt,north,east,psi,r[,u,v]` (header row, SI units, rev/s).

    Raises DataError naming the file and row (1-based, header = row 1) of malformed data.
    Empty cells and 'nan' are NaN. Time must be finite and strictly increasing.
    """
    path = Path(path)
    try:
        fh = open(path, newline="")
    except OSError as exc:
        raise DataError(f"{path}: cannot open ({exc.strerror})") from exc
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise DataError(f"{path}: empty file (expected a header row {','.join(REQUIRED_COLUMNS)})") from None
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise DataError(f"{path}, row 1: missing column(s) {', '.join(missing)} "
                            f"(expected {','.join(REQUIRED_COLUMNS)}[,u,v])")
        dup = {h for h in header if header.count(h) > 1}
        if dup:
            raise DataError(f"{path}, row 1: duplicate column(s) {', '.join(sorted(dup))}")
        out_names = OUTPUT_COLUMNS + tuple(c for c in OPTIONAL_OUTPUT_COLUMNS if c in header)
        cols = [header.index(c) for c in ("t",) + INPUT_COLUMNS + out_names]
        rows = []
        for i, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise DataError(f"{path}, row {i}: {len(row)} fields, header has {len(header)}")
            vals = []
            for j in cols:
                cell = row[j].strip()
                if cell == "" or cell.lower() == "nan":
                    vals.append(math.nan)
                    continue
                try:
                    vals.append(float(cell))
                except ValueError:
                    raise DataError(f"{path}, row {i}, column {header[j]}: {cell!r} is not a number") from None
            if not math.isfinite(vals[0]):
                raise DataError(f"{path}, row {i}: time t is missing or not finite")
            if rows and vals[0] <= rows[-1][0]:
                raise DataError(f"{path}, row {i}: time {vals[0]:g} s is not after the previous row's "
                                f"{rows[-1][0]:g} s (t must increase strictly)")
            if any(math.isinf(v) for v in vals):
                raise DataError(f"{path}, row {i}: infinite value")
            rows.append(vals)
    if len(rows) < 2:
        raise DataError(f"{path}: fewer than 2 data rows")
    a = np.array(rows)
    return IdRecord(a[:, 0], a[:, 1:6], a[:, 6:], out_names, str(path))


def save_csv(record: IdRecord, path: str | Path) -> None:
    header, rows = record.to_csv_rows()
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for row in rows:
            w.writerow(["nan" if not math.isfinite(v) else f"{v:.9g}" for v in row])


# suffix -> loader; the logs work adds ".mcap" here (register_loader)
LOADERS: dict[str, Callable[[Path], IdRecord]] = {".csv": load_csv}


def register_loader(suffix: str, loader: Callable[[Path], IdRecord]) -> None:
    LOADERS[suffix.lower()] = loader


def load_record(path: str | Path) -> IdRecord:
    """Load any supported identification data file (chosen by suffix)."""
    path = Path(path)
    loader = LOADERS.get(path.suffix.lower())
    if loader is None:
        raise DataError(f"{path}: unsupported data file type {path.suffix!r} "
                        f"(supported: {', '.join(sorted(LOADERS))})")
    return loader(path)
