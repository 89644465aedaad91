"""A mission's time and energy predicted before the boat leaves (issue 48 item 3).

`Path.duration_s()` is the planner's nominal time: each step at its planned speed. What the boat
takes and draws depends on the model in use (identified or the defaults), the controller and the
water and air: so the prediction flies the path with the controller in use on a boat equal to the
model in use (`SimulatedBoat.ideal_for`), on simulated time, in the current and wind the estimator
knows (the controller is given that current, as the estimate carries it), and in the sea given (a
`Waves`, as `lotsen mission --waves` gives it; a wind sea costs energy: `lotsen mission survey_lake --waves
0.05,0.9,45` in 0.1 m/s current and 3 m/s wind flew 26.2 Wh against 11.8 Wh predicted in flat water,
2026-11-28). Its figures are measured
as a flown mission's are: the duration from the start to the route's end, the motors' electrical
energy from the propeller speeds (`lotsen.sim.propulsion_energy_j`, the measure of the mission
report's `energy_J`), the time on survey lines (`lotsen.planning.survey.keeping`).

Cost: one controller step and ten simulator steps per 0.1 s of mission; measured 2026-11-28 on this
machine ~7 ms of CPU per simulated second with the MPC (the 40 x 30 m survey, 1000 s: ~7 s).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from lotsen.control import ControlConfig, make_path_follower
from lotsen.messages import VesselState
from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, Environment, VesselModel
from lotsen.model.environment import Waves
from lotsen.planning.survey.keeping import LineSpan, line_keeping, track_on_path
from lotsen.sim import SimConfig, SimulatedBoat, Simulator, propulsion_energy_j
from lotsen.sim.loop import control_ticks

#: the prediction gives up after this multiple of the planned time (+ 60 s): a path the model cannot fly
MAX_TIME_FACTOR = 2.0


@dataclass(frozen=True)
class MissionPrediction:
    """What a mission is predicted to take: time (s) from the start to the route's end, the motors'
    electrical energy (J) and mean power (W) over it, the time on survey lines (s; 0 without lines),
    whether the model reached the end, and what it was predicted with."""

    duration_s: float
    energy_J: float
    mean_power_W: float
    planned_duration_s: float
    time_on_lines_s: float
    reached_end: bool
    model: str
    controller: str
    current_ne_mps: tuple[float, float]
    wind_mps: float
    wind_from_deg: float
    cpu_s: float
    waves: Waves | None = None

    @property
    def share_on_lines(self) -> float:
        return self.time_on_lines_s / self.duration_s if self.duration_s > 0 else math.nan

    def as_dict(self) -> dict[str, Any]:
        out = {"duration_s": round(self.duration_s, 1), "energy_J": round(self.energy_J, 0),
               "energy_Wh": round(self.energy_J / 3600.0, 3), "mean_power_W": round(self.mean_power_W, 2),
               "planned_duration_s": round(self.planned_duration_s, 1), "reached_end": self.reached_end,
               "model": self.model, "controller": self.controller,
               "current_ne_mps": [round(c, 3) for c in self.current_ne_mps], "wind_mps": round(self.wind_mps, 2),
               "wind_from_deg": round(self.wind_from_deg, 1), "cpu_s": round(self.cpu_s, 2),
               "waves": None if self.waves is None else {"hs_m": self.waves.hs_m, "tp_s": self.waves.tp_s,
                                                         "from_deg": self.waves.from_deg}}
        if self.time_on_lines_s > 0:
            out["time_on_lines_s"] = round(self.time_on_lines_s, 1)
            out["share_on_lines"] = round(self.share_on_lines, 4)
        return out


def predict_mission(path: Any, model: VesselModel | None = None, *, current_ne_mps: tuple[float, float] = (0.0, 0.0),
                    wind_mps: float = 0.0, wind_from_deg: float = 0.0, control: ControlConfig = ControlConfig(),
                    limits: ActuatorLimits = DEFAULT_LIMITS, survey_lines: tuple[LineSpan, ...] = (),
                    model_name: str = "default coefficients", sim_dt_s: float = 0.01,
                    waves: Waves | None = None) -> MissionPrediction:
    """Fly `path` from its start at rest with `control`'s controller on a boat equal to `model`, in the
    current (north, east, m/s over ground), the wind (m/s, from deg) and the sea (`waves`; None: flat
    water) given; the controller sees the true state with that current, as it sees the estimator's."""
    cpu0 = time.process_time()
    model = model or VesselModel()
    speed = math.hypot(*current_ne_mps)
    env = Environment(current_speed_mps=speed, current_to_deg=math.degrees(math.atan2(current_ne_mps[1],
                                                                                   current_ne_mps[0])),
                      wind_speed_mps=wind_mps, wind_from_deg=wind_from_deg,
                      waves=waves if waves is not None and waves.hs_m > 0.0 else None)
    h0 = float(path.heading_rad[0])
    sim = Simulator(SimulatedBoat.ideal_for(model, limits), config=SimConfig(dt_s=sim_dt_s, sensors=False,
                                                                             environment=env),
                    x0=[float(path.north_m[0]), float(path.east_m[0]), h0, 0.0, 0.0, 0.0])
    follower = make_path_follower(control, model, limits)
    follower.reset(path)
    cur = (float(current_ne_mps[0]), float(current_ne_mps[1]))

    def step(t: float, state: VesselState) -> Any:
        return follower.update(t, replace(state, current_ne_mps=cur))

    planned = float(path.duration_s())
    t_max = MAX_TIME_FACTOR * planned + 60.0
    ts, xs, ns = [], [], []
    period = round(control.dt_s / sim_dt_s) * sim_dt_s
    for tick in control_ticks(sim, step, period, until_s=t_max):
        a = sim.actuators.state
        ts.append(tick.t_s + period)
        xs.append(sim.x[:2])
        ns.append((a[2], a[3], a[4]))
        if follower.done:
            break
    t = np.asarray(ts)
    energy = propulsion_energy_j(t, np.asarray(ns))
    duration = float(t[-1]) if t.size else 0.0
    on_lines = 0.0
    if survey_lines and t.size:
        xy = np.asarray(xs)
        s, cte = track_on_path(path, xy[:, 0], xy[:, 1])
        on_lines = line_keeping(survey_lines, t, s, cte, duration).time_on_lines_s
    return MissionPrediction(duration_s=duration, energy_J=energy, mean_power_W=energy / duration if duration else 0.0,
                             planned_duration_s=planned, time_on_lines_s=on_lines, reached_end=bool(follower.done),
                             model=model_name, controller=getattr(follower, "name", control.controller),
                             current_ne_mps=cur, wind_mps=float(wind_mps), wind_from_deg=float(wind_from_deg),
                             cpu_s=time.process_time() - cpu0, waves=env.waves)


def compare_with_flown(prediction: MissionPrediction, duration_s: float, energy_J: float) -> dict[str, float]:
    """Predicted against flown: each figure's relative error ((predicted - flown) / flown)."""
    def rel(p: float, f: float) -> float | None:
        return round((p - f) / f, 4) if f > 0 else None
    return {"duration_flown_s": round(duration_s, 1), "duration_predicted_s": round(prediction.duration_s, 1),
            "duration_error": rel(prediction.duration_s, duration_s),
            "energy_flown_J": round(energy_J, 0), "energy_predicted_J": round(prediction.energy_J, 0),
            "energy_error": rel(prediction.energy_J, energy_J)}

