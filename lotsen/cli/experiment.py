"""`lotsen experiment run|check|design`: identification experiments on the simulator (or, later, the boat).

`run --sim` drives `lotsen.sim.Simulator` (sensors on) with the experiment's input generator and
writes the measured data as the identification CSV (docs/sysid.md, "Simulated runs"):
  - rows at the command ticks (20 Hz default) and at every GNSS fix; the inputs of a row are the
    mean achieved actuator values over the interval to the next row (what a tachometer's pulse
    count over its window measures), so the identification's zero-order hold sees no lag error;
  - north/east: the GNSS fix converted to local NED around the GnssConfig origin (model.geodetic),
    only on rows with a fix (8 Hz); psi: the true heading plus white noise (`psi_noise_rad`,
    default 0.01 rad, a calibrated compass / fused heading), r: the gyro's z rate minus its bias
    estimated over a 2 s rest before the run (the residual bias walk stays in the data);
    psi and r are written on the GNSS rows only (8 Hz outputs).
`run --hardware [--emulated]` runs the same input generator through the runtime on the boat's
drivers (or their emulated twins): lotsen.stack.experiment documents what it records.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from lotsen.cli.mission import waves_flag
from lotsen.errors import ConfigError, LotsenError
from lotsen.files import atomic_output, check_outputs, write_output
from lotsen.harness.identification import lake_run, run_on_simulator
from lotsen.model import DEFAULT_PARAMETERS, VesselModel, VesselParameters
from lotsen.physics.config import address_flag as physics_address
from lotsen.settings import SEED, Number
from lotsen.sysid.data import save_csv
from lotsen.sysid.experiment import DESIGNED_FOR, Experiment, check_experiment, designed_for, load_experiment

#: the area check's margin inside the experiment's area
MARGIN = Number(0.0, 100.0, "m")
#: a designed experiment's input levels (duration / segment): beyond this the design runs for hours
MAX_DESIGN_SEGMENTS = 200
#: one side of a designed experiment's area (the area check's own limit: 2 km)
AREA_SIDE = Number(2.0, 2000.0, "m")


def load_params(path: str | None) -> VesselParameters:
    from lotsen.stack.stack import load_parameters  # the one loader (refuses a refused verdict)

    return load_parameters(path) if path else DEFAULT_PARAMETERS


def parse_area(text: str) -> tuple[float, float]:
    parts = text.lower().split("x")
    if len(parts) != 2:
        raise ConfigError(f"--area {text[:40]!r}: expected NORTHxEAST in metres, e.g. 30x30")
    return AREA_SIDE.parse(parts[0], "--area NORTH"), AREA_SIDE.parse(parts[1], "--area EAST")


def _parameter_names(text: str | None) -> tuple[str, ...] | None:
    """--fixed NAME,NAME: known coefficient names only."""
    if text is None:
        return None
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in VesselParameters.names()]
    if unknown or not names:
        raise ConfigError(f"--fixed {text[:60]!r}: {'unknown coefficient(s) ' + ', '.join(unknown[:5]) if unknown else 'no name'} "
                          f"(known: {', '.join(VesselParameters.names())})")
    return names


def _run_inputs(args: argparse.Namespace, config_files: tuple[str, ...] = ()) -> tuple[str | None, ...]:
    """The files `experiment run` reads: none of them may be its output."""
    return (args.experiment, args.config, args.params, args.model_params,
            None if args.boat == "ideal" else args.boat, *config_files)


def _area_advice(exp: Experiment, params: str | None) -> str:
    """What to say when the area check, predicting with the defaults (no `params`), refuses `exp`: a
    design for an identified model (`design --params P`) keeps P's predicted track inside the area, not
    the defaults', so the check must predict with the model it was designed for."""
    if params:
        return ""
    p = designed_for(exp) or "P.json"
    return (f" The prediction used the default coefficients; an experiment designed for another model "
            f"(`experiment design --params {p}`) is checked and run with the same --params {p}")


