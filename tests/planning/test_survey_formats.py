"""QGroundControl's Survey complex item (.plan): read into a survey route, planned, written back and
read again equal; the spacing from a camera's footprint; what lotsen cannot fly is refused naming
the key. The sample is built as QGroundControl's "Plan File Format" documents the item (version 4,
TransectStyleComplexItem version 1 with CameraCalc, Items and VisualTransectPoints), at a boat's
scale (tests/planning/data/qgc_survey.plan)."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.planning import plan_route
from lotsen.planning.formats import read_route_text, write_route_text
from lotsen.planning.io import load_route, route_from_dict, route_to_dict

SAMPLE = Path(__file__).parent / "data" / "qgc_survey.plan"


def sample() -> dict:
    return json.loads(SAMPLE.read_text())


def survey_of(plan: dict) -> dict:
    return next(it for it in plan["mission"]["items"] if it["type"] == "ComplexItem")


def test_the_documented_survey_item_plans_as_lotsen_lines():
    route = load_route(SAMPLE)
    p = route.survey
    assert (p.spacing_m, p.angle_deg, p.turnaround_m, p.speed_mps, p.entry, p.crosshatch) == (2.5, 0.0, 3.0, 0.8, 0, False)
    lines = route.survey_lines
    assert len(lines) == 12                                   # 30 m of east at 2.5 m
    assert all(abs(ln.length_m - 20.0) < 1e-3 for ln in lines)
    assert lines[0].start == pytest.approx((-5.0, 1.25 + 5.0), abs=1e-2)  # top left (north-west); origin: home, 5 m NW
    path = plan_route(route)
    assert path.length_m > 12 * 20


def test_a_survey_plan_round_trips_through_lotsen():
    route = load_route(SAMPLE)
    text, notes = write_route_text(route, "plan")
    assert not notes
    written = json.loads(text)
    item = survey_of(written)
    assert item["complexItemType"] == "survey" and item["TransectStyleComplexItem"]["TurnAroundDistance"] == 3.0
    assert item["TransectStyleComplexItem"]["CameraCalc"]["AdjustedFootprintSide"] == 2.5
    waypoints = [it for it in item["TransectStyleComplexItem"]["Items"] if it["command"] == 16]
    assert len(waypoints) == len(route.nodes)                 # ground stations that fly items fly lotsen's nodes
    back = route_from_dict(read_route_text(text, "plan", route.origin))
    a, b = route_to_dict(route), route_to_dict(back)
    assert [c for p in b["survey"]["polygon"] for c in p] == pytest.approx(
        [c for p in a["survey"]["polygon"] for c in p], abs=2e-3)
    assert {k: v for k, v in b["survey"].items() if k != "polygon"} == {k: v for k, v in a["survey"].items()
                                                                       if k != "polygon"}
    assert len(back.nodes) == len(route.nodes)
    assert max(math.hypot(x.north_m - y.north_m, x.east_m - y.east_m) for x, y in zip(back.nodes, route.nodes)) < 5e-3


def test_the_spacing_of_a_camera_survey_is_its_side_footprint():
    plan = sample()
    item = survey_of(plan)
    item["TransectStyleComplexItem"]["CameraCalc"] = {
        "AdjustedFootprintFrontal": 2.2, "AdjustedFootprintSide": 3.1, "CameraName": "Sony ILCE-QX1",
        "DistanceToSurface": 4.0, "DistanceToSurfaceRelative": True, "FixedOrientation": False, "FocalLength": 16,
        "FrontalOverlap": 70, "ImageDensity": 0.1, "ImageHeight": 3632, "ImageWidth": 5456, "Landscape": True,
        "MinTriggerInterval": 0, "SensorHeight": 15.4, "SensorWidth": 23.2, "SideOverlap": 70,
        "ValueSetIsDistance": False, "version": 1}
    item["TransectStyleComplexItem"]["Refly90Degrees"] = True
    item["entryLocation"] = 3
    d = read_route_text(json.dumps(plan), "plan")
    assert (d["survey"]["spacing_m"], d["survey"]["crosshatch"], d["survey"]["entry"]) == (3.1, True, 3)
    route = route_from_dict(d)
    assert {ln.pass_index for ln in route.survey_lines} == {0, 1}


def _edit(fn):
    plan = sample()
    fn(plan, survey_of(plan))
    return json.dumps(plan)


@pytest.mark.parametrize("edit,words", [
    (lambda p, s: s["TransectStyleComplexItem"]["CameraCalc"].update(AdjustedFootprintSide=0),
     ["AdjustedFootprintSide (line spacing)", "0"]),
    (lambda p, s: s.update(polygon=s["polygon"][:2]), ["polygon", "do not close a polygon"]),
    (lambda p, s: s.update(polygon=[s["polygon"][0], s["polygon"][2], s["polygon"][1], s["polygon"][3]]),
     ["survey.polygon", "edges cross"]),
    (lambda p, s: s.update(version=3), ["version 3", "versions 4 and 5"]),
    (lambda p, s: s.update(flyAlternateTransects=True), ["flyAlternateTransects"]),
    (lambda p, s: p["mission"]["items"].append(copy.deepcopy(s)), ["a second survey"]),
    (lambda p, s: p["mission"]["items"].insert(0, {"autoContinue": True, "command": 16, "doJumpId": 9, "frame": 3,
                                                    "params": [0, 0, 0, None, *s["polygon"][0], 0],
                                                    "type": "SimpleItem"}), ["WAYPOINT beside a survey"]),
    (lambda p, s: p["mission"]["items"].append({"autoContinue": True, "command": 20, "doJumpId": 40, "frame": 2,
                                                 "params": [0] * 7, "type": "SimpleItem"}), ["after the survey"]),
    (lambda p, s: s["TransectStyleComplexItem"].update(TurnAroundDistance=60), ["line 1", "shorter turnaround"]),
])
def test_survey_items_lotsen_cannot_fly_are_refused_naming_the_key(edit, words):
    with pytest.raises(ConfigError) as exc:
        route_from_dict(read_route_text(_edit(edit), "plan"))
    for w in words:
        assert w in str(exc.value), str(exc.value)


def test_lotsen_plan_reads_a_survey_plan_and_exports_it(tmp_path):
    out = tmp_path / "again.plan"
    res = subprocess.run([sys.executable, "-m", "lotsen", "plan", str(SAMPLE), "--export", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "survey: 12 lines" in res.stdout
    assert survey_of(json.loads(out.read_text()))["complexItemType"] == "survey"


def test_the_documented_survey_plan_flies_on_the_simulated_stack():
    """The .plan's survey uploaded to the simulated stack as the page uploads it, armed and in AUTO
    (truth as the estimate, the LOS follower: the plan is under test here, the controllers in
    bench survey): the boat sounds along the first line, on it (the whole survey: tests/bathymetry)."""
    from lotsen.harness.survey import SurveyRunConfig, run_survey
    from lotsen.runtime.config import LakeBedSection

    route = load_route(SAMPLE)
    bed = LakeBedSection(depths_m=((3.0, 3.0), (3.0, 3.0)), origin_m=(-50.0, -50.0), cell_m=100.0, sounder_dropout=0.0)
    run = run_survey(route, SurveyRunConfig(lakebed=bed, fusion="truth", controller="los", cell_m=2.5,
                                            max_duration_s=60.0))
    assert [m for _, m, _ in run.modes][:2] == ["MANUAL", "AUTO"] and run.modes[-1][1] == "AUTO", run.modes
    first = route.survey_lines[0]
    (n0, e0), (n1, e1) = first.start, first.end
    lo, hi = min(n0, n1) + 4.0, max(n0, n1) - 4.0                      # the line's middle, past the turn-in
    on_line = [s for s in run.soundings if lo <= s.north_m <= hi and abs(s.east_m - e0) < 2.0]
    assert len(on_line) >= 60                                        # 5 Hz along its middle 12 m
    assert max(abs(s.east_m - e0) for s in on_line) < 0.3
    assert abs(float(np.mean([s.depth_m for s in on_line])) - 3.0) < 0.01
