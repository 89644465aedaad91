"""Identification data: one record of inputs and measured outputs, its segments, and loaders.

A record holds rows at times t_k (non-uniform, non-decreasing) of
    inputs  u_k = [alpha1, alpha2, n1, n2, nt]          (rad, rev/s)
    outputs y_k = [north, east, psi, r] (+ optionally u, v)  (m, m, rad, rad/s, m/s, m/s)
in the **asynchronous** form the boat records (docs/sysid.md, "Data"): every stream keeps its own
time stamps, and a row may carry only inputs or only outputs (NaN = no value at this stamp).
Conventions used by every estimator in this package:
  - a commanded input (input_kind "held", the default) holds from its stamp until the next stamp
    of the same column (zero-order hold; the row's other cells may be empty); achieved actuator
    values are continuous signals: "mean" (interval means) and "sample" (point samples) are
    reconstructed piecewise linearly and each integration step uses the step average (INPUT_KINDS);
  - the record starts where every input column has had a value (earlier rows cannot be simulated);
  - outputs are compared only where they are finite (a NaN entry simply has no residual);
  - a gap of more than `gap_s` between consecutive *measurements* splits the record into separate
    segments, each with its own initial state (the inputs keep holding across the gap).

Loaders live at the I/O boundary (`load_csv`, `load_record`); `LOADERS` maps a file suffix to a
loader so that a second source (the MCAP run logs) can be registered without touching callers.
`check_record` refuses data no estimator can use (non-finite or decreasing time, infinite values,
no measurements, an input column that never has a value) with a DataError naming the place.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from lotsen.errors import DataError
from lotsen.files import MAX_DATA_BYTES, atomic_output, read_text

INPUT_COLUMNS = ("alpha1", "alpha2", "n1", "n2", "nt")
OUTPUT_COLUMNS = ("north", "east", "psi", "r")
OPTIONAL_OUTPUT_COLUMNS = ("u", "v")
#: the IMU's means over each row interval (specific force, body x fwd, y stbd, z down, m/s^2; rates p, q, r,
#: rad/s), optional: not outputs of the model; the sea state of the record is estimated from them
#: (lotsen.fusion.seastate.record_sea_state; docs/sysid.md "Records in waves")
IMU_COLUMNS = ("imu_ax", "imu_ay", "imu_az", "imu_p", "imu_q", "imu_r")
REQUIRED_COLUMNS = ("t",) + INPUT_COLUMNS + OUTPUT_COLUMNS
# index of each output in the model state x = [N, E, psi, u, v, r]
OUTPUT_STATE_INDEX = {"north": 0, "east": 1, "psi": 2, "u": 3, "v": 4, "r": 5}
PSI_OUTPUT = "psi"
# how a record's input values are meant (docs/sysid.md, "Data"):
#   "held"   - commands: each value holds from its stamp until the next (zero-order hold);
#   "mean"   - achieved values, each the mean over [its stamp, the next stamp of its column) (a
#              tachometer count, a logger's interval mean): reconstructed as the piecewise-linear
#              signal with those interval means and central-difference slopes;
#   "sample" - achieved values sampled at their stamps: linearly interpolated between stamps.
# After a column's last stamp every kind holds its last value.
INPUT_KINDS = ("held", "mean", "sample")
#: interval means reconstructed with each slope taken from the next interval's mean instead of the two
#: neighbours' (central): an equally defensible guess at how the actuators moved within each logged
#: interval, which identification uses to measure how much its answer depends on that guess
#: (lotsen.sysid.estimators.reconstruction_spread); not a kind a file declares
MEAN_FORWARD = "mean_forward"
# what a value of a record may be (magnitude, unit): beyond these a cell is damaged data, and a
# 1e308 would overflow the estimator's arithmetic. Generous: a servo angle within a turn, propeller
# speeds a motor cannot reach, positions 100 km from the first fix, a heading unwrapped over 1600 turns.
VALUE_LIMITS: dict[str, tuple[float, str]] = {
    "alpha1": (2 * math.pi, "rad"), "alpha2": (2 * math.pi, "rad"), "n1": (500.0, "rev/s"),
    "n2": (500.0, "rev/s"), "nt": (500.0, "rev/s"), "north": (1e5, "m"), "east": (1e5, "m"),
    "psi": (1e4, "rad"), "r": (100.0, "rad/s"), "u": (50.0, "m/s"), "v": (50.0, "m/s")}
T_LIMIT_S = 1e10  # a POSIX time stamp is 1.8e9 s


@dataclass
class IdRecord:
    """Samples of one experiment: t (K), inputs (K x 5), outputs (K x ny) with names."""

    t: np.ndarray
    inputs: np.ndarray
    outputs: np.ndarray
    output_names: tuple[str, ...] = OUTPUT_COLUMNS
    source: str = "<memory>"
    input_kind: str = "held"  # one of INPUT_KINDS
    #: K x 6 (IMU_COLUMNS) or None: the IMU's mean over [t_k, t_k+1), NaN on rows without one
    imu: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.input_kind not in (*INPUT_KINDS, MEAN_FORWARD):
            raise DataError(f"{self.source}: input kind {self.input_kind!r} is not one of {', '.join(INPUT_KINDS)}")
        self.t = np.asarray(self.t, dtype=float)
        self.inputs = np.asarray(self.inputs, dtype=float).reshape(len(self.t), 5)
        self.outputs = np.asarray(self.outputs, dtype=float).reshape(len(self.t), len(self.output_names))
        if self.imu is not None:
            self.imu = np.asarray(self.imu, dtype=float).reshape(len(self.t), len(IMU_COLUMNS))

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    def slice(self, t_start: float, t_end: float) -> "IdRecord":
        """Rows with t_start <= t < t_end (e.g. an estimation / validation split).

        The inputs holding at the slice's first row (stamped earlier) are written into that row,
        so the slice means the same as the part of the record it came from."""
        m = (self.t >= t_start) & (self.t < t_end)
        U = self.inputs[m].copy()
        idx = np.flatnonzero(m)
        if len(idx) and idx[0] > 0:
            held = _hold_inputs(self.inputs[: idx[0] + 1])[-1]
            U[0] = held
        return IdRecord(self.t[m], U, self.outputs[m], self.output_names, self.source, self.input_kind,
                        None if self.imu is None else self.imu[m])

    @property
    def header(self) -> list[str]:
        return ["t", *INPUT_COLUMNS, *self.output_names, *(IMU_COLUMNS if self.imu is not None else ())]

    def to_csv_rows(self) -> tuple[list[str], list[list[float]]]:
        return self.header, [list(map(float, row)) for row in self._columns()]

    def _columns(self) -> np.ndarray:
        parts = [self.t[:, None], self.inputs, self.outputs] + ([self.imu] if self.imu is not None else [])
        return np.column_stack(parts)


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
    # d inputs / dt within each row interval (None: inputs held); inputs[k] is then the value of the
    # reconstructed input just after t[k], and a step of the integrator over [a, b] inside row k
    # uses the step average inputs[k] + input_slopes[k] * ((a + b) / 2 - t[k]) (step_inputs)
    input_slopes: np.ndarray | None = field(default=None)

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0


def _hold_inputs(inputs: np.ndarray) -> np.ndarray:
    """Zero-order hold over non-finite entries (last finite value of the column; NaN before the first)."""
    out = np.array(inputs, dtype=float)
    for j in range(out.shape[1]):
        col = out[:, j]
        bad = ~np.isfinite(col)
        if bad.any():
            idx = np.where(~bad, np.arange(len(col)), 0)
            np.maximum.accumulate(idx, out=idx)
            out[:, j] = col[idx]  # before the first finite value: col[0], i.e. NaN
    return out


def _reconstruct_inputs(t: np.ndarray, inputs: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Per row: the input value just after t[k] and its slope within the row interval (module docstring
    of INPUT_KINDS). "held" gives the zero-order hold and no slopes. NaN before a column's first stamp."""
    U = _hold_inputs(inputs)
    if kind == "held":
        return U, None
    slopes = np.zeros_like(U)
    for j in range(U.shape[1]):
        st = np.flatnonzero(np.isfinite(inputs[:, j]))
        if len(st) < 2:
            continue
        ts, us = t[st], inputs[st, j]
        dts = np.diff(ts)
        # stamp interval q = [ts[q], ts[q+1]) of every row from the first to the last stamp
        rows = np.arange(st[0], st[-1])
        q = np.searchsorted(st, rows, side="right") - 1
        if kind == "sample":
            sl = np.where(dts > 0, np.diff(us) / np.where(dts > 0, dts, 1.0), 0.0)
            slopes[rows, j] = sl[q]
            U[rows, j] = us[q] + sl[q] * (t[rows] - ts[q])
        else:  # "mean": value us[q] is the mean over interval q, centred at c[q]
            c = 0.5 * (ts[:-1] + ts[1:])
            m = us[:-1]
            nq = len(c)
            sl = np.zeros(nq)
            if nq >= 2:
                lo = np.maximum(np.arange(nq) - (0 if kind == MEAN_FORWARD else 1), 0)
                hi = np.minimum(np.arange(nq) + 1, nq - 1)
                dc = c[hi] - c[lo]
                sl = np.where(dc > 0, (m[hi] - m[lo]) / np.where(dc > 0, dc, 1.0), 0.0)
            slopes[rows, j] = sl[q]
            U[rows, j] = m[q] + sl[q] * (t[rows] - c[q])
    return U, slopes


