"""`lotsen identify DATA.csv|RUN.mcap [...] --out params.json`: grey-box identification with report.

Method (docs/sysid.md, "Estimation"): by default multiple shooting over the whole record
(lotsen.sysid.multiple), the estimate whose intervals reach the record's Cramer-Rao bound;
`--method single` runs the older single shooting in 10 s windows (kept for comparison).

Scale: the common scale of M, damping and thrust is unidentifiable from motion data. If none of
those parameters is given with --fix, the command fixes m11 = 14.0 kg (weighed 13 kg plus about
8 % surge added mass, the project's default) and prints a loud warning; pass --fix m11=... (or
mu_az from a bollard-pull test) to set it from your own knowledge, or --no-default-scale to refuse.
Every other parameter is estimated unless fixed.

The command builds one `IdentificationProblem` from the flags and files (`_problem`), hands it to
`lotsen.sysid.identify.identify` (the lab loop and the benches do the same) and writes the answer
(`_answer`): the best predictor of the held-out data among the estimates, ok / weak when it is the
physical one, predictive (exit 0) when effective coefficients predict measurably better than the
model in use, refused otherwise (lotsen.sysid.judge).

Refused with a clear error (exit 2, nothing written): unreadable or non-finite data, a column never
measured, time going backwards, no excitation (all inputs zero, a boat that did not move), a record
whose identification would take more than --max-cpu (the time expected is said first), and data that
leave a parameter direction unidentifiable for the only estimator (fix those parameters with --fix).
Refused with a verdict (exit 1, the file written and marked "verdict": "refused", which every loader
refuses): no estimate predicts the held-out data measurably better than the model in use and the
physical checks fail (no convergence, a coefficient at its physical bound, a track the model does not
explain, intervals too wide).

Validation: files given with --validate; otherwise the last `--holdout` fraction (default 0.2) of
every file is held out (not used for estimation). --holdout 0 uses all data for estimation and
validates on it (the report says so). Progress bars are shown only when stderr is a terminal.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

from lotsen.cli.progress import progress_printer as _progress_printer
from lotsen.cli.workers import add_jobs_flag, keep_freed_memory, side_tasks, worker_pool
from lotsen.errors import ConfigError, LotsenError
from lotsen.files import check_outputs, write_output
from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, VesselParameters, load_parameter_file
from lotsen.runtime.config import VesselSection
from lotsen.settings import Number
from lotsen.sysid.estimate import SolverOptions, check_scale_fixed
from lotsen.sysid.identify import Prepared, estimation_windows, identify
from lotsen.sysid.judge import Identification, held_out_windows
from lotsen.sysid.problem import DEFAULT_BUDGET_CPU_S, IdentificationProblem, budget_refusal, held_out_split

SCALE_DEFAULT = ("m11", 14.0)
# Parameters that anchor the scale well when known (a fixed damping term such as Y_rv formally
# fixes it too, but is itself poorly known, so it does not stop the default m11).
SCALE_ANCHORS = ("m11", "m22", "m33", "mu_az", "mu_t")


def _ratio(text: str) -> float:
    """--reverse-thrust-ratio, within the range of `vessel.reverse_thrust_ratio`."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    lo, hi = next(f for f in dataclasses.fields(VesselSection) if f.name == "reverse_thrust_ratio").metadata["range"]
    if not lo <= v <= hi:
        raise argparse.ArgumentTypeError(f"{v:g} is outside {lo:g}-{hi:g} (astern thrust is at most the ahead thrust)")
    return v


_ANTENNA_M = Number(-1e3, 1e3, "m")  # finite; `vessel.gnss_antenna_m`'s own check: within 2 m of the origin
_NOISE_STD = Number(1e-6, 10.0)  # m, rad or rad/s: the output's unit


