"""The optional parts of a stack and how each joins it (registered with `register_part`).

Order matters: the state estimate first, then the supervisor (which runs the controllers), then
the recorder and the web server, which only observe and relay.
"""

from __future__ import annotations

import importlib
import math
from typing import Any

from lotsen.errors import ConfigError, LotsenError
from lotsen.messages import MagCalibrationResult, MagSample, Topic, VesselState
from lotsen.runtime.executor import Node, NodeContext
from lotsen.runtime.launch import Stack, register_part


class TruthStateNode(Node):
    """fusion: truth — republishes the simulator's ground truth as the state estimate."""

    name = "state_truth"

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.TRUTH, self._on_truth)

    def _on_truth(self, msg: VesselState) -> None:
        est = VesselState(stamp_s=msg.stamp_s, north_m=msg.north_m, east_m=msg.east_m,
                          heading_rad=msg.heading_rad, u_mps=msg.u_mps, v_mps=msg.v_mps, r_radps=msg.r_radps,
                          source="truth")
        self.ctx.publish(Topic.STATE, est)
        self.ctx.publish(Topic.SENS_FUS, est)


class FusionNode(Node):
    """Runs an estimator (the model-aided EKF or the seed's filters) on the sensor topics and
    publishes state/estimate and imu/sens_fus at `rate_hz`, and imu/mag_calibrated per sample."""

    name = "fusion"

    def __init__(self, estimator: Any, calibration: Any, rate_hz: float = 20.0) -> None:
        self.estimator = estimator
        self.calibration = calibration
        self.period_s = 1.0 / rate_hz

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        est = self.estimator
        ctx.subscribe(Topic.IMU_RAW, self._guard(est.on_imu))
        ctx.subscribe(Topic.IMU_MAG, self._on_mag)
        ctx.subscribe(Topic.GNSS, self._guard(est.on_gnss))
        ctx.subscribe(Topic.SHIP_COMMAND, self._guard(est.on_command))
        ctx.subscribe(Topic.MAG_CALIBRATION, self._on_calibration)
        ctx.add_timer(self.period_s, self._publish)

    def _guard(self, fn: Any) -> Any:
        # a sensor message that upsets the filter is counted and dropped, never fatal
        def call(msg: Any) -> None:
            try:
                fn(msg)
            except (ValueError, ArithmeticError, LotsenError) as exc:
                self.ctx.log("warning", f"fusion dropped a {type(msg).__name__}: {exc}")
        return call

    def _on_mag(self, msg: MagSample) -> None:
        from lotsen.fusion import calibrated_heading

        self._guard(self.estimator.on_mag)(msg)
        if all(math.isfinite(v) for v in msg.field_uT[:2]):
            self.ctx.publish(Topic.IMU_MAG_CALIBRATED, calibrated_heading(msg, self.calibration))

    def _on_calibration(self, result: MagCalibrationResult) -> None:
        from lotsen.fusion import MagCalibration

        if result.ok:
            self.calibration = MagCalibration(center=result.center, matrix=result.matrix,
                                              residual_rms=result.residual, coverage_deg=result.coverage_deg)
            self.estimator.calibration = self.calibration
            if hasattr(self.estimator, "set_calibration"):
                self.estimator.set_calibration(self.calibration)

    def _publish(self) -> None:
        t = self.ctx.now()
        try:
            est = self.estimator.estimate(t)
        except (ValueError, ArithmeticError) as exc:
            self.ctx.log("error", f"fusion estimate failed: {exc}")
            return
        if est is None:
            return
        self.ctx.publish(Topic.STATE, est)
        self.ctx.publish(Topic.SENS_FUS, est)


def twin_factory_calibration(stack: Stack) -> Any:
    """The simulated magnetometer's distortion as a calibration (the twin's 'factory' values).

    Lets `make run` start with a sensible heading; the operator's calibrate_mag replaces it.
    """
    from lotsen.fusion import MagCalibration

    imu = stack.simulator.config.imu if stack.simulator else None
    if imu is None:
        return MagCalibration.identity()
    H = imu.earth_field_horizontal_uT
    S = imu.soft_iron
    return MagCalibration(center=imu.hard_iron_uT, matrix=((S[0][0] * H, S[0][1] * H), (S[1][0] * H, S[1][1] * H)),
                          heading_offset_rad=imu.declination_rad, units="uT")


def _load_calibration(path: str) -> Any:
    from lotsen.files import read_json
    from lotsen.fusion import MagCalibration

    return MagCalibration.from_dict(read_json(path, ConfigError), where=f"nodes.mag_calibration_file: {path}")