def step_input_lines(seg: Segment, k: int | np.ndarray, frac: float | np.ndarray) -> np.ndarray:
    """The input of an integration step inside row interval k of `seg` that starts at fraction `frac`
    of the interval, as a line [u0 (5), du (5)]: u(s) = u0 + du s for s in the step (held: du = 0).
    Within a row interval the reconstruction is exactly this line, so an integrator that evaluates
    it at its stages (lotsen.sysid.sensitivity) integrates the reconstructed input exactly."""
    U = np.atleast_2d(seg.inputs[k])
    if seg.input_slopes is None:
        out = np.concatenate([U, np.zeros_like(U)], axis=-1)
    else:
        dt = np.append(np.diff(seg.t), 0.0)[k]
        slope = np.atleast_2d(seg.input_slopes[k])
        out = np.concatenate([U + slope * np.atleast_1d(np.asarray(frac * dt))[:, None], slope], axis=-1)
    return out[0] if np.ndim(k) == 0 else out


def check_record(record: IdRecord) -> None:
    """Refuse a record no estimator can use, with a DataError that names the problem and place."""
    src = record.source
    t = record.t
    if len(t) < 2:
        raise DataError(f"{src}: fewer than 2 rows")
    bad_t = np.flatnonzero(~np.isfinite(t))
    if len(bad_t):
        raise DataError(f"{src}, row {bad_t[0]}: time t is not finite")
    back = np.flatnonzero(np.diff(t) < 0)
    if len(back):
        k = int(back[0]) + 1
        raise DataError(f"{src}, row {k}: time {t[k]:g} s is before the previous row's {t[k - 1]:g} s "
                        "(time must not decrease)")
    for name, arr, cols in (("input", record.inputs, INPUT_COLUMNS), ("output", record.outputs, record.output_names)):
        inf = np.argwhere(np.isinf(arr))
        if len(inf):
            k, j = inf[0]
            raise DataError(f"{src}, row {k}, {name} {cols[j]}: infinite value")
        bounds = np.array([VALUE_LIMITS[c][0] for c in cols])
        with np.errstate(invalid="ignore"):
            far = np.argwhere(np.abs(arr) > bounds)
        if len(far):
            k, j = far[0]
            limit, unit = VALUE_LIMITS[cols[j]]
            raise DataError(f"{src}, row {k}, {name} {cols[j]}: {arr[k, j]:g} {unit} outside the allowed range "
                            f"-{limit:g} to {limit:g} {unit} (damaged data?)")
    if not np.all(np.abs(t) <= T_LIMIT_S):
        k = int(np.argmax(np.abs(t) > T_LIMIT_S))
        raise DataError(f"{src}, row {k}: time {t[k]:g} s outside the allowed range -{T_LIMIT_S:g} to {T_LIMIT_S:g} s")
    never = [c for j, c in enumerate(INPUT_COLUMNS) if not np.isfinite(record.inputs[:, j]).any()]
    if never:
        raise DataError(f"{src}: input column(s) {', '.join(never)} never have a value (an input holds from its "
                        "stamp until the next, so every column needs at least one)")
    if not np.isfinite(record.outputs).any():
        raise DataError(f"{src}: no finite measurement in any output column ({', '.join(record.output_names)})")
    # a column that is there but never measured (a heading channel lost for the whole run) would be read
    # as data by every estimator: refuse it by name rather than fail deep inside one of them
    empty = [c for j, c in enumerate(record.output_names) if not np.isfinite(record.outputs[:, j]).any()]
    if empty:
        raise DataError(f"{src}: output column(s) {', '.join(empty)} never have a value (every cell empty or NaN): "
                        "the channel was not recorded; drop the column from the file or record it")


