"""A survey flown by `lotsen run` at wall-clock pace (issue 48 item 5): uploaded, armed and sent to AUTO
through the WebSocket as the page does, in 0.1 m/s current and 3 m/s wind on the lake boat, judged by its
own log (lotsen.stack.soak): flown to its end with no failsafe, and its line keeping per line from the log
(the true track against the planned route the boat held). A small survey (3 lines of 8 m, ~75 s in
AUTO); the 40 x 30 m survey on both hulls at wall-clock pace is bench survey's table 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from lotsen.stack.soak import LivePlan, run_live

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"   # the boat at north 4, east 20, heading north
WEATHER = {"current_speed_mps": 0.1, "current_to_deg": 90.0, "wind_speed_mps": 3.0, "wind_from_deg": 45.0}
SURVEY = {"harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0},
          "area": [[0, 0], [40, 0], [40, 40], [0, 40]],   # the config's route's: the boat's own fence
          "survey": {"polygon": [[10, 16], [18, 16], [18, 22], [10, 22]], "spacing_m": 2.0, "speed_mps": 0.8,
                     "turnaround_m": 1.0, "turn_radius_m": 2.0}}

pytestmark = pytest.mark.live


def test_lotsen_run_flies_a_survey_and_its_log_gives_the_line_keeping(tmp_path):
    report = run_live(LivePlan(config=CONFIG, idle_s=5.0, route=SURVEY, return_home=False, environment=WEATHER,
                               arm_after_route_s=2.0), tmp_path)
    print(report.summary())
    assert report.ok, report.summary() + "\n" + "\n".join(report.output[-20:])
    f = report.figures
    assert f["survey_lines"] == 3 and f["survey_lines_flown"] == 3, f
    assert f["survey_cross_track_rms_m"] <= 0.02 and f["survey_cross_track_max_m"] <= 0.06, f
    assert f["survey_settle_distance_max_m"] is not None and f["survey_settle_distance_max_m"] < 1.0, f
    assert 0.3 < f["survey_share_on_lines"] < 0.6, f                  # 24 m of lines in ~75 s
    assert f["energy_J"] > 0 and len(f["survey_per_line"]) == 3