def _cmd_run(args: argparse.Namespace) -> int:
    from lotsen.stack.stack import example_or_file

    # a bare NAME is the example experiment of that name (examples/experiments/NAME.yaml), from any folder
    args.experiment = example_or_file(args.experiment, "experiments")
    exp = load_experiment(args.experiment)
    if args.physics:
        if args.hardware:
            raise ConfigError("--physics replaces the simulated boat; it cannot run with --hardware")
        if args.boat:
            raise ConfigError("--boat: with --physics the boat is the physics server's")
        if Path(args.out).suffix != ".mcap":
            raise ConfigError(f"--out {args.out}: with --physics the run is recorded on the stack: give RUN.mcap "
                              "(lotsen identify reads it)")
        args.sim = True
    if args.hardware and Path(args.out).suffix.lower() == ".mcap":
        raise ConfigError(f"--out {args.out}: with --hardware the record is written as CSV (give RUN.csv; the "
                          "recorder's MCAP of the run lands in the log folder)")
    if args.sim == args.hardware:
        raise LotsenError("say where to run, once: --sim (simulated boat), --physics udp:HOST:PORT (an external "
                          "physics) or --hardware [--emulated] (the boat's drivers)")
    if args.emulated and not args.hardware:
        raise LotsenError("--emulated is for --hardware (the drivers' emulated twins); --sim runs the simulated boat")
    if args.waves is not None and (args.hardware or args.physics):
        raise ConfigError("--waves: only the simulated boat's sea can be set (the lake and an external physics have "
                          "their own)")
    check_outputs((args.out,), _run_inputs(args), ConfigError)
    if args.config:  # read and checked whatever the run uses of it: a bad file is never ignored
        from lotsen.stack.config import load_stack_config

        load_stack_config(args.config)
    model = VesselModel(load_params(args.params))
    check_experiment(exp, VesselModel(load_params(args.model_params)) if args.model_params else model,
                     margin_m=args.margin, area_advice=_area_advice(exp, args.params or args.model_params))
    out = Path(args.out)
    if args.sim and out.suffix == ".mcap":  # the lab loop: the stack, its recorder, an MCAP to identify
        from dataclasses import replace

        from lotsen.cli.mission import check_physics_answered
        from lotsen.cli.run import with_model_and_boat, with_physics, with_waves
        from lotsen.harness.lab_loop import record_on_simulated_stack
        from lotsen.stack.config import load_stack_config
        from lotsen.stack.stack import boat_description

        config = with_model_and_boat(replace(load_stack_config(args.config), seed=args.seed), args.params, args.boat)
        config = with_waves(with_physics(replace(config, mode="sim"), args.physics), args.waves)
        from lotsen.stack.config import config_files

        _say_sea(args.waves.waves() if args.waves else None)
        with atomic_output(out, _run_inputs(args, config_files(config)), ConfigError, "log") as tmp:
            node = record_on_simulated_stack(exp, tmp, config, keep_inside=not args.no_return)
        print(f"{args.out}: {exp.duration_s:.1f} s of '{exp.name}' on {boat_description(config, model)}"
              + (f" (ABORTED: {node.aborted})" if node.aborted else ""), file=sys.stderr)
        _say_measured_sea(node)
        if hasattr(node.plant, "silent_at_s"):  # an external physics
            check_physics_answered(node.plant, [node.aborted] if node.aborted else [], args.out)
        return 1 if node.aborted else 0
    if args.hardware:
        from dataclasses import replace

        from lotsen.stack.config import load_stack_config
        from lotsen.stack.experiment import run_on_stack

        config = load_stack_config(args.config)
        config = replace(config, mode="hardware", seed=args.seed,
                         extra=replace(config.extra, emulated=bool(args.emulated)))
        node = run_on_stack(exp, config, realtime=not args.emulated, keep_inside=not args.no_return)
        record = node.record()
        save_csv(record, args.out, _run_inputs(args))
        where = "the emulated boat" if args.emulated else "the boat"
        print(f"{args.out}: {len(record.t)} rows, {record.t[-1] if len(record.t) else 0:.1f} s of '{exp.name}' "
              f"on {where}" + (f" (ABORTED: {node.aborted})" if node.aborted else ""), file=sys.stderr)
        _say_measured_sea(node)
        return 1 if node.aborted else 0
    from lotsen.sim import DEFAULT_BOAT, SimulatedBoat
    from lotsen.stack.stack import load_parameters

    boat = (SimulatedBoat.ideal_for(model) if args.boat == "ideal" else
            DEFAULT_BOAT.with_parameters(load_parameters(args.boat)) if args.boat else DEFAULT_BOAT)
    from lotsen.model import Environment

    env = Environment(waves=args.waves.waves()) if args.waves else None
    _say_sea(env.waves if env is not None else None)
    run = run_on_simulator(exp, boat, seed=args.seed, psi_noise_rad=args.psi_noise, environment=env)
    save_csv(run.record, args.out, _run_inputs(args))
    print(f"{args.out}: {len(run.record.t)} rows, {exp.duration_s:.1f} s of '{exp.name}' on the simulator "
          f"(gyro bias estimate {run.gyro_bias_estimate_radps:+.4f} rad/s)", file=sys.stderr)
    return 0


