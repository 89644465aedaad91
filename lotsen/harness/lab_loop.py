"""The lab loop on simulated time: designed experiments recorded on the stack -> identification ->
a mission with the identified model, on a simulated boat that is not its model.

    identified, report = identify_on(boat, work_dir)      # None when identification refused
    metrics = track_with_model(boat, identified, seed=0)  # figure eight on the EKF, current + wind

`record_on_simulated_stack` is what `lotsen experiment run --sim --out RUN.mcap` does: the
experiment node drives the stack's supervisor, the recorder writes every topic. `identify_logs`
is what `lotsen identify RUN.mcap ... --validate CHECK.mcap --out params.json` does with the hull's
measured geometry: the same problem handed to the same `lotsen.sysid.identify.identify`. A lab knows the scale from the weighed
hull (m11 fixed), the GNSS antenna's position from a tape, and the astern/ahead thrust ratio from a
bollard pull: `identify_on` gives those, nothing else of the boat.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import tempfile
from pathlib import Path
from typing import Any, Mapping, Sequence

from lotsen.control import ControlConfig, make_path_follower
from lotsen.errors import ConfigError, LotsenError
from lotsen.files import read_yaml
from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
from lotsen.logs.export import sysid_record
from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, Environment, VesselModel, VesselParameters
from lotsen.planning import plan_route
from lotsen.planning.io import load_route
from lotsen.runtime.config import BoatSection, LaunchConfig, LoggingSection, WebSection
from lotsen.sim import SimulatedBoat
from lotsen.stack.experiment import ExperimentNode, run_on_stack
from lotsen.stack.stack import EXAMPLES, example_route
from lotsen.sysid.experiment import Experiment, load_experiment, parse_experiment
from lotsen.sysid.identify import identify
from lotsen.sysid.judge import Identification
from lotsen.sysid.problem import IdentificationProblem, held_out_split

#: the battery of designed experiments (examples/experiments), the broadband PRBS first
EXPERIMENTS = ("prbs_multisine", "zigzag_20_20", "turning_circles", "bow_thruster_steps", "zigzag_10_10",
               "speed_steps")
#: the mission's water and air: 0.1 m/s current towards 90 deg, 3 m/s wind from 45 deg
LAB_ENVIRONMENT = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)


def record_on_simulated_stack(experiment: Experiment, out: Path, config: LaunchConfig,
                              keep_inside: bool = True) -> ExperimentNode:
    """Run `experiment` on the stack with the simulated boat of `config` (its `sim.boat`), on
    simulated time, recording every topic as the boat's recorder does; the MCAP lands at `out`
    (what `lotsen identify RUN.mcap` reads). Returns the ExperimentNode. `keep_inside`: the boat is
    turned back at the area's edge (ExperimentNode)."""
    with tempfile.TemporaryDirectory(prefix="lotsen-experiment-") as tmp:
        config = dataclasses.replace(config, mode="sim", logging=LoggingSection(enabled=True, directory=tmp),
                                     web=WebSection(enabled=False))
        node = run_on_stack(experiment, config, realtime=False, keep_inside=keep_inside)
        logs = sorted(Path(tmp).glob("*.mcap"))
        if not logs:
            raise LotsenError("the experiment ran but the recorder wrote no log")
        shutil.move(str(logs[-1]), out)
    return node


def identify_logs(logs: Sequence[str | Path], out: Path | None = None, *, fixed: Mapping[str, float],
                  gnss_antenna_m: tuple[float, float] = (0.0, 0.0), reverse_thrust_ratio: float = 1.0,
                  init: VesselParameters | None = None, validate: Sequence[str | Path] = ()) -> Identification:
    """`lotsen identify LOGS --validate VALIDATE --fix ... --gnss-antenna X,Y --reverse-thrust-ratio R
    [--init] --out OUT` with its defaults: the run logs' fixes moved to the hull's origin, the one
    `identify(problem)`, judged on `validate` (records with other inputs; without them the last 20 % of
    each log); the parameter file written to `out` when given (marked refused when the verdict is)."""
    records = [sysid_record(p, gnss_antenna_m=gnss_antenna_m) for p in logs]
    validation = [sysid_record(p, gnss_antenna_m=gnss_antenna_m) for p in validate]
    est, val, judged_on, held_out = held_out_split(records, validation, 0.2)
    geometry = dataclasses.replace(DEFAULT_GEOMETRY, reverse_thrust_ratio=reverse_thrust_ratio)
    problem = IdentificationProblem(est, val, dict(fixed), {n: "measured on the hull" for n in fixed}, geometry,
                                    init or DEFAULT_PARAMETERS, DEFAULT_PARAMETERS, validation_source=judged_on,
                                    held_out=held_out)
    ident = identify(problem)
    if out is not None:
        Path(out).write_text(json.dumps(ident.to_json_dict(), indent=2) + "\n")
    return ident


