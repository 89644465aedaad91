"""`lotsen mission ROUTE.yaml|NAME --sim|--physics udp:HOST:PORT [--controller mpc|pursuit|los|lq]
[--current SPEED,DIR_DEG] [--wind SPEED,DIR_DEG] [--seed N] [--boat BOAT.json|ideal] [--params PARAMS.json]
[--config CONFIG.yaml] --report report.json [--plot mission.png]`

Plans the route (lotsen.planning; a bare NAME without such a file is the example route
examples/routes/NAME.yaml, so `lotsen mission figure_eight --sim ...` runs from any folder), runs
the closed loop on the simulated boat (controller at 10 Hz on the simulator's 100 Hz steps), holds
the last point with the station keeper, and writes a JSON report (tracking errors, propeller
reversals, solve times, completion, which boat and which model) and optionally a plot. The simulated
boat (`--boat`, default the lake boat) and the model the estimator and controllers use (`--params`,
default the default coefficients) are separate: a boat is never its model unless `--boat ideal` says
so. `--physics udp:HOST:PORT` flies an external physics instead (ArduPilot SITL's JSON protocol,
docs/physics.md; the channel map from `--config`'s extra.physics): lotsen's sensor models, estimator
and controllers, the physics's boat, water and wind.
Exit code 0 when the mission completed, 1 when it did not (the report is written either way), 2
with an error when the physics stopped answering during the mission.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path as FilePath
from typing import Any

from lotsen.cli.outputs import check_plot_name, save_plot
from lotsen.errors import ConfigError, LotsenError
from lotsen.files import check_outputs, write_output
from lotsen.physics.config import address_flag as physics_address
from lotsen.cli.prediction import parse_speed_dir  # noqa: F401 - the flags' parser, shared with plan and physics-server
from lotsen.settings import SEED, Number

#: planned time a simulated mission may take (its simulation runs up to twice that + 60 s):
#: beyond it a route is a typo or a hostile file, and the command would run for hours. 3600 s (was
#: 900): a survey is long (the 40 x 30 m example at 2 m: 1000 s; ~1 ms of CPU per simulated second
#: with the EKF, 2-3 min)
MAX_MISSION_PLANNED_S = 3600.0


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "mission", help="plan a route and fly it in closed loop on the simulated boat",
        description="Plan ROUTE, follow it with the selected controller on the simulator, hold the "
                    "last point, and report tracking errors and solver times.")
    p.add_argument("route", help="route file (.yaml, .yml, .geojson, a ground station's file), or the name of an "
                                 "example route shipped with lotsen (figure_eight, harbour_approach, ...)")
    p.add_argument("--sim", action="store_true", help="run on the simulated boat")
    p.add_argument("--physics", metavar="udp:HOST:PORT", type=physics_address,
                   help="fly an external physics instead of the simulated boat (ArduPilot SITL's JSON protocol, "
                        "docs/physics.md); its boat, water and wind are its own")
    p.add_argument("--config", metavar="CONFIG.yaml",
                   help="with --physics: the launch config whose extra.physics (channel map, timeouts, GNSS antenna) "
                        "is used")
    p.add_argument("--controller", default="mpc", choices=("mpc", "pursuit", "los", "lq"))
    p.add_argument("--current", metavar="SPEED,DIR_DEG", help="current speed (m/s) and direction it flows TO (deg)")
    p.add_argument("--wind", metavar="SPEED,DIR_DEG", help="wind speed (m/s) and direction it comes FROM (deg)")
    p.add_argument("--waves", metavar="HS,TP,FROM_DEG[,S]", type=waves_flag,
                   help="a wind sea: significant height (m), peak period (s), the direction it comes FROM (deg), "
                        "optionally the spreading exponent (default 10; 0 long-crested)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the simulator's noise")
    p.add_argument("--estimator", default="ekf", choices=("truth", "ekf"),
                   help="state for the controller: lotsen.fusion's EKF on the simulated sensors (default) "
                        "or the simulator's truth (errors are always measured on the truth)")
    p.add_argument("--boat", metavar="BOAT.json|ideal",
                   help="the simulated boat's coefficients (a params JSON as `lotsen identify --out` writes it; "
                        "the lake boat's unmodelled effects stay), or 'ideal': the boat equals the model in use. "
                        "Default: the lake boat (docs/simulator.md)")
    p.add_argument("--params", metavar="PARAMS.json",
                   help="the model the estimator and the controllers use (default: the default coefficients)")
    p.add_argument("--hold", type=Number(0.0, 600.0, "s"), default=10.0, help="seconds of station keeping at the end")
    p.add_argument("--horizon", type=Number(2, 100, "steps", integer=True), help="MPC horizon in steps (default 20)")
    p.add_argument("--report", required=True, help="write the JSON report here")
    p.add_argument("--plot", help="write a PNG: path and track, errors over time")
    p.set_defaults(func=run)


def waves_flag(text: str) -> Any:
    """argparse `type=` of `--waves HS,TP,FROM_DEG[,S]`: a `WavesConfig` (lotsen.runtime.config)."""
    from lotsen.runtime.config import WavesConfig

    try:
        return WavesConfig.parse(text, "value")
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("value ")) from None


def waves_report(waves: Any) -> dict | None:
    """The sea of a run as a report writes it (None: flat water, "calm water")."""
    if waves is None:
        return None
    return {"hs_m": waves.hs_m, "tp_s": waves.tp_s, "from_deg": waves.from_deg, "spreading": waves.spreading}


def route_file(text: str) -> str:
    """ROUTE as given, or, when no such file exists and it is a bare name, the example route of
    that name (examples/routes/NAME.yaml): the README's walkthrough runs from any folder."""
    from lotsen.stack.stack import example_or_file

    return example_or_file(text, "routes")