def split_segments(record: IdRecord, gap_s: float = 1.0, min_samples: int = 8) -> list[Segment]:
    """Gap-free pieces of a record, each from its first to its last measurement.

    Inputs are held (each from its stamp to the next) and known from the first row where every
    input column has had a value; a gap of more than `gap_s` between consecutive measurement times
    starts a new segment. Pieces with fewer than `min_samples` measurement rows are dropped.
    """
    t = record.t
    if len(t) == 0:
        return []
    U, S = _reconstruct_inputs(t, record.inputs, record.input_kind)
    known = np.all(np.isfinite(U), axis=1)
    if not known.any():
        return []
    first = int(np.argmax(known))
    meas = np.flatnonzero(np.isfinite(record.outputs).any(axis=1))
    meas = meas[meas >= first]
    if len(meas) == 0:
        return []
    breaks = np.flatnonzero(np.diff(t[meas]) > gap_s) + 1
    segs = []
    for piece in np.split(meas, breaks):
        if len(piece) < min_samples:
            continue
        a, b = int(piece[0]), int(piece[-1]) + 1
        segs.append(Segment(t[a:b].copy(), U[a:b].copy(), record.outputs[a:b].copy(), record.output_names,
                            record.source, a, input_slopes=None if S is None else S[a:b].copy()))
    return segs