def _say_sea(waves: Any) -> None:
    """The experiment's check of the sea it runs in (lotsen.sysid.waves.experiment_sea_warning)."""
    from lotsen.sysid.waves import experiment_sea_warning

    msg = experiment_sea_warning(waves.hs_m, waves.tp_s, waves.from_deg, measured=False) if waves is not None else None
    if msg:
        print(msg, file=sys.stderr)


def _say_measured_sea(node: Any) -> None:
    """The sea the boat's IMU measured during a run on the stack (and the warning when too high)."""
    from lotsen.sysid.waves import describe, experiment_sea_warning

    sea = node.sea
    if sea is None:
        return
    print(f"sea state during the run: {describe(sea).replace('the record', 'the boat')}", file=sys.stderr)
    msg = experiment_sea_warning(sea.hs_m, sea.tp_s, sea.from_deg)
    if msg:
        print(msg, file=sys.stderr)


def _cmd_lake(args: argparse.Namespace) -> int:
    check_outputs((args.out, args.boat), (), ConfigError)
    lake = lake_run(args.seed, args.duration, args.current, args.wind)
    save_csv(lake.run.record, args.out)
    env = lake.environment
    if args.boat:
        write_output(args.boat, json.dumps(lake.boat.to_dict(), indent=2) + "\n", (args.out,), ConfigError, "boat file")
    print(f"{args.out}: {len(lake.run.record.t)} rows, {args.duration:.0f} s lake record (seed {args.seed}): current "
          f"{env.current_speed_mps:.3f} m/s towards {env.current_to_deg:.0f} deg, wind {env.wind_speed_mps:.1f} m/s "
          f"from {env.wind_from_deg:.0f} deg, gusts {env.wind_gust_std_mps:.2f} m/s over "
          f"{env.wind_gust_time_constant_s:.1f} s" + (f"; the boat's true parameters: {args.boat}" if args.boat else ""),
          file=sys.stderr)
    return 0


def _cmd_check(args: argparse.Namespace) -> int:
    from lotsen.stack.stack import describe_parameters

    exp = load_experiment(args.experiment)
    pred = check_experiment(exp, VesselModel(load_params(args.params)), margin_m=args.margin,
                            area_advice=_area_advice(exp, args.params))
    if args.params:
        print(f"model: {describe_parameters(args.params)}")
    if args.sea is not None:
        _say_sea(args.sea.waves())
    print(f"{args.experiment}: OK ({exp.duration_s:.1f} s, predicted north {pred.x[:, 0].min():.1f}..{pred.x[:, 0].max():.1f} m, "
          f"east {pred.x[:, 1].min():.1f}..{pred.x[:, 1].max():.1f} m, inside the area)")
    return 0