def run(args: argparse.Namespace) -> int:
    if not args.sim and not args.physics:
        raise LotsenError("mission: say what to fly: --sim (the simulated boat) or --physics udp:HOST:PORT (an "
                          "external physics); the runtime runs missions on the boat")
    if args.physics:
        if args.boat:
            raise ConfigError("--boat: with --physics the boat is the physics server's")
        if args.current or args.wind or args.waves:
            raise ConfigError("--current/--wind/--waves: with --physics the water and the wind are the physics "
                              "server's; set them there")
    elif args.config:
        raise ConfigError("--config: only read for --physics (its extra.physics section)")
    from dataclasses import replace

    from lotsen.cli.plan import plan_within_budget
    from lotsen.cli.prediction import predict
    from lotsen.control import ControlConfig, MPCConfig, make_path_follower
    from lotsen.model import Environment, VesselModel, VesselParameters
    from lotsen.planning import PlannerConfig
    from lotsen.planning.io import load_route
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, planned_duration_s, run_mission
    from lotsen.planning.survey.keeping import line_spans
    from lotsen.stack.prediction import compare_with_flown
    from lotsen.sim import DEFAULT_BOAT, SimulatedBoat
    from lotsen.model import load_parameter_file

    cur = parse_speed_dir(args.current, "current")
    wind = parse_speed_dir(args.wind, "wind")
    check_plot_name(args.plot)
    args.route = route_file(args.route)
    inputs = (args.route, args.params, None if args.boat == "ideal" else args.boat, args.config)
    check_outputs((args.report, args.plot), inputs, ConfigError)
    waves = args.waves.waves() if args.waves else None
    env = Environment(current_speed_mps=cur[0], current_to_deg=cur[1], wind_speed_mps=wind[0], wind_from_deg=wind[1],
                      waves=waves)
    # the files first (a bad file is reported before minutes of simulation), then the plan
    model_file = load_parameter_file(args.params) if args.params else None
    model = VesselModel(model_file.parameters if model_file else VesselParameters())
    boat_file = load_parameter_file(args.boat) if args.boat and args.boat != "ideal" else None
    boat = SimulatedBoat.ideal_for(model) if args.boat == "ideal" else (
        DEFAULT_BOAT.with_parameters(boat_file.parameters, name=f"lake boat with {boat_file.describe()}")
        if boat_file else DEFAULT_BOAT)
    route = load_route(args.route)
    path = plan_within_budget(route, PlannerConfig())
    planned_s = planned_duration_s(path)
    if planned_s > MAX_MISSION_PLANNED_S:
        raise ConfigError(f"{args.route}: the planned path takes {planned_s:.0f} s at its speeds; a simulated "
                          f"mission is at most {MAX_MISSION_PLANNED_S:.0f} s (faster node speeds or a shorter route)")
    control = ControlConfig(controller=args.controller)
    if args.horizon is not None:
        control = replace(control, mpc=replace(MPCConfig(), horizon=args.horizon))
    cfg = MissionConfig(control_rate_hz=1.0 / control.dt_s, environment=env, seed=args.seed, hold_s=args.hold,
                        sensors=args.estimator != "truth")
    plant = physics_plant(args.config, args.physics, cfg.sim_dt_s) if args.physics else None
    boat = plant if plant is not None else boat
    estimator = make_sim_ekf(cfg, path, model, boat=boat) if args.estimator == "ekf" else None
    # before the boat leaves: the time and energy the model in use predicts in the current, wind and waves
    # given (with --physics none are given: the prediction is in calm water), the controller on the estimate's
    # error as on the EKF, or on the true state as the flight is with --estimator truth
    prediction = predict(route, path, model, model_file.describe() if model_file else "default coefficients",
                         cur, wind, args.controller, waves=waves,
                         estimator="noise" if args.estimator == "ekf" else "truth")
    try:
        result = run_mission(path, make_path_follower(control, model), cfg, model=model, estimator=estimator,
                             survey_lines=line_spans(route, path),
                             **({"plant": plant} if plant is not None else {"boat": boat}))
    finally:
        if plant is not None:
            plant.close()
    ideal = bool(getattr(boat, "ideal", False))
    report = dict(result.metrics)
    report.update(model=model_file.source if model_file else "default coefficients",
                  model_defaults_for=list(model_file.defaults_for) if model_file else [],
                  boat=boat.describe(model.params), ideal_model=ideal)
    report.update(route=str(args.route), environment={"current_mps": cur[0], "current_to_deg": cur[1],
                                                       "wind_mps": wind[0], "wind_from_deg": wind[1],
                                                       "waves": waves_report(waves)},
                  seed=args.seed, estimator=args.estimator, control_rate_hz=cfg.control_rate_hz,
                  prediction=prediction.as_dict())
    if result.completed and "energy_J" in result.metrics:
        report["predicted_vs_flown"] = compare_with_flown(prediction, result.metrics["duration_s"],
                                                          result.metrics["energy_J"])
    write_output(args.report, json.dumps(report, indent=2) + "\n", inputs, ConfigError, "report")
    m = result.metrics
    print(f"boat: {report['boat']}; model: {model_file.describe() if model_file else report['model']}"
          + (" [ideal model]" if ideal else ""))
    print(f"{m['controller']}: {'completed' if m['completed'] else 'NOT completed (' + m['reason'] + ')'} in "
          f"{m['duration_s']:.1f} s; cross-track RMS {m['cross_track_rms_m'] * 100:.1f} cm, max "
          f"{m['cross_track_max_m'] * 100:.1f} cm; heading RMS {m['heading_error_rms_deg']:.1f} deg; speed RMS "
          f"{m['speed_error_rms_mps']:.3f} m/s"
          + (f"; {m['reversals_per_s']:.2f} propeller reversals/s (on the {m['reversals_counted_on']})"
             if "reversals_per_s" in m else "")
          + (f"; solve median {m['solve_time_median_ms']:.2f} ms, max "
                                                  f"{m['solve_time_max_ms']:.1f} ms" if m['solve_time_median_ms'] else ""))
    if "energy_J_by_propeller" in m:  # where the energy went: a couple or a steady bow push shows here
        e1, e2, eb = (e / 3600.0 for e in m["energy_J_by_propeller"])
        a1, a2 = (100.0 * x for x in m["azimuth_astern_share"])
        print(f"energy {m['energy_J'] / 3600.0:.2f} Wh at the motors: azimuth 1 {e1:.2f}, azimuth 2 {e2:.2f}, bow "
              f"{eb:.2f} Wh; azimuths astern {a1:.0f} % and {a2:.0f} % of the time")
    if "survey" in m:
        sv = m["survey"]
        settle = sv.get("settle_distance_max_m")
        print(f"survey: {sv['lines_flown']} of {sv['lines']} lines; worst line cross-track RMS "
              f"{sv['cross_track_rms_m'] * 100:.1f} cm, max {sv['cross_track_max_m'] * 100:.1f} cm; within "
              f"{sv['settle_tolerance_m'] * 100:.0f} cm " + (f"at most {settle:.2f} m after a turn" if settle is not None
                                                           else "NOT reached on every line")
              + f"; {sv['share_on_lines'] * 100:.1f} % of the time on lines")
    if "predicted_vs_flown" in report:
        c = report["predicted_vs_flown"]
        print(f"predicted {c['duration_predicted_s']:.0f} s and {c['energy_predicted_J'] / 3600:.2f} Wh, flown "
              f"{c['duration_flown_s']:.0f} s and {c['energy_flown_J'] / 3600:.2f} Wh "
              f"({c['duration_error'] * 100:+.1f} %, {c['energy_error'] * 100:+.1f} %)")
    print(f"wrote {args.report}")
    if args.plot:
        save_plot(args.plot, lambda p: plot_mission(result, p), inputs)
        print(f"wrote {args.plot}")
    if plant is not None:
        check_physics_answered(plant, result.metrics.get("failsafes_triggered", []), args.report)
    return 0 if result.completed else 1