def add_state(stack: Stack) -> None:
    cfg = stack.config.nodes
    if cfg.fusion == "truth":
        if stack.simulator is None:
            raise ConfigError("nodes.fusion: 'truth' exists only in simulation")
        stack.add(TruthStateNode())
        return
    from lotsen.fusion import EkfConfig, ModelAidedEKF, SeedFilters, SeedFiltersConfig

    calibration = (_load_calibration(cfg.mag_calibration_file) if cfg.mag_calibration_file
                   else twin_factory_calibration(stack))
    origin = _gnss_origin(stack)
    if cfg.fusion == "ekf":
        estimator = ModelAidedEKF(stack.model, calibration, EkfConfig(origin=origin))
    else:
        estimator = SeedFilters(calibration, SeedFiltersConfig(origin=origin))
    stack.add(FusionNode(estimator, calibration))


def _gnss_origin(stack: Stack) -> tuple[float, float, float] | None:
    extra = stack.config.extra.get("origin")
    if extra:
        return (float(extra["lat_deg"]), float(extra["lon_deg"]), float(extra.get("height_m", 0.0)))
    if stack.simulator is not None:
        g = stack.simulator.config.gnss
        return (g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m)
    return None


def _mag_calibrator(samples: list[tuple[float, float]]) -> MagCalibrationResult:
    from lotsen.fusion import fit_mag_calibration

    cal = fit_mag_calibration([s[0] for s in samples], [s[1] for s in samples], units="uT")
    return MagCalibrationResult(stamp_s=0.0, ok=True, center=tuple(cal.center), matrix=cal.matrix,
                                residual=cal.residual_rms, coverage_deg=cal.coverage_deg,
                                text=f"{cal.n_points} points, coverage {cal.coverage_deg:.0f} deg, "
                                     f"residual {cal.residual_rms:.3f}")


def add_supervisor(stack: Stack) -> None:
    from lotsen.runtime.supervisor import SupervisorConfig, SupervisorNode

    cfg = stack.config
    sup = SupervisorNode(stack.model, stack.simulator.limits if stack.simulator else _limits(),
                         SupervisorConfig(control_rate_hz=cfg.nodes.control_rate_hz,
                                          controller=cfg.nodes.controller,
                                          failsafes=_failsafe_config(stack)),
                         mag_calibrator=_mag_calibrator)
    if cfg.route:
        from lotsen.planning import plan_route
        from lotsen.planning.io import load_route

        route = load_route(cfg.route)
        sup.set_route(route, plan_route(route))
    stack.add(sup)
    if sup.path is not None:
        from lotsen.runtime.supervisor import _path_message

        stack.bus.publish(Topic.PATH, _path_message(0.0, sup.path, sup.config.path_message_points))
    from lotsen.planning.io import route_to_dict

    stack.services["route"] = route_to_dict(sup.route) if sup.route is not None else None


def _limits() -> Any:
    from lotsen.model import DEFAULT_LIMITS

    return DEFAULT_LIMITS


def _failsafe_config(stack: Stack) -> Any:
    from lotsen.runtime.config import from_mapping
    from lotsen.runtime.failsafes import FailsafeConfig

    try:
        return from_mapping(FailsafeConfig, stack.config.extra.get("failsafes", {}), "extra.failsafes")
    except ConfigError:
        raise


def _optional(module: str, function: str) -> Any:
    try:
        return getattr(importlib.import_module(module), function)
    except ModuleNotFoundError as exc:
        if exc.name and module.startswith(exc.name):
            return None
        raise


def add_recorder(stack: Stack) -> None:
    # always attached: it records from the start when logging.enabled, and otherwise waits idle
    # for the operator's logging_on
    fn = _optional("lotsen.logs.part", "add_recorder")
    if fn is not None:
        fn(stack)


def add_zenoh(stack: Stack) -> None:
    # bridges the bus to other processes/machines when the config has an `extra.zenoh` section
    fn = _optional("lotsen.transport.part", "add_bridge")
    if fn is not None:
        fn(stack)


def add_web(stack: Stack) -> None:
    fn = _optional("lotsen.web.part", "add_web")
    if fn is not None and stack.config.web.enabled:
        fn(stack)


register_part("state", add_state)
register_part("supervisor", add_supervisor)
register_part("logs", add_recorder)
register_part("zenoh", add_zenoh)
register_part("web", add_web)
