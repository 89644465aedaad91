"""The time and energy of a mission predicted before the boat leaves, for the commands (`lotsen plan
--predict`, `lotsen mission`'s report): the flags of current and wind, the model in use, the
prediction itself (lotsen.stack.prediction) and its one line for the console."""

from __future__ import annotations

import math

from lotsen.errors import ConfigError
from lotsen.settings import Number

#: the environment's ranges are the config's (sim.environment), one definition
_CURRENT_MPS, _WIND_MPS, _DIRECTION_DEG = Number(0.0, 2.0, "m/s"), Number(0.0, 20.0, "m/s"), Number(-360.0, 360.0, "deg")


def parse_speed_dir(text: str | None, what: str) -> tuple[float, float]:
    """'0.1,90' -> (0.1, 90.0); ConfigError naming the option otherwise."""
    if text is None:
        return 0.0, 0.0
    parts = text.split(",")
    if len(parts) != 2:
        raise ConfigError(f"--{what} {text[:40]!r}: expected SPEED,DIR_DEG, e.g. 0.1,90")
    speed_range = _CURRENT_MPS if what == "current" else _WIND_MPS
    where = f"--{what} {text[:40]!r} (SPEED,DIR_DEG)"
    return speed_range.parse(parts[0], f"{where}: the speed"), _DIRECTION_DEG.parse(parts[1], f"{where}: the direction")


#: the planned time a prediction (or a simulated mission) may take: beyond it a route is a typo or a
#: hostile file, and the simulation would run for many minutes (~23 ms of CPU per simulated second: three
#: flights with the estimator's error, lotsen.stack.prediction)
MAX_PREDICTED_PLANNED_S = 3600.0


def model_in_use(params: str | None):  # type: ignore[no-untyped-def]
    """The model in use and its name: the parameter file's, else the default coefficients."""
    from lotsen.model import VesselModel, VesselParameters, load_parameter_file

    f = load_parameter_file(params) if params else None
    return VesselModel(f.parameters if f else VesselParameters()), (f.describe() if f else "default coefficients")


def predict(route, path, model, model_name: str, current: tuple[float, float], wind: tuple[float, float],
            controller: str = "mpc", waves=None, estimator: str = "noise"):  # type: ignore[no-untyped-def]
    """The mission's time and energy (lotsen.stack.prediction) in the current (m/s, to deg), wind
    (m/s, from deg) and sea (a `Waves`, None: flat water) given, the controller on the estimate's error
    (`estimator` "noise") or on the true state ("truth"); ConfigError for a path too long to predict."""
    from lotsen.control import ControlConfig
    from lotsen.planning.survey.keeping import line_spans
    from lotsen.stack.prediction import predict_mission

    planned = path.duration_s()
    if planned > MAX_PREDICTED_PLANNED_S:
        raise ConfigError(f"the planned path takes {planned:.0f} s; a prediction (a simulated mission) is at most "
                          f"{MAX_PREDICTED_PLANNED_S:.0f} s")
    a = math.radians(current[1])
    return predict_mission(path, model, current_ne_mps=(current[0] * math.cos(a), current[0] * math.sin(a)),
                           wind_mps=wind[0], wind_from_deg=wind[1], control=ControlConfig(controller=controller),
                           survey_lines=line_spans(route, path), model_name=model_name, waves=waves,
                           estimator=estimator)


def describe_prediction(p) -> str:  # type: ignore[no-untyped-def]
    """One line for the console: what the prediction says and what it was made with."""
    c = math.hypot(*p.current_ne_mps)
    lines = (f", {100 * p.share_on_lines:.0f} % on lines" if p.time_on_lines_s > 0 else "")
    spread = (f" ({p.energy_range_J[0] / 3600:.1f}-{p.energy_range_J[1] / 3600:.1f} over {p.draws} flights on the "
              f"estimate's error)" if p.draws > 1 else "")
    return (f"predicted: {p.duration_s:.0f} s ({p.duration_s / 60:.1f} min{lines}), {p.energy_J / 3600:.1f} Wh{spread} "
            f"at the motors (mean {p.mean_power_W:.0f} W); {p.controller} on the {p.model}, current {c:.2f} m/s, "
            f"wind {p.wind_mps:g} m/s" + (f", waves Hs {p.waves.hs_m * 100:.0f} cm" if p.waves is not None else "")
            + ("" if p.reached_end else "; the model did NOT reach the end"))
