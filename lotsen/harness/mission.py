"""Closed-loop mission harness: a path follower (and the station keeper at the end) on the simulated boat.

It runs the stack's own closed loop on simulated time (lotsen.stack.launch.build_stack: the
simulated boat node with its actuator guard, the estimator node, the supervisor with its modes
and failsafes), so a harness figure is a figure of the product's loop, failsafes included.

    result = run_mission(path, make_path_follower(ControlConfig(controller="mpc")),
                         MissionConfig(environment=Environment(current_speed_mps=0.1)))
    result.metrics["cross_track_rms_m"]

The simulator steps at its own rate (100 Hz); the controller runs every `1 / control_rate_hz`
seconds on the true state, or on an estimator's output (`estimator=` an object with
on_imu / on_mag / on_gnss / on_command and estimate(t) -> VesselState, e.g. lotsen.fusion's EKF).
When the follower reports `done` (end of the path), the supervisor holds the last point and
heading for `hold_s`; a failsafe that takes the boat out of AUTO ends the mission as not
completed, with the failsafe named. Simulated time only, seeded noise: deterministic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lotsen.control import (
    ControlConfig, PathFollower, PathReference, StationKeeper, make_path_follower, make_station_keeper,
)
from lotsen.fusion import EkfConfig, MagCalibration, ModelAidedEKF
from lotsen.messages import ActuatorState, ControllerStatus, OperatorCommand, SupervisorStatus, ThrustCommand, Topic, VesselState
from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, Environment, VesselModel
from lotsen.model.angles import wrap_angle
from lotsen.planning.survey.keeping import LineSpan, line_keeping, track_on_path
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection, WebSection
from lotsen.runtime.executor import Node, NodeContext
from lotsen.sim import DEFAULT_BOAT, Plant, SimConfig, SimulatedBoat, Simulator
from lotsen.sim.activity import actuator_activity
from lotsen.stack.launch import Harness, build_stack


#: the hold's settled figures count from this long after the path's end (the approach to the point)
HOLD_SETTLE_S = 10.0


@dataclass(frozen=True)
class MissionConfig:
    control_rate_hz: float = 10.0
    sim_dt_s: float = 0.01
    environment: Environment = field(default_factory=Environment)
    seed: int = 0
    sensors: bool = False  # True when an estimator consumes the sensor messages
    hold_s: float = 10.0  # station keeping at the end of the path
    max_duration_s: float | None = None  # default: 2 x planned time + 60 s
    abort_cross_track_m: float = 5.0  # the mission fails if the vessel strays this far
    start_offset_m: tuple[float, float] = (0.0, 0.0)  # initial (along-track, cross-track) offset
    start_heading_offset_rad: float = 0.0
    record_predictions: bool = False


@dataclass
class MissionResult:
    completed: bool
    reason: str
    metrics: dict[str, Any]
    t: np.ndarray  # control ticks (s)
    x: np.ndarray  # true state at each tick (K x 6)
    x_used: np.ndarray  # state the controller saw (truth or estimate)
    u: np.ndarray  # commands (K x 5)
    cross_track_m: np.ndarray
    heading_error_rad: np.ndarray
    speed_mps: np.ndarray
    speed_ref_mps: np.ndarray
    progress_m: np.ndarray
    solve_time_ms: np.ndarray
    mode: np.ndarray  # "follow" or "hold" per tick
    statuses: list[ControllerStatus]
    path: Any
    cross_track_estimated_m: np.ndarray | None = None  # the controller's view when an estimator ran
    failsafes: tuple[str, ...] = ()  # failsafes active at the end
    achieved: np.ndarray | None = None  # achieved actuators (K x 5: angles rad, speeds rev/s) when the boat reports them

    @property
    def n_achieved(self) -> np.ndarray | None:
        """Achieved propeller speeds (K x 3, rev/s) when the boat reports them."""
        return self.achieved[:, 2:5] if self.achieved is not None else None


def planned_duration_s(path: Any, min_speed_mps: float = 0.15) -> float:
    v = np.maximum(np.asarray(path.speed_mps, dtype=float), min_speed_mps)
    ds = np.diff(np.asarray(path.s_m, dtype=float))
    return float(np.sum(ds / (0.5 * (v[1:] + v[:-1]))))


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(a)))) if a.size else float("nan")


class _TickRecorder(Node):
    """Samples the loop at every control tick: truth, the state the controller saw, the command,
    the controller's status and the supervisor's mode."""

    name = "mission_trace"

    def __init__(self, abort_cross_track_m: float) -> None:
        self.rows: list[tuple] = []
        self.statuses: list[ControllerStatus] = []
        self.abort_cross_track_m = abort_cross_track_m
        self.aborted = ""
        self._cmd: ThrustCommand | None = None
        self._sup: SupervisorStatus | None = None
        self._act: ActuatorState | None = None
        self.achieved: list[tuple[float, ...]] = []

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.SHIP_COMMAND, self._on_command)
        ctx.subscribe(Topic.CONTROL_STATUS, self._on_status)
        ctx.subscribe(Topic.SUPERVISOR, self._on_supervisor)
        ctx.subscribe(Topic.ACTUATORS, self._on_actuators)

    def _on_actuators(self, a: ActuatorState) -> None:
        self._act = a

    def _on_command(self, cmd: ThrustCommand) -> None:
        self._cmd = cmd

    def _on_supervisor(self, s: SupervisorStatus) -> None:
        self._sup = s

    def _on_status(self, status: ControllerStatus) -> None:
        latest = self.ctx.bus.latest
        truth, state, cmd = latest.get(Topic.TRUTH), latest.get(Topic.STATE), self._cmd
        if truth is None or state is None or cmd is None or self._sup is None:
            return
        mode = "follow" if self._sup.mode in ("AUTO", "RETURN") else "hold"
        self.statuses.append(status)
        self.rows.append((self.ctx.now(), truth.as_array_tuple(), state.as_array_tuple(), cmd.as_tuple(),
                          status.cross_track_error_m, status.heading_error_rad, status.speed_mps,
                          status.speed_ref_mps, status.progress_m, status.solve_time_ms, mode))
        act = self._act
        self.achieved.append(act.as_tuple() if act is not None else (math.nan,) * 5)
        if mode == "follow" and abs(status.cross_track_error_m) > self.abort_cross_track_m and not self.aborted:
            self.aborted = (f"aborted: cross-track error {status.cross_track_error_m:.2f} m "
                            f"at t = {self.ctx.now():.1f} s")


def run_mission(path: Any, follower: PathFollower | None = None, config: MissionConfig = MissionConfig(),
                *, station_keeper: StationKeeper | None = None, model: VesselModel | None = None,
                boat: SimulatedBoat | None = None, sim_model: VesselModel | None = None,
                limits: ActuatorLimits = DEFAULT_LIMITS, estimator: Any = None,
                sim_config: SimConfig | None = None, plant: Plant | None = None,
                survey_lines: tuple[LineSpan, ...] = ()) -> MissionResult:
    """Run one mission in simulation on the stack's closed loop: the simulated boat node (with
    its actuator guard), the estimator node (or the truth), and the supervisor with its
    failsafes, armed and sent to AUTO at the start. `model` is the controllers' and the
    estimator's model (default: the default model); `boat` the simulated boat (default: the lake
    boat, which is not the default model). `sim_model`: a boat exactly equal to that model
    (no unmodelled effects; `SimulatedBoat.ideal_for`). `plant`: another body behind lotsen's
    sensors instead (an external physics, `lotsen.physics.client.UdpPhysics`, or any `Plant`),
    placed at the path's start; its water and air are its own (`config.environment` must be calm).
    `survey_lines`: a survey's lines on the path (`lotsen.planning.survey.keeping.line_spans`): the
    report gets their line keeping (`survey`)."""
    model = model or VesselModel()
    follower = follower or make_path_follower(ControlConfig(), model, limits)
    keeper = station_keeper or make_station_keeper(ControlConfig(), model, limits)
    sim_cfg = sim_config or SimConfig(dt_s=config.sim_dt_s, seed=config.seed, environment=config.environment,
                                      sensors=config.sensors or estimator is not None)
    along, cross = config.start_offset_m
    h0 = float(path.heading_rad[0])
    x0 = [float(path.north_m[0]) + along * math.cos(h0) - cross * math.sin(h0),
          float(path.east_m[0]) + along * math.sin(h0) + cross * math.cos(h0),
          h0 + config.start_heading_offset_rad, 0.0, 0.0, 0.0]
    if plant is not None:
        if boat is not None or sim_model is not None:
            raise ValueError("run_mission: give a plant or a boat, not both")
        sim = Simulator(plant, config=sim_cfg, x0=x0)
    else:
        if boat is None:
            boat = SimulatedBoat.ideal_for(sim_model, limits) if sim_model is not None else DEFAULT_BOAT
        sim = Simulator(boat, config=sim_cfg, x0=x0)
    launch = LaunchConfig(seed=config.seed, nodes=NodesSection(fusion="truth" if estimator is None else "ekf",
                                                               control_rate_hz=config.control_rate_hz),
                          sim=SimSection(dt_s=sim_cfg.dt_s, esc_arm_time_s=0.0), web=WebSection(enabled=False),
                          # a controller run nobody watches, often without sensors (truth as the estimate)
                          extra={"failsafes": {"prearm_skip": ["pilot_link", "battery"]}})
    stack = build_stack(launch, realtime=False, parts=("state", "supervisor"),
                        harness=Harness(simulator=sim, model=model, estimator=estimator, follower=follower,
                                        station_keeper=keeper, truth_rate_hz=1.0 / sim_cfg.dt_s))
    sup = stack.nodes["supervisor"]
    sup.set_route(None, path)
    trace = stack.add(_TickRecorder(config.abort_cross_track_m))
    ex = stack.executor
    ex.run_until(0.0)  # first step: the ESCs report armed, the state is there
    for action in ("arm", "auto"):
        stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=0.0, action=action, source="mission"))
    t_max = config.max_duration_s or 2.0 * planned_duration_s(path) + 60.0
    t_done: list[float] = []

    def finished() -> bool:
        if trace.aborted or sup.mode.name not in ("AUTO", "HOLD"):
            return True
        if sup.mode.name == "HOLD" and sup.reason.startswith("auto finished"):
            if not t_done:
                t_done.append(ex.clock.now())
            return ex.clock.now() - t_done[0] >= config.hold_s
        return False

    ex.run_until(t_max, stop=finished)
    if trace.aborted:
        reason = trace.aborted
    elif t_done and ex.clock.now() - t_done[0] >= config.hold_s - 1e-9:
        reason = "completed"
    elif sup.mode.name not in ("AUTO", "HOLD") or (sup.mode.name == "HOLD" and not t_done):
        reason = f"aborted: mode {sup.mode.name} ({sup.reason})"
    else:
        reason = "timeout"
    rows = trace.rows
    arr = lambda i: np.array([r[i] for r in rows], dtype=float)  # noqa: E731
    modes = np.array([r[10] for r in rows])
    res = MissionResult(
        completed=reason == "completed", reason=reason, metrics={}, t=arr(0), x=arr(1).reshape(-1, 6),
        x_used=arr(2).reshape(-1, 6), u=arr(3).reshape(-1, 5), cross_track_m=arr(4), heading_error_rad=arr(5),
        speed_mps=arr(6), speed_ref_mps=arr(7), progress_m=arr(8), solve_time_ms=arr(9), mode=modes,
        statuses=trace.statuses, path=path, failsafes=tuple(sup.failsafes.active))
    achieved = np.array(trace.achieved, dtype=float).reshape(-1, 5)
    if achieved.size and np.all(np.isfinite(achieved)):
        res.achieved = achieved
    if estimator is not None and res.t.size:
        # the controller saw the estimate: measure the true errors against the path
        ref = PathReference(path)
        hint = 0.0
        true_cte = np.empty(res.t.size)
        for i, xi in enumerate(res.x):
            hint, true_cte[i], _ = ref.project(xi[0], xi[1], hint)
        res.cross_track_estimated_m = res.cross_track_m
        res.cross_track_m = true_cte
    res.metrics = mission_metrics(res, follower, t_done[0] if t_done else None)
    if survey_lines and res.t.size:
        res.metrics["survey"] = survey_keeping(res, survey_lines, t_done[0] if t_done else None).summary()
    res.metrics["failsafes_triggered"] = sorted({e.split(":")[0] for e in sup.failsafe_history})
    plant_status = sim.plant.status()  # an external physics's counters (lotsen's own boat has none)
    if plant_status:
        res.metrics["physics"] = plant_status
    return res


def survey_keeping(res: MissionResult, spans: tuple[LineSpan, ...], t_done: float | None) -> Any:
    """The line keeping of a survey mission on the true track (`lotsen.planning.survey.keeping`): per
    line the cross-track RMS and max, the distance after the turn until within 5 cm, the time on it;
    the share of the mission's time (AUTO until the route's end) on lines."""
    f = res.mode == "follow"
    s, cte = track_on_path(res.path, res.x[f, 0], res.x[f, 1])
    return line_keeping(spans, res.t[f], s, cte, t_done if t_done is not None else float(res.t[f][-1]))


def mission_metrics(res: MissionResult, follower: Any, t_done: float | None) -> dict[str, Any]:
    """The report's numbers: errors over the path-following phase, the actuators' activity during it
    (`actuator_activity`, on the achieved values where the boat reports them), the hold at the end."""
    f = res.mode == "follow"
    h = res.mode == "hold"
    cte = res.cross_track_m[f]
    hdg = res.heading_error_rad[f]
    spd = res.speed_mps[f] - res.speed_ref_mps[f]
    st = res.solve_time_ms[f]
    st = st[np.isfinite(st)]
    failures = int(getattr(follower, "failures", 0))
    out: dict[str, Any] = {
        "completed": bool(res.completed),
        "reason": res.reason,
        "controller": getattr(follower, "name", type(follower).__name__),
        "path_length_m": round(float(res.path.length_m), 3),
        "duration_s": round(float(t_done if t_done is not None else (res.t[-1] if res.t.size else 0.0)), 2),
        "cross_track_rms_m": round(_rms(cte), 4),
        "cross_track_max_m": round(float(np.max(np.abs(cte))) if cte.size else float("nan"), 4),
        "heading_error_rms_deg": round(math.degrees(_rms(hdg[np.isfinite(hdg)])), 3),
        "speed_error_rms_mps": round(_rms(spd[np.isfinite(spd)]), 4),
        "solve_time_median_ms": round(float(np.median(st)), 4) if st.size else None,
        "solve_time_max_ms": round(float(np.max(st)), 4) if st.size else None,
        "failures": failures,
    }
    # the actuators' work during path following: the achieved values if the boat reports them
    acts = res.achieved if res.achieved is not None else res.u
    out.update(actuator_activity(res.t[f], acts[f]))
    if "reversals_per_s" in out:
        out["reversals_counted_on"] = "achieved speeds" if res.achieved is not None else "commands"
    if np.any(h):
        xh = res.x[h]
        end_n, end_e = float(res.path.north_m[-1]), float(res.path.east_m[-1])
        out["hold_position_error_final_m"] = round(float(math.hypot(xh[-1, 0] - end_n, xh[-1, 1] - end_e)), 4)
        out["hold_heading_error_final_deg"] = round(math.degrees(abs(
            wrap_angle(xh[-1, 2] - float(res.path.heading_rad[-1])))), 3)
        # the settled hold (from HOLD_SETTLE_S after the path's end): RMS distance from the point
        th = res.t[h]
        settled = th >= th[0] + HOLD_SETTLE_S
        if np.count_nonzero(settled) > 1:
            d = np.hypot(xh[settled, 0] - end_n, xh[settled, 1] - end_e)
            out["hold_position_error_rms_m"] = round(_rms(d), 4)
            out["hold_position_error_max_m"] = round(float(np.max(d)), 4)
            out["hold"] = actuator_activity(th[settled], acts[h][settled])
    if res.x_used.size and not np.allclose(res.x_used, res.x):
        d = res.x_used[f, :2] - res.x[f, :2]
        out["estimate_position_error_rms_m"] = round(_rms(np.hypot(d[:, 0], d[:, 1])), 4)
    if res.cross_track_estimated_m is not None:
        out["cross_track_rms_estimated_m"] = round(_rms(res.cross_track_estimated_m[f]), 4)
    return out


def antenna_height_m(boat: SimulatedBoat | Plant) -> float:
    """The GNSS antenna's height above the roll and pitch centre, as measured on the hull."""
    return boat.hull.gnss_antenna_height_m if isinstance(boat, SimulatedBoat) else boat.gnss_antenna_height_m


