"""The 6-DOF hull (hull6dof.py) behind lotsen's plant interface, in-process: missions and experiments
on the hull at simulation speed, without the protocol (the model-chain bench's fast path; the proof
that the same hull flies over the protocol is tests/physics/test_seam.py with hull_server.py).

    from hull_plant import HullPlant, fly_route
    result = fly_route("examples/routes/figure_eight.yaml", model=VesselModel(params),
                       environment=HullEnvironment(current_mps=0.08, wind_mps=4.0, gust_fraction=0.2))
    result.metrics["cross_track_rms_m"]

`fly_route(..., physics="udp:127.0.0.1:9002")` flies the same through the protocol against a
running hull_server.py (or any physics server) instead.

This adapter uses lotsen (the plant interface, the actuator guard's limits, lotsen's sensors and
the mission harness); the hull itself (hull6dof.py) does not.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any, Sequence

sys.path.insert(0, str(Path(__file__).parent))

from hull6dof import Hull6DOF, HullEnvironment, HullParameters  # noqa: E402

from lotsen.model import DEFAULT_LIMITS, ActuatorLimits  # noqa: E402
from lotsen.sim.actuators import ActuatorDynamics  # noqa: E402
from lotsen.sim.plant import Plant, PlantSample, planar_state  # noqa: E402
from lotsen.sim.waves import BodyMotion  # noqa: E402


def hull_limits(params: HullParameters = HullParameters()) -> ActuatorLimits:
    """What the hull's actuators can do, as lotsen's guard clips set-points."""
    return replace(DEFAULT_LIMITS, alpha_max_rad=params.alpha_max_rad, alpha_rate_max_radps=params.alpha_rate_radps,
                   n_az_max_rps=params.n_max_rps, n_bow_max_rps=params.n_bow_max_rps,
                   motor_time_constant_s=params.motor_time_constant_s, n_rate_max_rps2=params.motor_ramp_rps2)


class HullPlant(Plant):
    """Hull6DOF as a lotsen `Plant`: one lotsen step = `dt_s` of the hull (its own 5 ms RK4 steps)."""

    def __init__(self, params: HullParameters = HullParameters(), environment: HullEnvironment = HullEnvironment(),
                 dt_s: float = 0.01, gnss_antenna_m: tuple[float, float] = (0.0, 0.0),
                 gnss_antenna_height_m: float = 0.0) -> None:
        self._attach(Hull6DOF(params, environment), hull_limits(params), "6-DOF hull (tests/physics/hull6dof.py)",
                     (params, environment), dt_s, gnss_antenna_m, gnss_antenna_height_m)

    def _attach(self, hull: Any, limits: ActuatorLimits, name: str, setup: tuple[Any, Any], dt_s: float,
                gnss_antenna_m: tuple[float, float], gnss_antenna_height_m: float) -> None:
        """The adapter around `hull`, any hull with this one's surface (hull_b_plant.HullBPlant attaches
        the catamaran); `setup`: its parameters and environment."""
        self.hull = hull
        self.params, self.env = setup
        self.name = name
        self.dt_s = dt_s
        self.limits = limits
        self.gnss_antenna_m = gnss_antenna_m
        self.gnss_antenna_height_m = gnss_antenna_height_m  # above the hull's roll and pitch centre
        self.actuators = ActuatorDynamics(self.limits, dt_s)  # set-points and faults; state: the hull's
        self._step_input: tuple[float, ...] = (0.0,) * 5
        self._read()

    def _read(self) -> None:
        h = self.hull
        vel, f = h.measure()
        n, e, psi, _, _, r = h.x3
        self._x, self._x_dot = planar_state(n, e, psi, vel, r, f[:2], h.eta[3], h.eta[4], q=h.nu[4])
        # what an IMU on the hull measures (as hull_server.py reports it over the protocol)
        self._motion = BodyMotion(h.eta[3], h.eta[4], h.eta[2], h.nu[3], h.nu[4], tuple(f), r)
        self.actuators.state = tuple(h.actuators)

    @property
    def wind_now(self) -> tuple[float, float]:
        return self.hull.wind_now

    def command(self, u: Sequence[float]) -> None:
        a = self.actuators
        a.set_command(*u)
        c = list(a.command)
        for i in a.faults.stuck_servos:
            c[i] = a.state[i]
        for i in a.faults.failed_units:
            c[2 + i] = 0.0
        self.hull.command(*c)

    def place(self, x: Sequence[float]) -> None:
        self.hull.reset((x[0], x[1], x[2]), t_s=self.hull.t)
        self.hull.set_velocity(x[3], x[4], x[5])
        self._read()

    def step(self) -> PlantSample:
        sample = PlantSample(self._x, self._x_dot, tuple(self.actuators.state), self._motion)
        self._step_input = self.hull.advance(self.dt_s)
        self._read()
        return sample

    def describe(self, reference: Any = None) -> str:
        return self.name


def fly_path(path: Any, model: Any = None, *, environment: HullEnvironment = HullEnvironment(),
             params: HullParameters = HullParameters(), seed: int = 0, controller: str = "mpc",
             estimator: str = "ekf", hold_s: float = 10.0, physics: str | None = None) -> Any:
    """A planned path flown on the hull by lotsen's stack (`lotsen.harness.mission.run_mission`):
    lotsen's sensors on `seed`, its EKF (or the truth) and controller on `model` (default: the
    default model). `physics`: fly through the protocol at that address instead (a running
    hull_server.py with the same environment and parameters); default in-process."""
    from lotsen.control import ControlConfig, make_path_follower
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
    from lotsen.model import VesselModel

    model = model or VesselModel()
    control = ControlConfig(controller=controller)
    cfg = MissionConfig(control_rate_hz=1.0 / control.dt_s, seed=seed, hold_s=hold_s, sensors=estimator != "truth")
    if physics is None:
        plant: Any = HullPlant(params, environment, cfg.sim_dt_s)
    else:
        from lotsen.physics import PhysicsConfig
        from lotsen.physics.client import UdpPhysics

        plant = UdpPhysics(PhysicsConfig(address=physics), dt_s=cfg.sim_dt_s)
    ekf = make_sim_ekf(cfg, path, model, boat=plant) if estimator == "ekf" else None
    try:
        return run_mission(path, make_path_follower(control, model), cfg, model=model, estimator=ekf, plant=plant)
    finally:
        plant.close()


def fly_route(route: str | Path, model: Any = None, **kwargs: Any) -> Any:
    """`fly_path` on the route file's planned path."""
    from lotsen.planning import plan_route
    from lotsen.planning.io import load_route

    return fly_path(plan_route(load_route(str(route))), model, **kwargs)

