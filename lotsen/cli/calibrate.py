"""`lotsen calibrate-mag DATA.csv --out mag.json`: planar magnetometer calibration from one turn.

DATA.csv has a header with (at least) the columns `t,mag_x,mag_y` in any consistent units; rows
with empty or non-numeric values are skipped and counted. The JSON written holds `center` (2),
`matrix` (2x2, maps the unit circle onto the ellipse), `residual_rms`, `coverage_deg`,
`n_points` and `heading_offset_rad` (declination / mounting offset: not determinable from the
magnetometer, set by `--heading-offset-deg`).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
from pathlib import Path

from lotsen.files import read_json, read_text
from lotsen.errors import DataError
from lotsen.fusion.magcal import CalibrationLimits, MagCalibration, fit_mag_calibration

REQUIRED_COLUMNS = ("t", "mag_x", "mag_y")


def register(subparsers) -> None:  # type: ignore[no-untyped-def]
    p = subparsers.add_parser(
        "calibrate-mag", help="fit the magnetometer's hard/soft iron from one full turn (seed 3.3)",
        description="Least-squares ellipse fit to the horizontal magnetometer samples of one full turn; "
                    "writes centre (hard iron) and symmetric matrix (soft iron) as JSON.")
    p.add_argument("data", help="CSV with columns t,mag_x,mag_y (any units)")
    p.add_argument("--out", required=True, help="calibration JSON to write")
    p.add_argument("--min-coverage-deg", type=float, default=CalibrationLimits.min_coverage_deg,
                   help="refuse data covering less of the turn (default %(default)s)")
    p.add_argument("--min-points", type=int, default=CalibrationLimits.min_points,
                   help="refuse fewer finite samples (default %(default)s)")
    p.add_argument("--heading-offset-deg", type=float, default=0.0,
                   help="declination + mounting offset added to the heading (not observable from the data)")
    p.set_defaults(func=run)


def load_mag_csv(path: str | Path) -> tuple[list[float], list[float], list[float], int]:
    """Read t, mag_x, mag_y; returns (t, x, y, rows_skipped). Raises DataError naming file and row."""
    path = Path(path)
    text = read_text(path, DataError, "magnetometer CSV")
    reader = csv.DictReader(text.splitlines())
    cols = [c.strip() for c in (reader.fieldnames or [])]
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(missing)} (header: {','.join(cols) or 'none'}); "
                        f"need {','.join(REQUIRED_COLUMNS)}")
    reader.fieldnames = cols
    t, x, y, skipped = [], [], [], 0
    for row in reader:
        try:
            vals = [float(row[c]) for c in REQUIRED_COLUMNS]
        except (TypeError, ValueError):
            skipped += 1
            continue
        if not all(math.isfinite(v) for v in vals):
            skipped += 1
            continue
        t.append(vals[0])
        x.append(vals[1])
        y.append(vals[2])
    return t, x, y, skipped


def load_mag_calibration(path: str | Path) -> MagCalibration:
    """Read a calibration JSON written by `lotsen calibrate-mag`."""
    return MagCalibration.from_dict(read_json(path, DataError), where=str(path))


def run(args: argparse.Namespace) -> int:
    t, x, y, skipped = load_mag_csv(args.data)
    limits = CalibrationLimits(min_points=args.min_points, min_coverage_deg=args.min_coverage_deg)
    try:
        cal = fit_mag_calibration(x, y, limits, heading_offset_rad=math.radians(args.heading_offset_deg))
    except DataError as exc:
        raise type(exc)(f"{args.data}: {exc}") from None
    out = Path(args.out)
    try:
        out.write_text(json.dumps(cal.to_dict(), indent=2) + "\n", encoding="utf-8")
    except OSError as exc:
        raise DataError(f"{out}: cannot write ({exc.strerror})") from None
    (c0, c1), ((a, b), (_, d)) = cal.center, cal.matrix
    print(f"{len(x)} samples ({skipped} rows skipped) over {t[-1] - t[0]:.1f} s: coverage {cal.coverage_deg:.0f} deg, "
          f"residual RMS {cal.residual_rms:.4f} of the field ({cal.residual_rms * cal.radius:.3g} units)")
    print(f"center = [{c0:.4g}, {c1:.4g}], matrix = [[{a:.4g}, {b:.4g}], [{b:.4g}, {d:.4g}]]")
    print(f"wrote {out}")
    return 0