def _parse_antenna(text: str) -> tuple[float, float]:
    """--gnss-antenna X,Y, checked as `vessel.gnss_antenna_m` is."""
    parts = text.split(",")
    if len(parts) != 2:
        raise ConfigError(f"--gnss-antenna {text[:40]!r}: expected two numbers X,Y in metres")
    x, y = _ANTENNA_M.parse(parts[0], "--gnss-antenna X"), _ANTENNA_M.parse(parts[1], "--gnss-antenna Y")
    try:
        return VesselSection(gnss_antenna_m=(x, y)).gnss_antenna_m
    except ConfigError as exc:
        raise ConfigError(f"--gnss-antenna {text[:40]!r} (as {exc})") from None


def _parse_fix(items: list[str]) -> dict[str, float]:
    from lotsen.sysid.estimate import NAMES

    out: dict[str, float] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--fix {item!r}: expected NAME=VALUE, e.g. --fix m11=14.0")
        name, value = item.split("=", 1)
        name = name.strip()
        if name not in NAMES:
            raise ConfigError(f"--fix {item[:40]!r}: unknown parameter {name[:20]!r} (known: {', '.join(NAMES)})")
        # the coefficient's physical range, as in a parameter file
        out[name] = VesselParameters.__dataclass_fields__[name].metadata["number"].parse(value, f"--fix {name}")
    return out


def _parse_noise(items: list[str]) -> dict[str, float]:
    out: dict[str, float] = {}
    for item in items:
        name, _, value = item.partition("=")
        if not name.strip() or not value:
            raise ConfigError(f"--noise {item[:40]!r}: expected OUTPUT=STD with a positive number, e.g. --noise r=0.003")
        out[name.strip()] = _NOISE_STD.parse(value, f"--noise {name.strip()[:20]}")
    return out


def _cmd_identify(args: argparse.Namespace) -> int:
    """`lotsen identify`: the problem from the flags and files, `identify(problem)`, the answer written."""
    problem, warnings, records = _problem(args)
    say = _progress_printer(f"identify ({'lake, ' if args.lake else ''}{args.method} shooting)")
    keep_freed_memory()
    # what depends on the records alone and is wanted only later is made beside the estimators, forked
    # before the workers (which it does not need): the prediction windows (0.13 s on the 10-min records,
    # wanted after the equation-error fit and by the judge) at once, then the sea state (0.2 s, it reads
    # every IMU row; wanted by the judge) at a lower priority
    soon = (lambda: estimation_windows(problem), lambda: held_out_windows(problem))
    with side_tasks(args.jobs, soon, (lambda: _sea_state(records),)) as (windows, held_out, sea), \
            worker_pool(args.jobs, lambda: _warm_kernels(problem)) as parallel:
        ident = identify(problem, say, parallel, Prepared(lambda: _said(sea()), windows, held_out))
    return _answer(args, dataclasses.replace(problem, sea=ident.sea), ident, warnings)


def _warm_kernels(problem: IdentificationProblem) -> None:
    """The compiled kernels the estimators run, built before the workers are forked (they inherit them)."""
    from lotsen.model import geometry_tuple
    from lotsen.sysid.kernels import step_kernels

    step_kernels(geometry_tuple(problem.geometry), lake=problem.lake)


