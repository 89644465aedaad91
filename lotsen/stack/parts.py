"""The optional parts of a stack and how each joins it (`lotsen.stack.launch.PARTS`).

Order matters: the state estimate first, then the supervisor (which runs the controllers), then
the recorder, the Zenoh bridge and the web server, which only observe and relay.
"""

from __future__ import annotations

from typing import Any

from lotsen.control import ControlConfig, MPCConfig
from lotsen.control.mpc import REALTIME_SOLVE_LIMIT_S
from lotsen.errors import ConfigError
from lotsen.files import read_json
from lotsen.fusion import EkfConfig, MagCalibration, ModelAidedEKF, SeedFilters, SeedFiltersConfig, fit_mag_calibration
from lotsen.fusion.seastate import SeaStateConfig
from lotsen.messages import MagCalibrationResult, ModelInfo, Topic
from lotsen.model import DEFAULT_LIMITS
from lotsen.planning import plan_route
from lotsen.planning.exchange import path_from_message, planned_route_message
from lotsen.planning.io import load_route
from lotsen.stack.fusion_node import FusionNode, TruthStateNode
from lotsen.stack.logs import add_recorder as _add_recorder
from lotsen.runtime.executor import Node, NodeContext, RealtimeExecutor
from lotsen.stack.sounding import SoundingNode
from lotsen.stack.stack import Stack, model_info
from lotsen.stack.web import add_web as _add_web
from lotsen.stack.zenoh import add_bridge
from lotsen.supervisor.node import SupervisorConfig, SupervisorNode
from lotsen.supervisor.prearm import route_corridor_m


def twin_factory_calibration(stack: Stack) -> MagCalibration:
    """The simulated magnetometer's distortion as a calibration (the twin's 'factory' values).

    Lets `make run` start with a sensible heading; the operator's calibrate_mag replaces it.
    """
    imu = stack.simulator.config.imu if stack.simulator else None
    if imu is None:
        return MagCalibration.identity()
    H = imu.earth_field_horizontal_uT
    S = imu.soft_iron
    return MagCalibration(center=imu.hard_iron_uT, matrix=((S[0][0] * H, S[0][1] * H), (S[1][0] * H, S[1][1] * H)),
                          heading_offset_rad=imu.declination_rad, units="uT")


def _load_calibration(path: str) -> MagCalibration:
    return MagCalibration.from_dict(read_json(path, ConfigError), where=f"nodes.mag_calibration_file: {path}")


def add_state(stack: Stack, estimator: Any = None) -> None:
    """The state estimate: the configured estimator (or the given one: harnesses), or the truth;
    and the soundings placed by it (depth/sounding: nothing happens without an echosounder)."""
    _add_estimator(stack, estimator)
    v = stack.config.vessel
    stack.add(SoundingNode(v.transducer_m, v.transducer_draft_m))


def _add_estimator(stack: Stack, estimator: Any = None) -> None:
    cfg = stack.config.nodes
    if estimator is not None:
        stack.add(FusionNode(estimator, getattr(estimator, "calibration", None),
                             sea_state=SeaStateConfig(hull_m=stack.config.vessel.hull_m)))
        return
    if cfg.fusion == "truth":
        if stack.simulator is None:
            raise ConfigError("nodes.fusion: 'truth' exists only in simulation")
        stack.add(TruthStateNode())
        return
    calibration = (_load_calibration(cfg.mag_calibration_file) if cfg.mag_calibration_file
                   else twin_factory_calibration(stack))
    o = stack.origin
    origin = (o.lat_deg, o.lon_deg, o.height_m) if o is not None else None
    if cfg.fusion == "ekf":
        estimator: Any = ModelAidedEKF(stack.model, calibration, EkfConfig(
            origin=origin, gnss_antenna_m=stack.config.vessel.gnss_antenna_m,
            gnss_antenna_height_m=stack.config.vessel.gnss_antenna_height_m))
    else:
        estimator = SeedFilters(calibration, SeedFiltersConfig(origin=origin))
    stack.add(FusionNode(estimator, calibration, sea_state=SeaStateConfig(hull_m=stack.config.vessel.hull_m)))