def lab_experiments() -> list[Experiment]:
    return [load_experiment(EXAMPLES / "experiments" / f"{name}.yaml") for name in EXPERIMENTS]


def validation_experiment(seed: int = 1) -> Experiment:
    """The record that judges the lab loop's answer: the broadband example (prbs_multisine) with its
    random sequences drawn from `seed`, so its inputs are not those of any estimation record (the
    battery's own prbs_multisine flown again would be a replay: in calm water the same true track)."""
    data = read_yaml(EXAMPLES / "experiments" / "prbs_multisine.yaml", ConfigError, "experiment file")
    pieces = [dict(p, seed=int(p["seed"]) + 100 * seed) if "seed" in p else dict(p) for p in data["pieces"]]
    return parse_experiment({**data, "name": f"prbs_multisine_seed{seed}", "pieces": pieces}, "validation")


def identify_on(boat: SimulatedBoat, work: Path, experiments: Sequence[Experiment] | None = None,
                base_seed: int = 100) -> tuple[VesselParameters | None, dict[str, Any]]:
    """The lab loop on `boat`: the designed experiments (default the battery `EXPERIMENTS`) recorded
    on the simulated stack (seeds `base_seed` + i) into `work`, and a record with other inputs to judge
    the answer on (`validation_experiment`), identified together; m11 fixed as the
    weighed hull gives it, and the geometry a lab measures on the hull given (the GNSS antenna's
    position; astern/ahead thrust from a bollard pull). Returns (parameters, the parameter file's
    content, also written to work/identified.json); the parameters are None when identification
    refused them (its verdict and reasons are in the content)."""
    boat_file = work / "boat.json"
    boat_file.write_text(json.dumps(boat.parameters.to_dict()))
    config = LaunchConfig(mode="sim")
    config = dataclasses.replace(config, sim=dataclasses.replace(
        config.sim, boat=BoatSection(parameters_file=str(boat_file))))
    logs = []
    for i, exp in enumerate(experiments if experiments is not None else lab_experiments()):
        out = work / f"{exp.name}.mcap"
        record_on_simulated_stack(exp, out, dataclasses.replace(config, seed=base_seed + i))
        logs.append(out)
    check = validation_experiment()
    check_log = work / f"{check.name}.mcap"
    record_on_simulated_stack(check, check_log, dataclasses.replace(config, seed=base_seed + len(logs)))
    hull = dict(fixed={"m11": boat.parameters.m11}, gnss_antenna_m=tuple(boat.gnss_antenna_m),
                reverse_thrust_ratio=boat.geometry.reverse_thrust_ratio)
    # the equation-error start depends on the data alone: no staged start from the broadband record is
    # needed; the answer is judged on a record with other inputs
    ident = identify_logs(logs, work / "identified.json", validate=[check_log], **hull)
    return (None if ident.refused else ident.result.params), ident.to_json_dict()


def track_with_model(boat: SimulatedBoat, params: VesselParameters, seed: int, route: str | None = None,
                     environment: Environment = LAB_ENVIRONMENT) -> dict[str, Any]:
    """A mission on `boat` with `params` as the controllers' and the EKF's model: the route (default
    the figure eight) followed on the EKF, with sensors, in `environment`. Returns the metrics."""
    model = VesselModel(params)
    path = plan_route(load_route(route or example_route("figure_eight")))
    cfg = MissionConfig(environment=environment, sensors=True, seed=seed)
    r = run_mission(path, make_path_follower(ControlConfig(), model), cfg, model=model, boat=boat,
                    estimator=make_sim_ekf(cfg, path, model, boat=boat))
    return r.metrics