def _cmd_design(args: argparse.Namespace) -> int:
    import yaml

    from lotsen.sysid.design import DesignConfig, design_experiment

    size = parse_area(args.area)
    fixed = _parameter_names(args.fixed)
    if args.duration / args.segment > MAX_DESIGN_SEGMENTS:
        raise ConfigError(f"--duration {args.duration:g} s / --segment {args.segment:g} s is "
                          f"{args.duration / args.segment:.0f} input levels; a design has at most {MAX_DESIGN_SEGMENTS}")
    check_outputs((args.out,), (args.params,), ConfigError)
    params = load_params(args.params)
    margin = DesignConfig.margin_m if args.margin is None else args.margin
    if 2 * margin >= min(size):
        raise ConfigError(f"--margin {margin:g} m leaves no room in a {args.area} m area: at most "
                          f"{min(size) / 2:g} m less than half its shorter side")
    cfg = DesignConfig(duration_s=args.duration, area_size_m=size, margin_m=margin, segment_s=args.segment,
                       criterion=args.criterion, seed=args.seed, iterations=args.iterations,
                       fixed=fixed or DesignConfig().fixed,
                       robust_samples=args.robust_samples, robust_spread=args.robust_spread)
    from lotsen.cli.progress import progress_printer  # a line every few seconds off a terminal too

    progress = progress_printer(f"design ({cfg.duration_s:g} s, {cfg.iterations} iterations)")
    done = [0]

    def step(_i: int, value: float) -> None:
        done[0] += 1
        progress(f"iteration {done[0]} of {cfg.iterations}: criterion {value:.4g}")

    around = (f" and {cfg.robust_samples - 1} parameter sets within +-{100 * cfg.robust_spread:g} %"
              if cfg.robust_samples > 1 else "")
    progress(f"optimising the inputs for the information at the prior{around}")
    result = design_experiment(params, cfg, progress=step)
    progress(None)
    check_experiment(result.experiment, VesselModel(params), margin_m=0.0)
    experiment = result.experiment
    if args.params:  # which model the design is for: `experiment run` checks the area with it (--params)
        from dataclasses import replace

        experiment = replace(experiment, description=f"{experiment.description}{DESIGNED_FOR}{args.params}")
    from lotsen.sysid.experiment import experiment_to_dict

    write_output(args.out, yaml.safe_dump(experiment_to_dict(experiment), sort_keys=False, width=120),
                 (args.params,), ConfigError, "experiment")
    print(f"{args.out}: {result.summary()}", file=sys.stderr)
    if args.sea is not None:
        _say_sea(args.sea.waves())
    return 0