def check_excitation(segments: list[Segment]) -> None:
    """Refuse data that cannot identify anything: every input zero, or a boat that did not move."""
    if not segments:
        return
    src = segments[0].source
    if all(np.all(s.inputs == 0.0) for s in segments):
        raise DataError(f"{src}: no excitation: every input (alpha1, alpha2, n1, n2, nt) is zero throughout; "
                        "the data carry no information about the vessel's parameters")
    names = segments[0].output_names
    moved = 0.0
    turned = 0.0
    for s in segments:
        for name in ("north", "east"):
            if name in names:
                col = s.outputs[:, names.index(name)]
                ok = np.isfinite(col)
                if ok.sum() > 1:
                    moved = max(moved, float(np.ptp(col[ok])))
        if "psi" in names:
            col = s.outputs[:, names.index("psi")]
            ok = np.isfinite(col)
            if ok.sum() > 1:
                turned = max(turned, float(np.ptp(np.unwrap(col[ok]))))
    # sensor noise alone spans a few cm and a few degrees over a long record
    if moved < 0.5 and turned < math.radians(10.0):
        raise DataError(f"{src}: no excitation: the boat did not move (position range {moved:.3f} m, heading range "
                        f"{math.degrees(turned):.1f} deg): nothing to identify")


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
                               s.source, s.first_row + k,
                               input_slopes=None if s.input_slopes is None else s.input_slopes[k:k_end]))
            k = k_end
    return out