def _problem(args: argparse.Namespace) -> tuple[IdentificationProblem, list[str], list]:
    """The identification problem the flags and files describe (its sea state not yet known: `_sea_state`
    of the records), the warnings to report and the estimation records; the files first (a bad file is
    reported before any warning about the estimate), the time it will take said before any work, and
    refused when over the budget (--max-cpu)."""
    from lotsen.sysid.data import load_record, register_loader

    antenna = _parse_antenna(args.gnss_antenna) if args.gnss_antenna else (0.0, 0.0)
    # the project's own run logs (the same path as `lotsen export`), the fixes moved to the hull's origin
    register_loader(".mcap", lambda path: _run_log_record(path, antenna))
    fixed = _parse_fix(args.fix or [])
    provenance = {n: "--fix" for n in fixed}
    noise = _parse_noise(args.noise or [])
    inputs = (*args.data, *(args.validate or ()), args.init, args.in_use)
    check_outputs((args.out, args.report), inputs, ConfigError)  # never over a record (it was, exit 1)
    init = load_parameter_file(args.init) if args.init else None
    in_use = load_parameter_file(args.in_use) if args.in_use else init
    records = [_with_kind(load_record(p), args.inputs) for p in args.data]
    validation = [_with_kind(load_record(p), args.inputs) for p in args.validate] if args.validate else None
    args.recorded_on = _recorded_on([*args.data, *(args.validate or [])])
    args.inputs_checked = inputs
    warnings = [f"initial guess {init.describe()}"] if init is not None and init.defaults_for else []
    if not any(n in fixed for n in SCALE_ANCHORS):
        if args.no_default_scale:
            check_scale_fixed(fixed)
        fixed[SCALE_DEFAULT[0]] = SCALE_DEFAULT[1]
        provenance[SCALE_DEFAULT[0]] = "the default scale (weighed 13 kg + surge added mass)"
        msg = ("WARNING: nothing fixes the common scale of mass, damping and thrust (unidentifiable from motion "
               f"data); fixing m11 = {SCALE_DEFAULT[1]} kg (weighed 13 kg + surge added mass). All of M, damping, "
               "C_N, mu_az, mu_t scale with this choice. Use --fix m11=... or --fix mu_az=... to set it.")
        print(msg, file=sys.stderr)
        warnings.append(msg)
    est, val, judged_on, held_out = held_out_split(records, validation, args.holdout)
    if not held_out:
        warnings.append("validation on the estimation data (--holdout 0): fit figures are optimistic")
    solver = SolverOptions(gap_s=args.gap, noise_std=noise, max_iterations=args.max_iter, window_s=args.window,
                           node_s=args.node, estimate_noise=not args.fixed_noise, gust_std=args.gust_std,
                           gyro_bias=True if args.gyro_offset else None, gyro_offset_block_s=args.gyro_offset_block)
    problem = IdentificationProblem(
        est, val, fixed, provenance, dataclasses.replace(DEFAULT_GEOMETRY, reverse_thrust_ratio=args.reverse_thrust_ratio),
        init.parameters if init else DEFAULT_PARAMETERS, in_use.parameters if in_use else None, args.lake,
        _parse_terms(args.terms), args.method, judged_on, held_out, solver)
    print(f"identify: {problem.n_rows} rows, judged on {judged_on}: expect about "
          f"{max(problem.expected_cpu_s(), 1.0):.0f} s of CPU", file=sys.stderr)
    too_long = budget_refusal(problem, args.max_cpu)
    if too_long:
        raise ConfigError(too_long)
    return problem, warnings, records


def _said(sea):  # type: ignore[no-untyped-def]
    """The sea state, printed when known."""
    if sea is not None:
        from lotsen.sysid.waves import describe

        print(f"sea state: {describe(sea)}", file=sys.stderr)
    return sea


