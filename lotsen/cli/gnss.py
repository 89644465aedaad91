"""`lotsen gnss-replay CAPTURE.ubx`: the NAV-PVT fixes of a recorded receiver byte stream as CSV.

Columns `t,lat,lon,height,fix_type,h_acc`: t is the receiver's GPS time of week in seconds
(NAV-PVT iTOW) by default, or with `--time utc` the receiver's UTC time as POSIX seconds (empty
when the receiver had no valid date and time); lat/lon in degrees, height (ellipsoidal) and h_acc
in metres, fix_type the name of lotsen.messages.GnssFixType (RTK_FIXED, RTK_FLOAT, FIX_3D, ...).
The capture may mix UBX, NMEA, RTCM3 and garbage (e.g. `cat /dev/ttyAMA1 > capture.ubx`);
counts of what was skipped go to stderr. A NAV-PVT claiming a physically impossible fix (latitude
beyond 90 deg, zero accuracy, RTK fixed at metres, ...; `lotsen.drivers.ubx.implausible_fix`) is
refused as the driver refuses it: not in the CSV, named on stderr with its iTOW and the reason.
A capture without a single usable fix says so and exits 1 (the CSV holds only its header).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Iterator

from lotsen.errors import DataError
from lotsen.files import MAX_CAPTURE_BYTES, check_input_file, check_output, write_output

_MAX_REFUSALS_SHOWN = 20


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("gnss-replay", help="print the NAV-PVT fixes of a recorded UBX byte stream as CSV")
    p.add_argument("capture", help="file with the receiver's raw bytes (UBX, may contain NMEA/RTCM/garbage)")
    p.add_argument("--time", choices=("itow", "utc"), default="itow",
                   help="t column: GPS time of week in s (default) or UTC POSIX seconds")
    p.add_argument("--out", help="write the CSV here instead of standard output")
    p.set_defaults(func=run)


def _chunks(path: Path, size: int = 65536) -> Iterator[bytes]:
    with path.open("rb") as f:
        while chunk := f.read(size):
            yield chunk


def _num(v: float, fmt: str) -> str:
    return format(v, fmt) if math.isfinite(v) else ""


def run(args: argparse.Namespace) -> int:
    from lotsen.drivers.ubx import replay_stream

    path = Path(args.capture)
    if not path.exists():
        raise DataError(f"{path}: no such capture file")
    check_input_file(path, MAX_CAPTURE_BYTES, DataError, "capture file")
    if args.out:
        check_output(args.out, (path,), DataError, "CSV")
    try:
        result = replay_stream(_chunks(path))
    except OSError as exc:
        raise DataError(f"{path}: cannot read: {exc.strerror}") from None
    lines = ["t,lat,lon,height,fix_type,h_acc"]
    for pvt in result.fixes:
        f = pvt.fix
        if args.time == "utc":
            t = f"{pvt.utc.timestamp():.3f}" if pvt.utc is not None else ""
        else:
            t = f"{pvt.itow_s:.3f}"
        lines.append(f"{t},{_num(f.lat_deg, '.9f')},{_num(f.lon_deg, '.9f')},{_num(f.height_m, '.3f')},"
                     f"{f.fix_type.name},{_num(f.h_acc_m, '.3f')}")
    text = "\n".join(lines) + "\n"
    if args.out:
        write_output(args.out, text, (path,), DataError, "CSV")
    else:
        sys.stdout.write(text)
    c = result.counters
    print(f"gnss-replay: {len(result.fixes)} NAV-PVT fixes from {c.bytes_in} bytes; {c.ubx_frames} UBX, "
          f"{c.nmea_sentences} NMEA, {c.rtcm_frames} RTCM3 frames; {c.garbage_bytes} garbage bytes, "
          f"{c.bad_checksums} bad checksums, {result.undecodable} undecodable NAV-PVT, "
          f"{len(result.refused)} refused as physically impossible", file=sys.stderr)
    for pvt, why in result.refused[:_MAX_REFUSALS_SHOWN]:
        print(f"gnss-replay: refused NAV-PVT at iTOW {pvt.itow_s:.3f} s: {why}", file=sys.stderr)
    if len(result.refused) > _MAX_REFUSALS_SHOWN:
        print(f"gnss-replay: ... and {len(result.refused) - _MAX_REFUSALS_SHOWN} more refused", file=sys.stderr)
    if not result.fixes:
        print(f"gnss-replay: {path}: not one usable NAV-PVT fix in the capture", file=sys.stderr)
        return 1
    return 0