def register(subparsers: Any) -> None:
    p = subparsers.add_parser("experiment", help="identification experiments: run, check, design")
    sub = p.add_subparsers(dest="experiment_command", required=True)
    r = sub.add_parser("run", help="run an experiment YAML on the simulator (--sim) or the boat (--hardware) "
                                   "and write the data CSV")
    r.add_argument("experiment")
    r.add_argument("--sim", action="store_true", help="run on the simulated boat")
    r.add_argument("--hardware", action="store_true",
                   help="run on the boat through its drivers (with the state estimate and the recorder)")
    r.add_argument("--emulated", action="store_true", help="with --hardware: the drivers' emulated twins")
    r.add_argument("--physics", metavar="udp:HOST:PORT", type=physics_address,
                   help="run on an external physics instead of the simulated boat (ArduPilot SITL's JSON protocol, "
                        "docs/physics.md; the channel map from --config's extra.physics), recorded on the stack: "
                        "--out RUN.mcap")
    r.add_argument("--config", help="launch config YAML: for --hardware its devices and pins (extra.hardware); "
                                    "for --sim with an .mcap output its sim.boat and vessel sections")
    r.add_argument("--out", required=True,
                   help="RUN.mcap: with --sim, the stack with its recorder (the log `lotsen identify` reads); "
                        "or a CSV (t,alpha1,alpha2,n1,n2,nt,north,east,psi,r) straight from the simulator; with "
                        "--hardware a CSV of the run (the recorder's MCAP lands in the log folder)")
    r.add_argument("--boat", metavar="BOAT.json|ideal",
                   help="with --sim: the simulated boat's coefficients (default: the lake boat), or 'ideal' "
                        "(the boat equals --params)")
    r.add_argument("--params", help="the model in use: the area check's prediction and, on the stack, the "
                                    "estimator (default: the default coefficients)")
    r.add_argument("--model-params", help="parameters of the model used for the area check (default: --params)")
    r.add_argument("--waves", metavar="HS,TP,FROM_DEG[,S]", type=waves_flag,
                   help="with --sim: the simulated boat in a wind sea: significant height (m), peak period (s), the "
                        "direction it comes FROM (deg), optionally the spreading exponent (default 10; 0 long-crested)")
    r.add_argument("--seed", type=SEED, default=0)
    r.add_argument("--psi-noise", type=Number(0.0, 1.0, "rad"), default=0.01, help="heading noise std, rad (default 0.01)")
    r.add_argument("--margin", type=MARGIN, default=1.0, help="area safety margin in metres (default 1)")
    r.add_argument("--no-return", action="store_true",
                   help="on the stack: end the run at the area's edge instead of turning the boat back to the "
                        "area's centre and resuming the signal (docs/sysid.md, 'Keeping inside the area')")
    r.set_defaults(func=_cmd_run)
    lk = sub.add_parser("lake", help="a simulated lake record: a 10-min PRBS on a boat that is not the default "
                                     "model, in current and gusty wind (for identify --lake)")
    lk.add_argument("--out", required=True, help="identification CSV to write")
    lk.add_argument("--boat", help="also write the boat's true parameters (a params JSON)")
    lk.add_argument("--seed", type=SEED, default=0)
    lk.add_argument("--duration", type=Number(10.0, 3600.0, "s"), default=600.0, help="s (default 600)")
    lk.add_argument("--current", type=Number(0.0, 2.0, "m/s"), default=None, help="m/s (default: random up to 0.1)")
    lk.add_argument("--wind", type=Number(0.0, 20.0, "m/s"), default=None, help="mean wind, m/s (default: random up to 5)")
    lk.set_defaults(func=_cmd_lake)
    c = sub.add_parser("check", help="check limits and the predicted area of an experiment")
    c.add_argument("experiment")
    c.add_argument("--params", help="vessel parameters JSON for the prediction")
    c.add_argument("--margin", type=MARGIN, default=1.0, help="area safety margin in metres (default 1)")
    c.add_argument("--sea", metavar="HS,TP,FROM_DEG", type=waves_flag,
                   help="the sea the experiment will run in (as the page shows the boat's estimate): says whether "
                        "it is too high for a trustworthy record and what to do")
    c.set_defaults(func=_cmd_check)
    d = sub.add_parser("design", help="optimise an experiment's inputs for the Fisher information")
    d.add_argument("--duration", type=Number(5.0, 600.0, "s"), default=60.0, help="experiment length, s")
    d.add_argument("--area", default="30x30", help="allowed area NORTHxEAST in metres, centred on the start")
    d.add_argument("--margin", type=MARGIN, default=None,
                   help="keep the predicted track this far inside the area, m (default 2); more for a boat not yet "
                        "identified, which turns wider or tighter than the model predicts")
    d.add_argument("--out", required=True)
    d.add_argument("--params", help="current parameter estimate JSON (default: the defaults)")
    d.add_argument("--segment", type=Number(0.5, 60.0, "s"), default=3.0,
                   help="length of each piecewise-constant input level, s")
    d.add_argument("--criterion", choices=("A", "D"), default="A",
                   help="A: minimise the sum of relative variances; D: maximise log det of the relative FIM")
    d.add_argument("--iterations", type=Number(1, 200, integer=True), default=40)
    d.add_argument("--fixed", help="comma-separated parameters treated as known (default: m11 only, the scale)")
    d.add_argument("--robust-samples", type=Number(1, 8, integer=True), default=3,
                   help="design for the prior and N-1 parameter sets around it (default 3; 1 = the prior only)")
    d.add_argument("--robust-spread", type=Number(0.0, 0.5), default=0.15,
                   help="relative spread of those parameter sets (default 0.15 = +-15 %%)")
    d.add_argument("--seed", type=SEED, default=0)
    d.add_argument("--sea", metavar="HS,TP,FROM_DEG", type=waves_flag,
                   help="the sea the experiment will run in: says whether it is too high for a trustworthy record "
                        "and what to do")
    d.set_defaults(func=_cmd_design)