def _answer(args: argparse.Namespace, problem: IdentificationProblem, ident: Identification,
            warnings: list[str]) -> int:
    """The parameter file, the report and the words on stderr; the exit code the README gives (0 for
    ok, weak and predictive; 1 for refused, the file written and marked so)."""
    res = ident.result
    for d in res.identifiability.directions:
        print(f"identifiability: {d}", file=sys.stderr)
    if ident.undetermined:
        warnings.append("undetermined (no interval given): " + ", ".join(f"{n} ({w})" for n, w in ident.undetermined.items()))
    if ident.at_bounds:
        msg = "WARNING: at a physical bound (undetermined: no interval): " + ", ".join(ident.at_bounds)
        print(msg, file=sys.stderr)
        warnings.append(msg)
    out = ident.to_json_dict()
    if args.recorded_on:
        out["recorded_on"] = args.recorded_on
    _print_environment(ident)
    write_output(args.out, json.dumps(out, indent=2) + "\n", args.inputs_checked, ConfigError, "parameter file")
    how = (f"{ident.estimator}, {res.iterations} iterations, s^2 = {res.noise_factor:.3g}"
           if ident.estimator != "equation error" else "equation error: the equations of motion fitted to the record")
    print(f"{args.out}: {len(res.free_names)} parameters estimated ({how})", file=sys.stderr)
    for n in res.free_names:
        v, sd = getattr(res.params, n), res.std[n]
        if n in ident.undetermined:
            print(f"  {n:6s} {v: .6g}  undetermined ({ident.undetermined[n]})", file=sys.stderr)
        else:
            print(f"  {n:6s} {v: .6g} +- {1.96 * sd:.3g} (95 %, {196 * sd / abs(v):.2g} %)", file=sys.stderr)
    if ident.prediction:
        _print_prediction(ident)
    for a in ident.advice:
        print(f"advice: {a}", file=sys.stderr)
    if args.report:
        _write_report(args, ident, problem, warnings)
    verdict = ident.verdict
    if verdict.verdict == "predictive":
        print(f"verdict: predictive — effective coefficients ({ident.estimator}): use them to predict and "
              "control this boat, not as its physical values (the loaders accept the file, the page labels it):",
              file=sys.stderr)
        for r in verdict.reasons:
            print(f"  - {r}", file=sys.stderr)
        return 0
    if verdict.verdict == "refused":
        print(f"REFUSED: these coefficients must not be used ({args.out} is marked refused and the loaders "
              "refuse it):", file=sys.stderr)
        for r in verdict.reasons:
            print(f"  - {r}", file=sys.stderr)
        return 1
    if verdict.weakly_determined:
        print(f"verdict: weak — usable, but weakly determined: {', '.join(verdict.weakly_determined)}", file=sys.stderr)
    else:
        print("verdict: ok", file=sys.stderr)
    return 0


def _print_environment(ident: Identification) -> None:
    """A lake answer's current and wind, the gust models' difference and the gyro offsets, in words."""
    sh = ident.estimate.shooting
    if sh is None:
        return
    env = sh.environment
    if env is not None:
        cn, ce = env.current_ne
        wn, we = env.wind_ne
        print(f"environment: current {math.hypot(cn, ce):.3f} m/s towards {math.degrees(math.atan2(ce, cn)) % 360:.0f} "
              f"deg, wind {math.hypot(wn, we):.1f} m/s from {math.degrees(math.atan2(-we, -wn)) % 360:.0f} deg; "
              f"intervals from the residuals' own correlation (sandwich; residuals correlated over up to "
              f"{env.autocorrelation_factor:.0f} samples)", file=sys.stderr)
    shift = sh.gust_interval_shift
    if shift:
        moved = sorted((n for n in shift if abs(shift[n]) > 1.0), key=lambda n: -abs(shift[n]))
        print("gust model: with the gusts cut into longer intervals the coefficients move "
              + (", ".join(f"{n} {shift[n]:+.1f} sigma" for n in moved) if moved else "by less than 1 sigma each")
              + "; the answer is the average of the two, its intervals include the difference", file=sys.stderr)
    if sh.gyro_bias is not None and sh.gyro_bias_std is not None and sh.gyro_bias_record is not None:
        per_record = [(q, sh.gyro_bias_record == q) for q in sorted(set(sh.gyro_bias_record.tolist()))]
        print("gyro offset (rad/s): " + "; ".join(
            f"record {q + 1}: " + ", ".join(f"{b:+.4f}" for b in sh.gyro_bias[on])
            + f" (+- {float(sh.gyro_bias_std[on].max()):.4f})" for q, on in per_record), file=sys.stderr)


def _parse_terms(text: str) -> tuple[str, ...] | None:
    """--terms: auto (None: chosen by held-out prediction), none, or names of optional model terms."""
    from lotsen.model.parameters import OPTIONAL_TERMS

    if text == "auto":
        return None
    if text == "none":
        return ()
    names = tuple(t.strip() for t in text.split(",") if t.strip())
    unknown = [n for n in names if n not in OPTIONAL_TERMS]
    if unknown or not names:
        raise ConfigError(f"--terms {text!r}: expected auto, none or a comma list of optional model terms "
                          f"({', '.join(OPTIONAL_TERMS)})")
    return names


