"""The page's Predict (issue 48 item 3) in what the running estimator knows: the current of the latest
estimate and the sea of fusion/sea_state, as the web process holds them, not the config's."""

from __future__ import annotations

import math
from types import SimpleNamespace

from lotsen.messages import SeaState, Topic, VesselState
from lotsen.model import VesselModel
from lotsen.planning import PlannerConfig
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.config import stack_config
from lotsen.stack.page_prediction import EstimatedConditions, PagePredictor, estimated_conditions
from lotsen.stack.web import add_prediction

ROUTE = {"harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
         "nodes": [{"north": 12.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5},
                   {"north": 20.0, "east": 8.0, "heading_deg": 90.0, "speed_mps": 0.5}]}
NAN = math.nan


def sea(valid=True, hs=0.06, tp=1.0, frm=45.0) -> SeaState:
    return SeaState(stamp_s=10.0, valid=valid, hs_m=hs, tp_s=tp, tp_encounter_s=tp, from_deg=frm, heave_std_m=0.01,
                    roll_std_deg=1.0, pitch_std_deg=1.0)


def test_the_conditions_are_the_estimates_current_and_the_measured_sea_unknown_values_count_as_none():
    assert estimated_conditions((0.02, 0.1), sea()) == EstimatedConditions((0.02, 0.1), (0.06, 1.0, 45.0))
    assert estimated_conditions((0.02, 0.1), sea(frm=-30.0)).sea == (0.06, 1.0, 330.0)
    assert estimated_conditions((NAN, 0.1), None) == EstimatedConditions((0.0, 0.0), None)
    for flat in (sea(valid=False), sea(hs=0.0, tp=NAN), sea(frm=NAN), sea(tp=NAN)):  # no valid sea, flat, no direction
        assert estimated_conditions(None, flat).sea is None and estimated_conditions(None, flat).waves is None
    w = EstimatedConditions((0.0, 0.1), (0.06, 1.0, 45.0)).waves
    assert (w.hs_m, w.tp_s, w.from_deg) == (0.06, 1.0, 45.0)


def test_the_stack_gives_predict_what_the_page_holds_of_the_estimator_now():
    hub = SimpleNamespace(handler=SimpleNamespace(), state=SimpleNamespace(latest={}))
    add_prediction(hub, stack_config(LaunchConfig()))
    assert hub.handler.estimated_current() == EstimatedConditions((0.0, 0.0), None)  # nothing heard yet
    hub.state.latest[Topic.STATE] = VesselState(stamp_s=10.0, north_m=0.0, east_m=0.0, heading_rad=0.0, u_mps=0.0,
                                                v_mps=0.0, r_radps=0.0, current_ne_mps=(0.03, 0.12))
    hub.state.latest[Topic.SEA_STATE] = sea()
    assert hub.handler.estimated_current() == EstimatedConditions((0.03, 0.12), (0.06, 1.0, 45.0))


def test_predict_flies_in_the_estimated_sea_and_reports_it():
    """A wind sea costs energy: the same route in the estimated Hs 6 cm sea is predicted to draw more than
    in flat water, and the answer says what sea it was flown in; an older caller's bare current still works."""
    model = VesselModel()
    predict = PagePredictor(model.params, model.geometry, "default coefficients", "mpc", PlannerConfig())
    flat = predict(ROUTE, EstimatedConditions((0.0, 0.1)))
    rough = predict(ROUTE, EstimatedConditions((0.0, 0.1), (0.06, 1.0, 45.0)))
    assert flat["ok"] and rough["ok"] and rough["reached_end"], rough
    assert flat["waves"] is None and rough["waves"] == {"hs_m": 0.06, "tp_s": 1.0, "from_deg": 45.0}
    assert rough["current_ne_mps"] == flat["current_ne_mps"] == [0.0, 0.1]
    assert rough["energy_J"] > 1.1 * flat["energy_J"], (rough["energy_J"], flat["energy_J"])
