"""The page's Predict: a route's time and energy before the boat leaves (lotsen.stack.prediction),
as a picklable job for the planner worker. Light on purpose: the web process builds it at start and
must not carry the controllers and the simulator; the worker imports them when it runs the job."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class PagePredictor:
    """Plans the route as the planner worker does and predicts it on the run's model in use with its
    controller, in the current the estimator knows now (the estimate's `current_ne_mps`; the EKF folds a
    steady wind into it). Runs under the budget's `predict_time_s` (PlannerWorker reads `budget_key`)."""

    parameters: Any  # lotsen.model.VesselParameters of the model in use
    geometry: Any    # lotsen.model.VesselGeometry
    model_name: str
    controller: str
    planner: Any     # the run's PlannerConfig
    budget_key = "predict_time_s"

    def __call__(self, route_data: dict, current_ne_mps: tuple[float, float]) -> dict[str, Any]:
        from lotsen.control import ControlConfig
        from lotsen.errors import LotsenError
        from lotsen.model import VesselModel
        from lotsen.planning import plan_route
        from lotsen.planning.io import route_from_dict
        from lotsen.planning.survey.keeping import line_spans
        from lotsen.stack.prediction import predict_mission

        try:
            route = route_from_dict(route_data)
            path = plan_route(route, self.planner)
            c = [float(v) if math.isfinite(float(v)) else 0.0 for v in current_ne_mps]
            p = predict_mission(path, VesselModel(self.parameters, self.geometry), current_ne_mps=(c[0], c[1]),
                                control=ControlConfig(controller=self.controller),
                                survey_lines=line_spans(route, path), model_name=self.model_name)
        except LotsenError as exc:
            return {"ok": False, "error": str(exc)}
        return {"ok": True, **p.as_dict()}