def _print_prediction(ident) -> None:  # type: ignore[no-untyped-def]
    """The held-out prediction errors of every model compared, in metres and degrees."""
    first = next(iter(ident.prediction.values()))
    hs = first.horizons_s
    print(f"open-loop prediction of the held-out data ({first.n_windows} windows; RMS error after "
          + ", ".join(f"{h:g}" for h in hs) + " s):", file=sys.stderr)
    for name, sc in ident.prediction.items():
        mark = " <- written" if name == ident.chosen else ""
        print(f"  {name:15s} " + "  ".join(f"{sc.position_m[h]:6.2f} m {sc.heading_deg[h]:5.1f} deg" for h in hs)
              + ("" if sc.stable else "  (diverges)") + mark, file=sys.stderr)
    held = ident.held_out_score
    if held is not None and held.n_windows and held.horizons_s == hs:
        print(f"  {'the answer':15s} " + "  ".join(f"{held.position_m[h]:6.2f} m {held.heading_deg[h]:5.1f} deg"
                                                   for h in hs)
              + "  (each half of the windows by the estimate chosen on the other half)", file=sys.stderr)
    print(f"  judged on {ident.judged_on}", file=sys.stderr)


def _write_report(args: argparse.Namespace, ident: Identification, problem: IdentificationProblem,
                  warnings: list[str]) -> None:
    from lotsen.sysid.report import Report, render_pdf, render_report

    sources = [f"{p} (recorded on {args.recorded_on[str(p)]})" if str(p) in args.recorded_on else str(p)
               for p in args.data]
    report = Report.of(ident, problem, sources, warnings)
    pdf = Path(args.report).suffix.lower() == ".pdf"
    write_output(args.report, render_pdf(report) if pdf else render_report(report), args.inputs_checked,
                 ConfigError, "report")
    print(f"{args.report}: written" + ("" if report.fit_val else " (no validation data)"), file=sys.stderr)


def _run_log_record(path: Path, antenna: tuple[float, float]):  # type: ignore[no-untyped-def]
    """A run log's identification record. The log reader (MCAP, the wire codec) is imported only for a
    run log: a CSV record does not pay for it."""
    from lotsen.logs.export import sysid_record

    return sysid_record(path, gnss_antenna_m=antenna)


def _recorded_on(paths: list[str]) -> dict[str, str]:
    """Run logs' boats as their recorder named them (lotsen.logs.export.recorded_on), printed: the
    report and the parameter file name the boat (its parameter file) the records are of."""
    boats = {}
    for p in paths:
        if Path(p).suffix.lower() != ".mcap":
            continue
        from lotsen.logs.export import recorded_on

        boat = recorded_on(p)
        if boat:
            boats[str(p)] = boat
            print(f"{p}: recorded on {boat}", file=sys.stderr)
    return boats


def _sea_state(records):  # type: ignore[no-untyped-def]
    """The highest sea among the records' own IMU estimates (None: no record has IMU columns)."""
    from lotsen.harness.identification import record_sea_state

    seas = [s for s in (record_sea_state(r) for r in records) if s is not None]
    return max(seas, key=lambda s: s.hs_m if s.valid and s.hs_m == s.hs_m else -1.0, default=None)