# ----------------------------------------------------------------------------------------------
# loaders (I/O boundary)

def load_csv(path: str | Path) -> IdRecord:
    """Read `t,alpha1,alpha2,n1,n2,nt,north,east,psi,r[,u,v]` (header row, SI units, rev/s).

    Lines before the header starting with '#' are comments; `# inputs: held|mean|sample` sets the
    record's input_kind (default held: commands; mean / sample: achieved values, see INPUT_KINDS).

    Asynchronous form: a row may carry only inputs or only outputs (empty cells or 'nan'); rows
    with the same t are merged (a column given twice at one stamp with different values is an
    error). Raises DataError naming the file and row (1-based, header = row 1) of malformed data:
    unparsable or infinite cells, a missing or non-finite t, a t before the previous row's.
    """
    path = Path(path)
    fh = io.StringIO(read_text(path, DataError, "data file", MAX_DATA_BYTES), newline="")  # UTF-8 or a clear error
    with fh:
        reader = csv.reader(fh)
        kind = "held"
        first_line = 1
        try:
            row0 = next(reader)
            # leading comment lines; "# inputs: held|mean|sample" says how the input values are meant
            while row0 and row0[0].lstrip().startswith("#"):
                text = ",".join(row0).lstrip()[1:].strip()
                key, _, val = text.partition(":")
                if key.strip().lower() == "inputs":
                    kind = val.strip().lower()
                    if kind not in INPUT_KINDS:
                        raise DataError(f"{path}, row {first_line}: inputs {val.strip()!r} is not one of "
                                        f"{', '.join(INPUT_KINDS)}")
                row0 = next(reader)
                first_line += 1
            header = [h.strip() for h in row0]
        except StopIteration:
            raise DataError(f"{path}: empty file (expected a header row {','.join(REQUIRED_COLUMNS)})") from None
        missing = [c for c in REQUIRED_COLUMNS if c not in header]
        if missing:
            raise DataError(f"{path}, row {first_line}: missing column(s) {', '.join(missing)} "
                            f"(expected {','.join(REQUIRED_COLUMNS)}[,u,v])")
        dup = {h for h in header if header.count(h) > 1}
        if dup:
            raise DataError(f"{path}, row {first_line}: duplicate column(s) {', '.join(sorted(dup))}")
        out_names = OUTPUT_COLUMNS + tuple(c for c in OPTIONAL_OUTPUT_COLUMNS if c in header)
        imu_names = IMU_COLUMNS if all(c in header for c in IMU_COLUMNS) else ()
        names = ("t",) + INPUT_COLUMNS + out_names + imu_names
        cols = [header.index(c) for c in names]
        nan = math.nan
        rows: list[list[float]] = []
        line_of: list[int] = []
        t_prev = -math.inf
        body_at = fh.tell()
        plain = _plain_rows(fh.read(), len(header), cols)  # None: rows the loop must look at one by one
        fh.seek(body_at)
        for i, row in enumerate(reader if plain is None else (), start=first_line + 1):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise DataError(f"{path}, row {i}: {len(row)} fields, header has {len(header)}")
            vals = []
            for j in cols:
                cell = row[j].strip()
                if cell == "" or cell.lower() == "nan":
                    vals.append(nan)
                    continue
                try:
                    v = float(cell)
                except ValueError:
                    raise DataError(f"{path}, row {i}, column {header[j]}: {cell!r} is not a number") from None
                if math.isinf(v):
                    raise DataError(f"{path}, row {i}, column {header[j]}: infinite value")
                vals.append(v)
            t = vals[0]
            if not math.isfinite(t):
                raise DataError(f"{path}, row {i}: time t is missing or not finite")
            if t < t_prev:
                raise DataError(f"{path}, row {i}: time {t:g} s is before the previous row's {t_prev:g} s "
                                "(time must not decrease)")
            if t == t_prev:  # same stamp: merge into the previous row
                last = rows[-1]
                for j in range(1, len(vals)):
                    v = vals[j]
                    if v == v:  # finite
                        if last[j] == last[j] and last[j] != v:
                            raise DataError(f"{path}, row {i}, column {names[j]}: {v:g} differs from {last[j]:g} "
                                            f"given at the same time {t:g} s (row {line_of[-1]})")
                        last[j] = v
                continue
            t_prev = t
            rows.append(vals)
            line_of.append(i)
    a = plain if plain is not None else np.array(rows)
    del rows
    if len(a) < 2:
        raise DataError(f"{path}: fewer than 2 data rows")
    ny = 6 + len(out_names)
    rec = IdRecord(a[:, 0], a[:, 1:6], a[:, 6:ny], out_names, str(path), kind, a[:, ny:] if imu_names else None)
    check_record(rec)
    return rec


