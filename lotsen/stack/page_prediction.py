"""The page's Predict: a route's time and energy before the boat leaves (lotsen.stack.prediction),
as a picklable job for the planner worker. Light on purpose: the web process builds it at start and
must not carry the controllers and the simulator; the worker imports them when it runs the job."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class EstimatedConditions:
    """The water and the air as the running estimator knows them now (picklable, for the worker): the
    current over ground (north, east, m/s: the estimate's `current_ne_mps`; the EKF has no wind of its
    own, it folds a steady wind's push into this current) and the sea the IMU measures (fusion/sea_state:
    significant height m, peak period s, the direction it comes from, deg); `sea` None: flat water, or
    no valid estimate with a height, a period and a direction."""

    current_ne_mps: tuple[float, float] = (0.0, 0.0)
    sea: tuple[float, float, float] | None = None

    @property
    def waves(self) -> Any:
        """The sea as the prediction flies in it (lotsen.model.environment.Waves), None for flat water."""
        if self.sea is None:
            return None
        from lotsen.model.environment import Waves

        return Waves(hs_m=self.sea[0], tp_s=self.sea[1], from_deg=self.sea[2])


def estimated_conditions(current_ne_mps: Any, sea_state: Any) -> EstimatedConditions:
    """What the latest estimate's current (north, east) and sea state (SeaState) say, either may be None;
    values that are not finite count as unknown (the current as none, the sea as flat)."""
    current = (0.0, 0.0)
    if current_ne_mps is not None:
        c = [float(v) for v in current_ne_mps]
        current = (c[0], c[1]) if len(c) == 2 and all(math.isfinite(v) for v in c) else (0.0, 0.0)
    sea = None
    if sea_state is not None and getattr(sea_state, "valid", False):
        hs, tp, frm = (float(getattr(sea_state, k, math.nan)) for k in ("hs_m", "tp_s", "from_deg"))
        if all(math.isfinite(v) for v in (hs, tp, frm)) and hs > 0.0 and tp > 0.0:
            sea = (hs, tp, frm % 360.0)
    return EstimatedConditions(current, sea)


@dataclass(frozen=True)
class PagePredictor:
    """Plans the route as the planner worker does and predicts it on the run's model in use with its
    controller, in the current and the sea the estimator knows now (`EstimatedConditions`; None:
    nothing known, still water). Runs under the budget's `predict_time_s` (PlannerWorker reads
    `budget_key`)."""

    parameters: Any  # lotsen.model.VesselParameters of the model in use
    geometry: Any    # lotsen.model.VesselGeometry
    model_name: str
    controller: str
    planner: Any     # the run's PlannerConfig
    budget_key = "predict_time_s"

    def __call__(self, route_data: dict, conditions: EstimatedConditions | None) -> dict[str, Any]:
        from lotsen.control import ControlConfig
        from lotsen.errors import LotsenError
        from lotsen.model import VesselModel
        from lotsen.planning import plan_route
        from lotsen.planning.io import route_from_dict
        from lotsen.planning.survey.keeping import line_spans
        from lotsen.stack.prediction import predict_mission

        conditions = conditions if conditions is not None else EstimatedConditions()
        try:
            route = route_from_dict(route_data)
            path = plan_route(route, self.planner)
            p = predict_mission(path, VesselModel(self.parameters, self.geometry),
                                current_ne_mps=conditions.current_ne_mps, waves=conditions.waves,
                                control=ControlConfig(controller=self.controller),
                                survey_lines=line_spans(route, path), model_name=self.model_name)
        except LotsenError as exc:
            return {"ok": False, "error": str(exc)}
        return {"ok": True, **p.as_dict()}
