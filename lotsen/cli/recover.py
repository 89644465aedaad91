"""`lotsen recover RUN.mcap [--out FIXED.mcap]`: a killed recording -> a complete, indexed MCAP.

A run killed with SIGKILL (or a power cut, a full disk) leaves a file without summary and footer
that Foxglove and other seeking readers refuse. This reads it as a stream and writes everything
intact to a new file with index and summary (lotsen.logs.recover); the original is not touched.
`lotsen recover LOGDIR` recovers every unclosed file of a log directory as `lotsen run` does at
start (X.mcap -> X.recovered.mcap, the original renamed X.mcap.unclosed).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from lotsen.errors import DataError
from lotsen.files import MAX_LOG_BYTES, check_input_file, check_output


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("recover", help="make a killed/unclosed MCAP recording readable (index + summary)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", help="the unclosed .mcap file, or a log directory")
    p.add_argument("--out", help="output file (default: LOG with .recovered.mcap); not for a directory")
    p.add_argument("--force", action="store_true",
                   help="rewrite even a complete file, and overwrite an existing --out")
    p.add_argument("--json", action="store_true", help="print the recovery statistics as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lotsen.logs.recover import needs_recovery, recover_directory, recover_mcap, recovered_path

    src = Path(args.log)
    if src.is_dir():
        if args.out:
            raise DataError(f"{src}: --out is for a single file; a directory is recovered in place")
        results = recover_directory(src)
        if args.json:
            print(json.dumps([r.to_dict() for r in results], indent=1))
        else:
            for r in results:
                print(r.summary_line())
            if not results:
                print(f"{src}: no unclosed recordings")
        return 1 if any(r.error or r.nothing_recovered for r in results) else 0
    if not src.exists():
        raise DataError(f"{src}: no such log file")
    check_input_file(src, MAX_LOG_BYTES, DataError, "log file")
    dst = Path(args.out) if args.out else recovered_path(src)
    check_output(dst, (src,), DataError, "recovered file")
    if not args.force:
        try:
            complete = not needs_recovery(src)
        except OSError as exc:
            raise DataError(f"{src}: cannot read: {exc.strerror or exc}") from None
        if complete:
            print(f"{src}: complete (indexed, with summary); nothing to recover (--force rewrites it)")
            return 0
        if dst.exists():
            raise DataError(f"{dst}: exists; choose another --out or add --force")
    existed = dst.exists()
    stats = recover_mcap(src, dst)
    if stats.nothing_recovered and not existed:
        dst.unlink(missing_ok=True)  # an output with no message in it is no recovery
    if args.json:
        print(json.dumps({**stats.to_dict(), "nothing_recovered": stats.nothing_recovered}, indent=1))
    else:
        print(stats.summary_line())
        for problem in stats.problems:
            print(f"  {problem}")
    if stats.nothing_recovered:
        print(f"{src}: nothing could be recovered: not one readable message in {stats.source_bytes} bytes"
              + ("" if existed else f" ({dst} not written)"), file=sys.stderr)
        return 1
    return 0