#: a CSV body of numbers alone: digits, signs, points, exponents, commas and white space
_NOT_PLAIN = re.compile(r"[^0-9.eE+\-,\s]")


def _plain_rows(body: str, n_fields: int, cols: list[int]) -> np.ndarray | None:
    """The data rows of a CSV body of numbers and empty cells (NaN) whose t (column cols[0]) increases, as
    an array of `cols`: numpy's parser in one pass (each cell correctly rounded: the number float() reads,
    bit for bit). None for anything else ('nan' written out, a cell of spaces, an infinite value, a stamp
    repeated or going back, a wrong field count), which the row loop of load_csv then reads and names the
    row of. The 10-min lake record (14400 rows): 0.07 s here, 0.13 s in the loop."""
    body = body.rstrip("\r\n")
    if len(body) < 2 or _NOT_PLAIN.search(body):
        return None
    # an empty cell is a value not measured at that stamp: NaN, as the loop reads it
    body = body.replace(",,", ",nan,").replace(",,", ",nan,").replace("\n,", "\nnan,").replace(",\n", ",nan\n")
    body = ("nan" if body[0] == "," else "") + body.replace(",\r", ",nan\r") + ("nan" if body[-1] == "," else "")
    try:
        a = np.loadtxt(io.StringIO(body), delimiter=",", comments=None, dtype=float, ndmin=2)
    except ValueError:
        return None
    if a.shape[0] < 2 or a.shape[1] != n_fields or np.isinf(a).any():
        return None
    t = a[:, cols[0]]
    if not np.isfinite(t).all() or not (np.diff(t) > 0).all():
        return None
    return np.array(a[:, cols], order="C")  # the loop's layout (einsum sums in the order of the strides)


def save_csv(record: IdRecord, path: str | Path, inputs: tuple = ()) -> None:
    """Write the record (atomically, never over one of `inputs`: lotsen.files.atomic_output); a
    cell without a value at its row's stamp is left empty (asynchronous form).

    The stamps are written exactly (the shortest text that reads back as the same float): in the
    asynchronous form rows at one stamp are one instant (load_csv merges them), and two streams
    stamped 1e-17 s apart (a clock's sums, 0.06 and 0.060000000000000005) are two; at 10 significant
    digits they became one row, and the record identified from the CSV was another than the log's
    (X_uu 0.3-1.2 ppm apart), and a POSIX stamp (1.8e9 s) kept whole seconds only. The values keep
    10 significant digits, far below any sensor's resolution (the estimate moves by ~3e-10 relative)."""
    header = record.header
    data = record._columns()
    with atomic_output(path, inputs, DataError, "data file") as tmp, open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        if record.input_kind != "held":  # the default needs no line (files stay plain CSV)
            fh.write(f"# inputs: {record.input_kind}\n")
        w.writerow(header)
        for row in data.tolist():
            w.writerow([repr(row[0])] + ["" if v != v else f"{v:.10g}" for v in row[1:]])


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
