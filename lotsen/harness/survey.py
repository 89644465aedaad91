"""A survey flown on simulated time over a simulated lake bed, with the depth map it makes.

The stack `lotsen run` builds (simulated boat with its sounder over `sim.lakebed`, the state
estimate, the soundings node, the supervisor with its controller), the route uploaded as the page
uploads it (a `PlannedRoute` on planning/route), armed and sent to AUTO; the run ends when the
supervisor reports the route finished (or at `max_duration_s`). The soundings it published are
gridded (lotsen.bathymetry) and judged against the bed the simulator pinged: each cell's mean
against the bed's depth averaged under that cell's soundings (their true positions are what the
sounder saw; the estimate's error is part of the map's error).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from lotsen.bathymetry import DepthGrid, coverage
from lotsen.bathymetry.coverage import Coverage
from lotsen.messages import OperatorCommand, Sounding, SupervisorStatus, Topic, VesselState
from lotsen.planning import PlannerConfig, Route, plan_route
from lotsen.planning.exchange import planned_route_message
from lotsen.runtime.config import (
    EnvironmentConfig, LakeBedSection, LaunchConfig, LoggingSection, NodesSection, SimSection, WebSection,
)
from lotsen.runtime.executor import Node, NodeContext
from lotsen.stack.launch import build_stack


@dataclass(frozen=True)
class SurveyRunConfig:
    lakebed: LakeBedSection
    seed: int = 0
    fusion: str = "ekf"
    controller: str = "mpc"
    environment: EnvironmentConfig = EnvironmentConfig()
    cell_m: float = 2.0                   # the depth map's cell
    max_duration_s: float = 1800.0
    sounder_outage_s: tuple[float, float] | None = None   # no bottom found between these times (holes)
    failsafes: dict = field(default_factory=dict)
    log_dir: str | None = None            # record the run (MCAP) there


@dataclass
class SurveyRun:
    soundings: list[Sounding]
    truth: list[VesselState]
    grid: DepthGrid
    coverage: Coverage | None
    duration_s: float
    finished: bool
    modes: list[tuple[float, str, str]]
    cell_errors_m: np.ndarray             # per covered cell: map mean - the bed under its soundings
    wall_s: float
    log_path: Any = None

    def rms_cell_error_m(self) -> float:
        e = self.cell_errors_m
        return float(np.sqrt(np.mean(e**2))) if len(e) else math.nan


class _Observer(Node):
    name = "survey_trace"

    def __init__(self) -> None:
        self.soundings: list[Sounding] = []
        self.truth: list[VesselState] = []
        self.modes: list[tuple[float, str, str]] = []
        self.finished_at: float | None = None
        self.auto_seen = False

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.SOUNDING, self.soundings.append)
        ctx.subscribe(Topic.TRUTH, self.truth.append)
        ctx.subscribe(Topic.SUPERVISOR, self._on_status)

    def _on_status(self, s: SupervisorStatus) -> None:
        if not self.modes or self.modes[-1][1:] != (s.mode, s.reason):
            self.modes.append((self.ctx.now(), s.mode, s.reason))
        self.auto_seen |= s.mode == "AUTO"
        if self.auto_seen and self.finished_at is None and s.mode == "HOLD" and s.reason.startswith("auto finished"):
            self.finished_at = self.ctx.now()


def run_survey(route: Route, config: SurveyRunConfig, planner: PlannerConfig | None = None) -> SurveyRun:
    """Fly `route` (a survey route) on the simulated stack over `config.lakebed`."""
    t_wall = time.perf_counter()
    x0 = route.harbour
    launch = LaunchConfig(seed=config.seed, nodes=NodesSection(fusion=config.fusion, controller=config.controller),
                          sim=SimSection(initial_state=(x0.north_m, x0.east_m, x0.heading_rad, 0.0, 0.0, 0.0),
                                         environment=config.environment, lakebed=config.lakebed, esc_arm_time_s=0.0),
                          web=WebSection(enabled=False),
                          logging=LoggingSection(enabled=config.log_dir is not None, directory=config.log_dir or "logs"),
                          extra={"failsafes": {"prearm_skip": ["pilot_link"], **config.failsafes}})
    parts = ("state", "supervisor") + (("logs",) if config.log_dir is not None else ())
    stack = build_stack(launch, realtime=False, parts=parts)
    obs = stack.add(_Observer())
    ex = stack.executor
    path = plan_route(route, planner or PlannerConfig())
    ex.run_until(1.0)
    stack.bus.publish(Topic.ROUTE, planned_route_message(route, path, stamp_s=ex.clock.now(), source="survey"))
    for t, action in ((2.0, "arm"), (3.0, "auto")):
        ex.run_until(t)
        stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=ex.clock.now(), action=action, source="survey"))
    sim = stack.simulator
    outage = config.sounder_outage_s
    if outage is not None and sim.sounder is not None:
        normal = sim.sounder.config
        ex.run_until(3.0 + outage[0])
        sim.sounder.config = replace(normal, dropout_probability=1.0)
        ex.run_until(3.0 + outage[1])
        sim.sounder.config = normal
    end = 3.0 + config.max_duration_s
    while obs.finished_at is None and ex.clock.now() < end:
        ex.run_until(min(end, ex.clock.now() + 10.0))
    log_path = None
    rec = stack.services.get("recorder")
    if rec is not None:
        log_path = rec.path
    stack.shutdown()
    grid = DepthGrid(config.cell_m)
    for s in obs.soundings:
        grid.add(s.north_m, s.east_m, s.depth_m)
    cov = None
    if route.survey is not None and route.survey.polygon is not None:
        cov = coverage(grid, route.survey.polygon)
    return SurveyRun(obs.soundings, obs.truth, grid, cov, (obs.finished_at or ex.clock.now()) - 3.0,
                     obs.finished_at is not None, obs.modes, cell_errors(grid, obs.soundings, obs.truth, sim),
                     time.perf_counter() - t_wall, log_path)


def cell_errors(grid: DepthGrid, soundings: list[Sounding], truth: list[VesselState], sim: Any) -> np.ndarray:
    """Per cell of `grid`: its mean depth less the bed's depth averaged at the transducer's true
    positions at its soundings' times (the truth interpolated at each ping)."""
    if not soundings or not truth or sim.sounder is None:
        return np.array([])
    from lotsen.model.angles import lever_arm_ne

    t = np.array([s.stamp_s for s in truth])
    n = np.array([s.north_m for s in truth])
    e = np.array([s.east_m for s in truth])
    psi = np.unwrap([s.heading_rad for s in truth])
    arm = sim.sounder.config.transducer_m
    sums: dict[tuple[int, int], list[float]] = {}
    for s in soundings:
        tn, te, tp = (float(np.interp(s.stamp_s, t, a)) for a in (n, e, psi))
        dn, de = lever_arm_ne(tp, arm)
        bed = float(sim.sounder.bed.depth_at(tn + dn, te + de))
        k = grid.key(s.north_m, s.east_m)
        sums.setdefault(k, []).append(bed)
    out = []
    for k, beds in sums.items():
        cell = grid.cell(k)
        if cell is not None:
            out.append(cell[1] - float(np.mean(beds)))
    return np.asarray(out)
