"""`lotsen identify DATA.csv [...] --out params.json`: grey-box identification with report.

Scale: the common scale of M, damping and thrust is unidentifiable from motion data. If none of
those parameters is given with --fix, the command fixes m11 = 14.0 kg (weighed 13 kg plus about
8 % surge added mass, the project's default) and prints a loud warning; pass --fix m11=... (or
mu_az from a bollard-pull test) to set it from your own knowledge, or --no-default-scale to refuse.

Validation: files given with --validate; otherwise the last `--holdout` fraction (default 0.2) of
every file is held out (not used for estimation). --holdout 0 uses all data for estimation and
validates on it (the report says so).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from lotsen.errors import ConfigError, LotsenError
from lotsen.model import DEFAULT_PARAMETERS

SCALE_DEFAULT = ("m11", 14.0)
# Parameters that anchor the scale well when known (a fixed damping term such as Y_rv formally
# fixes it too, but is itself poorly known, so it does not stop the default m11).
SCALE_ANCHORS = ("m11", "m22", "m33", "mu_az", "mu_t")


def _parse_fix(items: list[str]) -> dict[str, float]:
    from lotsen.sysid.estimate import NAMES

    out: dict[str, float] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--fix {item!r}: expected NAME=VALUE, e.g. --fix m11=14.0")
        name, value = item.split("=", 1)
        name = name.strip()
        if name not in NAMES:
            raise ConfigError(f"--fix {item!r}: unknown parameter {name!r} (known: {', '.join(NAMES)})")
        try:
            out[name] = float(value)
        except ValueError:
            raise ConfigError(f"--fix {item!r}: {value!r} is not a number") from None
    return out


def _cmd_identify(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from lotsen.cli.experiment import load_params
    from lotsen.sysid.blackbox import fit_narx, narx_fit
    from lotsen.logs.export import sysid_loader
    from lotsen.sysid.data import load_record, register_loader
    from lotsen.sysid.estimate import estimate
    from lotsen.sysid.validate import inputs_at_outputs, residual_analysis, simulate_fit

    register_loader(".mcap", sysid_loader)  # the project's own run logs

    fixed = _parse_fix(args.fix or [])
    warnings: list[str] = []
    if not any(n in fixed for n in SCALE_ANCHORS):
        if args.no_default_scale:
            from lotsen.sysid.estimate import check_scale_fixed

            check_scale_fixed(fixed)
        fixed[SCALE_DEFAULT[0]] = SCALE_DEFAULT[1]
        msg = ("WARNING: nothing fixes the common scale of mass, damping and thrust (unidentifiable from motion "
               f"data); fixing m11 = {SCALE_DEFAULT[1]} kg (weighed 13 kg + surge added mass). All of M, damping, "
               "C_N, mu_az, mu_t scale with this choice. Use --fix m11=... or --fix mu_az=... to set it.")
        print(msg, file=sys.stderr)
        warnings.append(msg)
    theta0 = load_params(args.init) if args.init else DEFAULT_PARAMETERS
    records = [load_record(p) for p in args.data]
    if args.validate:
        est_records = records
        val_records = [load_record(p) for p in args.validate]
    elif args.holdout > 0:
        if not 0 < args.holdout < 0.9:
            raise ConfigError("--holdout must be between 0 and 0.9")
        est_records, val_records = [], []
        for r in records:
            t_split = r.t[0] + (1 - args.holdout) * r.duration_s
            est_records.append(r.slice(r.t[0], t_split))
            val_records.append(r.slice(t_split, r.t[-1] + 1))
    else:
        est_records = val_records = records
        warnings.append("validation on the estimation data (--holdout 0): fit figures are optimistic")
    bar = tqdm(file=sys.stderr, desc=f"identify ({args.method} shooting)", unit="it", total=None)

    def progress(i: int, cost: float) -> None:
        bar.update(1)
        bar.set_postfix(V=f"{cost:.5g}")

    if args.method == "single":
        res = estimate(est_records, theta0, fixed, window_s=args.window, gap_s=args.gap,
                       max_iterations=args.max_iter, progress=progress)
    else:
        from lotsen.sysid.multiple import estimate_multiple_shooting

        res = estimate_multiple_shooting(est_records, theta0, fixed, gap_s=args.gap, window_s=args.window,
                                         max_iterations=args.max_iter * 4, progress=progress)
    bar.close()
    for d in res.identifiability.directions:
        print(f"identifiability: {d}", file=sys.stderr)
    if res.identifiability.unidentifiable:
        msg = ("WARNING: the data leave some parameter direction unidentifiable (see above): those parameters keep "
               "values near their initial guess; fix them (--fix) or collect more exciting data")
        print(msg, file=sys.stderr)
        warnings.append(msg)
    if res.identifiability.poorly_determined:
        warnings.append("poorly determined (95 % relative error above 5 %): "
                        + ", ".join(res.identifiability.poorly_determined))
    Path(args.out).write_text(json.dumps(res.to_json_dict(), indent=2) + "\n")
    print(f"{args.out}: {len(res.free_names)} parameters estimated ({res.iterations} iterations, "
          f"s^2 = {res.noise_factor:.3g})", file=sys.stderr)
    if args.report:
        from lotsen.sysid.report import render_pdf, render_report

        fit_est = simulate_fit(res.params, est_records, args.window, args.gap)
        fit_val = simulate_fit(res.params, val_records, args.window, args.gap)
        narx = fit_narx(est_records, args.gap)
        bb = narx_fit(narx, val_records, args.window, args.gap)
        ra = residual_analysis(fit_val, inputs_at_outputs(val_records, args.window, args.gap))
        report_args = (res, [str(p) for p in args.data], fit_est, fit_val, bb, ra, warnings, theta0)
        if Path(args.report).suffix.lower() == ".pdf":
            Path(args.report).write_bytes(render_pdf(*report_args))
        else:
            Path(args.report).write_text(render_report(*report_args))
        print(f"{args.report}: validation fit " + ", ".join(f"{k} {v:.1f} %" for k, v in fit_val.fit_percent.items())
              + " (black-box: " + ", ".join(f"{k} {v:.1f} %" for k, v in bb.fit_percent.items()) + ")",
              file=sys.stderr)
    return 0


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("identify", help="estimate the vessel parameters from experiment data")
    p.add_argument("data", nargs="+", help="data files (CSV: t,alpha1,alpha2,n1,n2,nt,north,east,psi,r[,u,v])")
    p.add_argument("--out", required=True, help="parameter JSON to write (the 18 parameters + std)")
    p.add_argument("--fix", action="append", metavar="NAME=VALUE", help="hold a parameter at a known value")
    p.add_argument("--method", choices=("single", "multiple"), default="single")
    p.add_argument("--report", help="report to write: self-contained HTML (.html) or PDF (.pdf)")
    p.add_argument("--init", help="initial guess JSON (default: the documented defaults)")
    p.add_argument("--validate", nargs="+", help="held-out validation data files")
    p.add_argument("--holdout", type=float, default=0.2, help="fraction of each file held out (default 0.2)")
    p.add_argument("--window", type=float, default=10.0, help="simulation window length, s (default 10)")
    p.add_argument("--gap", type=float, default=1.0, help="a time gap longer than this splits a record, s")
    p.add_argument("--max-iter", type=int, default=60)
    p.add_argument("--no-default-scale", action="store_true",
                   help="refuse instead of fixing m11 when no scale parameter is fixed")
    p.set_defaults(func=_cmd_identify)


def main_standalone(argv: list[str] | None = None) -> int:  # for use before lotsen.cli.main exists
    parser = argparse.ArgumentParser(prog="lotsen")
    sub = parser.add_subparsers(dest="command", required=True)
    register(sub)
    from lotsen.cli import experiment

    experiment.register(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except LotsenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main_standalone())