def heading_calibration(stack: Stack) -> str:
    """Where the magnetometer calibration the estimator starts with comes from, for the pre-arm
    heading check; "" when there is none (hardware without nodes.mag_calibration_file)."""
    cfg = stack.config.nodes
    if cfg.fusion == "truth":
        return "not needed: the simulator's truth is the estimate"
    if cfg.mag_calibration_file:
        return f"nodes.mag_calibration_file {cfg.mag_calibration_file}"
    if stack.simulator is not None:
        return "the simulated magnetometer's factory values"
    return ""


#: raw samples sent with a fit for the operator's plot (one turn at the magnetometer's rate is more)
MAG_PLOT_POINTS = 200


def mag_calibrator(samples: list[tuple[float, float]]) -> MagCalibrationResult:
    cal = fit_mag_calibration([s[0] for s in samples], [s[1] for s in samples], units="uT")
    step = max(1, -(-len(samples) // MAG_PLOT_POINTS))
    return MagCalibrationResult(stamp_s=0.0, ok=True, center=tuple(cal.center), matrix=cal.matrix,
                                residual=cal.residual_rms, coverage_deg=cal.coverage_deg,
                                samples=tuple((round(float(x), 3), round(float(y), 3)) for x, y in samples[::step]),
                                text=f"{cal.n_points} points, coverage {cal.coverage_deg:.0f} deg, "
                                     f"residual {cal.residual_rms:.3f}")


class ModelInfoNode(Node):
    """Publishes which model is in use (and where it came from) once at start; the bridge latches it."""

    name = "model_info"

    def __init__(self, info: ModelInfo) -> None:
        self.info = info

    def start(self, ctx: NodeContext) -> None:
        self.info.stamp_s = ctx.now()
        ctx.publish(Topic.MODEL, self.info)


def add_supervisor(stack: Stack, follower: Any = None, station_keeper: Any = None) -> SupervisorNode:
    """The supervisor with the configured controllers (or the given ones: harnesses), holding
    the launch config's route planned here once, before the control loop starts."""
    cfg = stack.config
    # a wall-clock limit on the MPC's solve only at wall-clock pace: on simulated time the answer
    # must not depend on how busy the machine is
    solve_limit_s = REALTIME_SOLVE_LIMIT_S if isinstance(stack.executor, RealtimeExecutor) else 0.0
    control = ControlConfig(controller=cfg.nodes.controller, mpc=MPCConfig(time_limit_s=solve_limit_s))
    # the controllers' actuator limits are the model's, never the simulated boat's
    sup = SupervisorNode(stack.model, DEFAULT_LIMITS,
                         SupervisorConfig(control_rate_hz=cfg.nodes.control_rate_hz,
                                          controller=cfg.nodes.controller,
                                          failsafes=cfg.extra.failsafes, planner=cfg.extra.planner),
                         control_config=control,
                         mag_calibrator=mag_calibrator, follower=follower, station_keeper=station_keeper,
                         heading_calibration=heading_calibration(stack))
    if cfg.route:
        route = load_route(cfg.route)
        msg = planned_route_message(route, plan_route(route, cfg.extra.planner), source="config")
        path = path_from_message(msg)
        # the corridor now, at start-up: on the loop a survey's took 0.17 s (pre-arm checks)
        sup.set_route(route, path, msg.route_id, msg.node_s_m, route_corridor_m(route, path))
        if route.area is not None:  # the configured area is the boat's own: no upload may leave it
            sup.fence = route
    stack.add(sup)
    stack.add(ModelInfoNode(model_info(cfg, stack.model)))
    return sup


def add_recorder(stack: Stack) -> None:
    # always attached: it records from the start when logging.enabled, and otherwise waits idle
    # for the operator's logging_on
    _add_recorder(stack)


def add_zenoh(stack: Stack) -> None:
    # bridges the bus to other processes/machines when the config has an `extra.zenoh` section
    add_bridge(stack)


def add_web(stack: Stack) -> None:
    if stack.config.web.enabled:
        _add_web(stack)
