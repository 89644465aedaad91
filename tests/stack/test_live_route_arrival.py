"""A survey's route arriving at the core of `lotsen run` at wall-clock pace (issue 48 item 5): the 40 x 30 m
survey (78 000 path points) uploaded through the WebSocket as the page does, once before arming and once
again 10 s into AUTO. The control loop keeps its period both times: the largest gap between ship_commands
within 10 s of each upload is within the live-stack bar of 150 ms (it was 0.15-0.2 s when the route was
6.5 MB of number lists decoded on the core's Zenoh thread and checked on the loop). In AUTO the boat flies
the route it holds while the new one is checked, then holds (a new route while moving)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from lotsen.stack.soak import LivePlan, run_live

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"   # the boat at north 4, east 20, heading north
#: bench survey's table 2 survey: 15 lines of 30 m at 2 m spacing, the boat's harbour at (4, 20)
SURVEY = {"origin": {"lat_deg": 57.6905, "lon_deg": 11.976},
          "harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0},
          "area": [[-4, -4], [60, -4], [60, 50], [-4, 50]],
          "survey": {"polygon": [[8, 8], [48, 8], [48, 38], [8, 38]], "spacing_m": 2.0, "speed_mps": 0.8,
                     "turnaround_m": 1.0, "turn_radius_m": 2.0}}

pytestmark = pytest.mark.live


def survey_config(work: Path) -> Path:
    """config/sim.yaml with the survey as its route: the boat's own area is the survey's (the figure eight's
    40 x 40 m holds no 40 x 30 m survey with its turns)."""
    (work / "survey.yaml").write_text(yaml.safe_dump(SURVEY))
    text = CONFIG.read_text().replace("route: ../examples/routes/figure_eight.yaml", f"route: {work / 'survey.yaml'}")
    config = work / "config" / "sim.yaml"
    config.parent.mkdir(parents=True, exist_ok=True)
    config.write_text(text)
    return config


# the loop's timing under the load the route makes is the point: not beside another run; and not in `make
# test`: on fresh clones its gaps were 200 and 300 ms (2 of 2, 2026-11-28 18:13), in main 100-159 ms (bench
# survey table 2d measures the same); run it with `pytest -m timing_bar`. The 200-300 ms were the log's, not
# the loop's: the core sent every ship_command 100 ms apart, and Zenoh dropped one behind the 5-MB route on
# the router's link to the recorder (1 of 3 runs on main on 2026-11-29, 5 of 5 once the core sent its batches with
# the estimate); with the route at low priority (the web bridge's `bulk`) 100-108 ms in 3 of 3
@pytest.mark.alone
@pytest.mark.timing_bar
def test_a_survey_route_arriving_before_and_in_auto_leaves_no_gap_in_the_control_loop(tmp_path):
    report = run_live(LivePlan(config=survey_config(tmp_path), idle_s=5.0, route=SURVEY, return_home=False,
                               arm_after_route_s=2.0, reupload_after_auto_s=10.0,
                               extra_config={"planning": {"time_s": 60.0}}), tmp_path)
    print(report.summary())
    for t, what in report.timeline:
        print(f"  {t:8.2f}  {what}")
    f = report.figures
    assert f["route_arrival_1_max_gap_ms"] <= 150 and f["route_arrival_2_max_gap_ms"] <= 150, f
    assert report.ok, report.summary() + "\n" + "\n".join(report.output[-20:])
