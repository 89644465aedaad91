"""`lotsen calibrate-mag DATA.csv --out mag.json`: planar magnetometer calibration from one turn.

DATA.csv has a header with (at least) the columns `t,mag_x,mag_y` in any consistent units; rows
that cannot be read (a short row, an empty or non-numeric cell, a value beyond MAX_FIELD or a time
beyond MAX_TIME_S) are skipped, counted and named on stderr (the first few by line); when more
than MAX_SKIPPED_FRACTION of the rows cannot be read the file is refused as damaged. The JSON written holds `center` (2),
`matrix` (2x2, maps the unit circle onto the ellipse), `residual_rms`, `coverage_deg`,
`n_points` and `heading_offset_rad` (declination / mounting offset: not determinable from the
magnetometer, set by `--heading-offset-deg`).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import sys
from pathlib import Path

from lotsen.files import MAX_DATA_BYTES, check_outputs, read_json, read_text, write_output
from lotsen.errors import DataError
from lotsen.fusion.magcal import CalibrationLimits, MagCalibration, fit_mag_calibration
from lotsen.settings import Number

REQUIRED_COLUMNS = ("t", "mag_x", "mag_y")
#: a magnetometer reading in any unit (uT ~50, raw counts up to 32767, nT ~50000) is below this
MAX_FIELD = 1e7
MAX_TIME_S = 1e10  # a POSIX time stamp is 1.8e9 s
#: more rows than this fraction unreadable: the file is damaged, not a record with a few bad lines
MAX_SKIPPED_FRACTION = 0.1
_SHOWN = 5


def register(subparsers) -> None:  # type: ignore[no-untyped-def]
    p = subparsers.add_parser(
        "calibrate-mag", help="fit the magnetometer's hard/soft iron from one full turn (seed 3.3)",
        description="Least-squares ellipse fit to the horizontal magnetometer samples of one full turn; "
                    "writes centre (hard iron) and symmetric matrix (soft iron) as JSON.")
    p.add_argument("data", help="CSV with columns t,mag_x,mag_y (any units)")
    p.add_argument("--out", required=True, help="calibration JSON to write")
    p.add_argument("--min-coverage-deg", type=Number(90.0, 360.0, "deg"), default=CalibrationLimits.min_coverage_deg,
                   help="refuse data covering less of the turn (default %(default)s)")
    p.add_argument("--min-points", type=Number(6, 1_000_000, "samples", integer=True),
                   default=CalibrationLimits.min_points,
                   help="refuse fewer finite samples (default %(default)s; an ellipse needs at least 6)")
    p.add_argument("--heading-offset-deg", type=Number(-180.0, 180.0, "deg"), default=0.0,
                   help="declination + mounting offset added to the heading (not observable from the data)")
    p.set_defaults(func=run)


def load_mag_csv(path: str | Path, notes: list[str] | None = None) -> tuple[list[float], list[float], list[float], int]:
    """Read t, mag_x, mag_y; returns (t, x, y, rows_skipped). The first few skipped rows are
    described in `notes` (line and reason). Raises DataError naming the file (and line) when the
    header lacks a column or more than MAX_SKIPPED_FRACTION of the rows cannot be read."""
    path = Path(path)
    text = read_text(path, DataError, "magnetometer CSV", MAX_DATA_BYTES)
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = [c.strip() for c in next(reader)]
    except StopIteration:
        raise DataError(f"{path}: empty file (expected a header row {','.join(REQUIRED_COLUMNS)})") from None
    except csv.Error as exc:
        raise DataError(f"{path}, line 1: not a CSV header ({exc})") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in header]
    if missing:
        shown = ",".join(header)[:120] or "none"
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {shown}); "
                        f"need {','.join(REQUIRED_COLUMNS)}")
    cols = [header.index(c) for c in REQUIRED_COLUMNS]
    limits = (MAX_TIME_S, MAX_FIELD, MAX_FIELD)
    t, x, y, skipped, rows = [], [], [], 0, 0
    first_bad: list[str] = []
    line = 1
    try:
        for line, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            rows += 1
            why = _unreadable(row, header, cols, limits)
            if why:
                skipped += 1
                if len(first_bad) < _SHOWN:
                    first_bad.append(f"line {line}: {why}")
                continue
            t.append(float(row[cols[0]]))
            x.append(float(row[cols[1]]))
            y.append(float(row[cols[2]]))
    except csv.Error as exc:
        raise DataError(f"{path}, line {line + 1}: not CSV ({exc})") from None
    if notes is not None:
        notes.extend(first_bad)
    if rows and skipped > MAX_SKIPPED_FRACTION * rows:
        raise DataError(f"{path}: {skipped} of {rows} rows cannot be read (first: {first_bad[0]}); more than "
                        f"{MAX_SKIPPED_FRACTION:.0%} is a damaged file, not a record with a few bad lines")
    return t, x, y, skipped


def _unreadable(row: list[str], header: list[str], cols: list[int], limits: tuple[float, ...]) -> str:
    """Why a row cannot be used ('' when it can)."""
    if len(row) < len(header):
        return f"{len(row)} fields, the header has {len(header)}"
    for j, limit in zip(cols, limits):
        cell = row[j].strip()
        try:
            v = float(cell)
        except ValueError:
            return f"{header[j]} {cell[:20]!r} is not a number"
        if not math.isfinite(v) or abs(v) > limit:
            return f"{header[j]} {cell[:20]} is not a finite number within {limit:g}"
    return ""


def load_mag_calibration(path: str | Path) -> MagCalibration:
    """Read a calibration JSON written by `lotsen calibrate-mag`."""
    return MagCalibration.from_dict(read_json(path, DataError), where=str(path))


def run(args: argparse.Namespace) -> int:
    check_outputs((args.out,), (args.data,), DataError)
    notes: list[str] = []
    t, x, y, skipped = load_mag_csv(args.data, notes)
    for note in notes:
        print(f"calibrate-mag: {args.data}: skipped {note}", file=sys.stderr)
    # how many, always, before the fit: the answer rests on the rows that remain
    read = len(x) + skipped
    if skipped:
        print(f"calibrate-mag: {args.data}: {skipped} of {read} rows skipped (unreadable), {len(x)} used",
              file=sys.stderr)
    limits = CalibrationLimits(min_points=args.min_points, min_coverage_deg=args.min_coverage_deg)
    try:
        cal = fit_mag_calibration(x, y, limits, heading_offset_rad=math.radians(args.heading_offset_deg))
    except DataError as exc:
        why = f" ({skipped} of {read} rows were unreadable and skipped)" if skipped else ""
        raise type(exc)(f"{args.data}: {exc}{why}") from None
    out = write_output(args.out, json.dumps(cal.to_dict(), indent=2) + "\n", (args.data,), DataError, "calibration")
    (c0, c1), ((a, b), (_, d)) = cal.center, cal.matrix
    print(f"{len(x)} samples ({skipped} rows skipped) over {t[-1] - t[0]:.1f} s: coverage {cal.coverage_deg:.0f} deg, "
          f"residual RMS {cal.residual_rms:.4f} of the field ({cal.residual_rms * cal.radius:.3g} units)")
    print(f"center = [{c0:.4g}, {c1:.4g}], matrix = [[{a:.4g}, {b:.4g}], [{b:.4g}, {d:.4g}]]")
    print(f"wrote {out}")
    return 0