def physics_plant(config_path: str | None, address: str, dt_s: float) -> Any:
    """The external physics at `address` with the channel map of `config_path`'s extra.physics."""
    from dataclasses import replace

    from lotsen.physics.client import UdpPhysics
    from lotsen.stack.config import load_stack_config

    physics = load_stack_config(config_path).extra.physics
    return UdpPhysics(replace(physics, address=address), dt_s=dt_s)


def check_physics_answered(plant: Any, failsafes: Any, report: str) -> None:
    """A PhysicsError when the physics stopped answering during the run and did not come back (the
    run went on with stale sensors until the failsafes acted), or was lost for a while."""
    from lotsen.physics.client import PhysicsError

    t = plant.silent_at_s if plant.silent_at_s is not None else plant.lost_at_s
    if t is None:
        return
    c = plant.counters
    raise PhysicsError(f"the physics at {plant.address} stopped answering at t = {t:.1f} s "
                       f"({c['timeouts']} frames unanswered, {c['corrupt']} corrupt replies"
                       + (f"; last: {plant.last_problem}" if plant.last_problem else "")
                       + f"); the boat's sensors went stale and the failsafes acted ({', '.join(failsafes) or 'none'}); "
                       f"{report} has the run up to there")


def plot_mission(result: Any, out: FilePath) -> None:
    """Path and track (left), cross-track, heading and speed over time (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    path = result.path
    fig = plt.figure(figsize=(13, 7))
    ax = fig.add_subplot(1, 2, 1)
    ax.plot(path.east_m, path.north_m, "k--", lw=1, label="planned path")
    f = result.mode == "follow"
    ax.plot(result.x[f, 1], result.x[f, 0], "C0", lw=1.5, label="track (follow)")
    h = result.mode == "hold"
    if np.any(h):
        ax.plot(result.x[h, 1], result.x[h, 0], "C3", lw=1.5, label="track (hold)")
    ax.plot(path.east_m[0], path.north_m[0], "go", label="start")
    ax.plot(path.east_m[-1], path.north_m[-1], "rs", label="end")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    m = result.metrics
    ax.set_title(f"{m['controller']}: cross-track RMS {m['cross_track_rms_m'] * 100:.1f} cm, "
                 f"max {m['cross_track_max_m'] * 100:.1f} cm")
    t = result.t
    a1 = fig.add_subplot(3, 2, 2)
    a1.plot(t[f], result.cross_track_m[f] * 100, "C0")
    a1.set_ylabel("cross-track (cm)")
    a2 = fig.add_subplot(3, 2, 4, sharex=a1)
    a2.plot(t[f], np.degrees(result.heading_error_rad[f]), "C1")
    a2.set_ylabel("heading error (deg)")
    a3 = fig.add_subplot(3, 2, 6, sharex=a1)
    a3.plot(t, result.speed_mps, "C2", label="speed")
    a3.plot(t[f], result.speed_ref_mps[f], "k--", lw=1, label="reference")
    a3.set_ylabel("speed (m/s)")
    a3.set_xlabel("time (s)")
    a3.legend(fontsize=8)
    for a in (a1, a2, a3):
        a.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
