"""Hull B (hull_b.py, the catamaran) behind lotsen's plant interface, in-process: missions on it at
simulation speed, with hull_plant.py's adapter (HullPlant) around the catamaran.

    from hull_b_plant import HullBPlant, fly_path
    result = fly_path(path, environment=CatamaranEnvironment(current_mps=0.08, wind_mps=4.0))

This adapter uses lotsen (the plant interface, the actuator guard's limits, the mission harness);
the hull itself (hull_b.py) does not.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

sys.path.insert(0, str(Path(__file__).parent))

from hull_b import CatamaranEnvironment, CatamaranHull, CatamaranParameters  # noqa: E402
from hull_plant import HullPlant  # noqa: E402
import numpy as np  # noqa: E402

from lotsen.model import DEFAULT_LIMITS, ActuatorLimits  # noqa: E402


def hull_b_limits(hull: CatamaranHull) -> ActuatorLimits:
    """What the catamaran's actuators can do, as lotsen's guard clips set-points (the DC motors'
    equivalent first-order time constant and their no-load current-limited ramp)."""
    p = hull.p
    return replace(DEFAULT_LIMITS, alpha_max_rad=p.alpha_max_rad, alpha_rate_max_radps=p.alpha_rate_radps,
                   n_az_max_rps=p.n_max_rps, n_bow_max_rps=p.n_bow_max_rps,
                   motor_time_constant_s=hull.motor_time_constant_s, n_rate_max_rps2=hull.motor_ramp_rps2)


class HullBPlant(HullPlant):
    """CatamaranHull as a lotsen `Plant` (hull_plant.HullPlant's adapter around the catamaran): one lotsen
    step = `dt_s` of the hull (its own 5 ms steps)."""

    def __init__(self, params: CatamaranParameters = CatamaranParameters(),
                 environment: CatamaranEnvironment = CatamaranEnvironment(), dt_s: float = 0.01,
                 gnss_antenna_m: tuple[float, float] = (0.0, 0.0), gnss_antenna_height_m: float = 0.0) -> None:
        hull = CatamaranHull(params, environment)
        self._attach(hull, hull_b_limits(hull), "6-DOF catamaran (tests/physics/hull_b.py)", (params, environment),
                     dt_s, gnss_antenna_m, gnss_antenna_height_m)


def fly_path(path: Any, model: Any = None, *, environment: CatamaranEnvironment = CatamaranEnvironment(),
             params: CatamaranParameters = CatamaranParameters(), seed: int = 0, controller: str = "mpc",
             estimator: str = "ekf", hold_s: float = 5.0, gnss_antenna_m: tuple[float, float] = (0.0, 0.0),
             gnss_antenna_height_m: float = 0.0) -> Any:
    """A planned path flown on the catamaran by lotsen's stack (`lotsen.harness.mission.run_mission`):
    lotsen's sensors on `seed`, its EKF (or the truth) and controller on `model` (default model)."""
    from lotsen.control import ControlConfig, make_path_follower
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
    from lotsen.model import VesselModel

    model = model or VesselModel()
    control = ControlConfig(controller=controller)
    cfg = MissionConfig(control_rate_hz=1.0 / control.dt_s, seed=seed, hold_s=hold_s, sensors=estimator != "truth")
    plant = HullBPlant(params, environment, cfg.sim_dt_s, gnss_antenna_m, gnss_antenna_height_m)
    ekf = make_sim_ekf(cfg, path, model, boat=plant) if estimator == "ekf" else None
    try:
        return run_mission(path, make_path_follower(control, model), cfg, model=model, estimator=ekf, plant=plant)
    finally:
        plant.close()


def run_experiment(experiment: Any, *, seed: int = 0, model: Any = None) -> tuple[Any, list[tuple[float, float]]]:
    """`lotsen experiment run EXPERIMENT --physics udp:...` against `hull_server.py --hull b` (calm), in-process
    on simulated time: the same stack (the configured EKF, the supervisor with its failsafes, the experiment
    node), without the protocol and the recorder. `model`: the EKF's and the supervisor's model (default:
    the config's). Returns the ExperimentNode (`aborted`, `rows`) and the estimate's position error
    against the hull, (t, metres) every 0.1 s."""
    from dataclasses import replace as replace_config

    from lotsen.runtime.config import WebSection
    from lotsen.sim import Simulator
    from lotsen.stack.config import load_stack_config
    from lotsen.stack.experiment import ExperimentNode
    from lotsen.stack.launch import Harness, build_stack
    from lotsen.stack.stack import sim_config

    config = replace_config(load_stack_config(None), seed=seed, mode="sim", web=WebSection(enabled=False))
    plant = HullBPlant(dt_s=config.sim.dt_s)
    sim = Simulator(plant, config=sim_config(config), x0=config.sim.initial_state)
    stack = build_stack(config, realtime=False, parts=("state", "supervisor"), harness=Harness(simulator=sim, model=model))
    node = stack.add(ExperimentNode(experiment))
    ekf = stack.nodes["fusion"].estimator
    errors: list[tuple[float, float]] = []
    clock = stack.executor.clock

    def sample() -> None:
        est, x = ekf.estimate(clock.now()), sim.x
        errors.append((clock.now(), float(np.hypot(est.north_m - x[0], est.east_m - x[1]))))

    stack.executor.add_timer(0.1, sample, "position-error")
    try:
        stack.executor.run_until(experiment.duration_s + node.preroll_s + 10.0, stop=lambda: node.done)
        stack.executor.shutdown()
    finally:
        plant.close()
    return node, errors


def figure_eight(speed_mps: float = 0.5) -> Any:
    """examples/routes/figure_eight.yaml planned at `speed_mps` on every node (as bench_waves.py does)."""
    from lotsen.files import read_yaml
    from lotsen.planning import plan_route
    from lotsen.planning.io import route_from_dict

    route = read_yaml(Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight.yaml")
    route["nodes"] = [dict(n, speed_mps=speed_mps) for n in route["nodes"]]
    return plan_route(route_from_dict(route))


def main(argv: Sequence[str] | None = None) -> int:
    """`python tests/physics/hull_b_plant.py [--speed 0.5] [--seed 0]`: the figure eight flown on the
    catamaran by lotsen's stack in simulated time, in bench_waves.py's calm conditions (0.08 m/s current
    to 30 deg, 4 m/s wind from 250 deg with 20 % gusts and 15 deg wander, no waves; GNSS antenna 0.1 m
    ahead, 0.2 m up); prints completed and the mission's metrics."""
    import argparse
    import json

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--speed", type=float, default=0.5)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    env = CatamaranEnvironment(current_mps=0.08, current_to_deg=30.0, wind_mps=4.0, wind_from_deg=250.0,
                               gust_fraction=0.2, wind_wander_deg=15.0, seed=a.seed)
    res = fly_path(figure_eight(a.speed), environment=env, seed=a.seed, gnss_antenna_m=(0.1, 0.0),
                   gnss_antenna_height_m=0.2)
    m = {k: v for k, v in res.metrics.items() if isinstance(v, (int, float, str, bool, list))}
    print(json.dumps({"completed": bool(res.completed), **m}, indent=1))
    return 0 if res.completed else 1


if __name__ == "__main__":
    raise SystemExit(main())