def _with_kind(record, kind: str | None):  # type: ignore[no-untyped-def]
    """The record with its input kind overridden by --inputs (None: as the file says)."""
    if kind is None:
        return record
    return dataclasses.replace(record, input_kind=kind)


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("identify", help="estimate the vessel parameters from experiment data")
    p.add_argument("data", nargs="+", help="data files: CSV (t,alpha1,alpha2,n1,n2,nt,north,east,psi,r[,u,v]; a row "
                                           "may carry only inputs or only outputs) or a run log RUN.mcap")
    p.add_argument("--out", required=True, help="parameter JSON to write (the 18 parameters + std)")
    p.add_argument("--inputs", choices=("held", "mean", "sample"), default=None,
                   help="how the input values are meant (default: as the file says, '# inputs: ...' in a CSV, "
                        "else held): held = commands (zero-order hold); mean / sample = achieved values logged "
                        "as interval means / point samples (reconstructed piecewise linearly; docs/sysid.md)")
    p.add_argument("--fix", action="append", metavar="NAME=VALUE", help="hold a parameter at a known value")
    p.add_argument("--method", choices=("multiple", "single"), default="multiple",
                   help="multiple shooting over the whole record (default) or single shooting in --window windows")
    p.add_argument("--node", type=Number(0.2, 60.0, "s"), default=2.0,
                   help="multiple shooting: interval length, s (default 2)")
    p.add_argument("--noise", action="append", metavar="OUTPUT=STD",
                   help="assumed noise std of an output (default north/east 0.01 m, psi 0.01 rad, r 0.003 rad/s)")
    p.add_argument("--fixed-noise", action="store_true",
                   help="keep the assumed noise std (default: re-estimate each output's from its residuals)")
    p.add_argument("--report", help="report to write: self-contained HTML (.html) or PDF (.pdf)")
    p.add_argument("--init", help="initial guess JSON (default: the documented defaults); the estimate starts from "
                                  "the equations of motion fitted to the record, so the answer does not depend on it")
    p.add_argument("--in-use", metavar="PARAMS.json",
                   help="the model the boat flies now, to compare predictions with (default: --init, else the "
                        "documented defaults)")
    p.add_argument("--validate", nargs="+", help="held-out validation data files")
    p.add_argument("--holdout", type=Number(0.0, 0.85), default=0.2, help="fraction of each file held out (default 0.2)")
    p.add_argument("--window", type=Number(1.0, 600.0, "s"), default=10.0,
                   help="single shooting and validation: simulation window length, s (default 10)")
    p.add_argument("--gap", type=Number(0.01, 3600.0, "s"), default=1.0,
                   help="a time gap longer than this splits a record, s")
    p.add_argument("--max-iter", type=Number(1, 1000, integer=True), default=60)
    p.add_argument("--terms", default="auto", metavar="auto|none|NAME[,NAME]",
                   help="optional model terms (X_uuu: surge resistance growing faster than speed squared): auto "
                        "(default) turns each on where the held-out prediction shows the record needs it")
    p.add_argument("--gyro-offset", action="store_true",
                   help="estimate the yaw rate's (r) offset with the coefficients, one per record and "
                        "--gyro-offset-block: a gyro's bias wanders (always on with --lake)")
    p.add_argument("--gyro-offset-block", type=Number(0.0, 86400.0, "s"), default=60.0, metavar="S",
                   help="one yaw-rate offset per this many seconds of a record (default 60; 0: one per record)")
    p.add_argument("--lake", action="store_true",
                   help="estimate a constant current, the wind (air velocity and drag coefficients) and a gust "
                        "factor per shooting interval with the parameters (records taken outside calm water); "
                        "estimated twice, with --node and 1.5 x --node gust intervals, and averaged over the two "
                        "(their difference is part of the intervals; twice the time)")
    p.add_argument("--gust-std", type=Number(0.01, 2.0), default=0.3,
                   help="with --lake: prior spread of the per-interval gust factor on the wind speed (default 0.3)")
    p.add_argument("--reverse-thrust-ratio", type=_ratio, default=1.0, metavar="R",
                   help="astern thrust / ahead thrust at equal propeller speed, as measured (bollard pull) or "
                        "configured (vessel.reverse_thrust_ratio; default 1)")
    p.add_argument("--gnss-antenna", metavar="X,Y",
                   help="the GNSS antenna's body position from the model's origin, m (vessel.gnss_antenna_m; "
                        "default 0,0): run logs' fixes are moved to the origin")
    p.add_argument("--max-cpu", type=Number(1.0, 86400.0, "s"), default=DEFAULT_BUDGET_CPU_S,
                   help="refuse, before any work, a record whose identification would take more CPU than this "
                        f"(default {DEFAULT_BUDGET_CPU_S:g} s); the time expected is printed first")
    p.add_argument("--no-default-scale", action="store_true",
                   help="refuse instead of fixing m11 when no scale parameter is fixed")
    add_jobs_flag(p, "the shooting intervals and the equation-error searches")
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