def sim_mag_calibration(sim_config: SimConfig) -> MagCalibration:
    """The magnetometer calibration the simulated boat's distortion implies (what `lotsen calibrate`
    would find): its hard iron as the centre, soft iron times the horizontal field, the declination."""
    imu = sim_config.imu
    H = imu.earth_field_horizontal_uT
    (s00, s01), (s10, s11) = imu.soft_iron
    return MagCalibration(center=tuple(imu.hard_iron_uT), matrix=((H * s00, H * s01), (H * s10, H * s11)),
                          heading_offset_rad=imu.declination_rad)


def make_sim_ekf(config: MissionConfig, path: Any, model: VesselModel | None = None,
                 sim_config: SimConfig | None = None, boat: SimulatedBoat | Plant = DEFAULT_BOAT) -> ModelAidedEKF:
    """lotsen.fusion's model-aided EKF set up for the simulated boat (or plant): GNSS origin of the simulator,
    the boat's GNSS antenna position (measured on the hull, as `vessel.gnss_antenna_m`), the
    magnetometer calibration its distortion implies (what `lotsen calibrate` would find), and
    the start pose of the mission."""
    sc = sim_config or SimConfig()
    gnss = sc.gnss
    cal = sim_mag_calibration(sc)
    along, cross = config.start_offset_m
    h0 = float(path.heading_rad[0])
    x0 = VesselState(stamp_s=0.0, north_m=float(path.north_m[0]) + along * math.cos(h0) - cross * math.sin(h0),
                     east_m=float(path.east_m[0]) + along * math.sin(h0) + cross * math.cos(h0),
                     heading_rad=h0 + config.start_heading_offset_rad, u_mps=0.0, v_mps=0.0, r_radps=0.0)
    cfg = EkfConfig(origin=(gnss.origin_lat_deg, gnss.origin_lon_deg, gnss.origin_height_m),
                    gnss_antenna_m=boat.gnss_antenna_m, gnss_antenna_height_m=antenna_height_m(boat))
    return ModelAidedEKF(model or VesselModel(), cal, cfg, initial=x0,
                         initial_std=(0.5, 0.5, 0.2, 0.1, 0.1, 0.1, 0.02, 0.2, 0.2))
