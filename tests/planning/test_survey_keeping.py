"""Line keeping of a survey (lotsen.planning.survey.keeping): each line's span on the planned path,
and per line the cross-track RMS and max on it, the distance after the turn until within 5 cm and
the time on it, measured on synthetic tracks whose answers are known. Pure, well under a second."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lotsen.planning import plan_route
from lotsen.planning.io import route_from_dict
from lotsen.planning.survey.keeping import line_keeping, line_spans, track_on_path

AREA = [[-15, -15], [30, -15], [30, 25], [-15, 25]]


@pytest.fixture(scope="module")
def survey():
    route = route_from_dict({"harbour": {"north": -5.0, "east": -5.0, "heading_deg": 0.0}, "area": AREA,
                             "survey": {"polygon": [[0, 0], [12, 0], [12, 8], [0, 8]], "spacing_m": 2.0,
                                        "speed_mps": 0.8, "turnaround_m": 1.5}})
    return route, plan_route(route)


def test_each_line_spans_its_own_length_on_the_path_after_its_lead_in(survey):
    route, path = survey
    spans = line_spans(route, path)
    assert len(spans) == len(route.survey_lines) == 4
    for span, line in zip(spans, route.survey_lines):
        assert span.length_m == pytest.approx(line.length_m, abs=0.02)
        assert span.start_s_m - span.turn_end_s_m == pytest.approx(1.5, abs=0.02)   # the turnaround
        # the path at the span's ends is the line's ends
        for s, (n, e) in ((span.start_s_m, line.start), (span.end_s_m, line.end)):
            p = path.sample(s)
            assert math.hypot(float(p.north_m) - n, float(p.east_m) - e) < 0.02
    assert all(a.end_s_m < b.turn_end_s_m for a, b in zip(spans, spans[1:]))


def offset_track(path, offset_of_s, ds_m=0.02, speed_mps=0.8):
    """A track along `path` at `speed_mps`, displaced to starboard by offset_of_s(s)."""
    s = np.arange(0.0, path.length_m, ds_m)
    p = path.sample(s)
    h = np.asarray(p.heading_rad)
    d = offset_of_s(s)
    return s / speed_mps, np.asarray(p.north_m) - d * np.sin(h), np.asarray(p.east_m) + d * np.cos(h)


def test_an_offset_that_decays_after_the_turn_is_measured_per_line(survey):
    route, path = survey
    spans = line_spans(route, path)
    second = spans[1]

    def offset(s):
        # 3 cm everywhere; 20 cm at the end of the turn before line 2, decaying linearly to 3 cm 0.6 m later
        d = np.full_like(s, 0.03)
        ramp = (s >= second.turn_end_s_m) & (s < second.turn_end_s_m + 0.6)
        d[ramp] = 0.20 - (0.17 / 0.6) * (s[ramp] - second.turn_end_s_m)
        return d

    t, n, e = offset_track(path, offset)
    s, cte = track_on_path(path, n, e)
    assert np.max(np.abs(np.abs(cte) - offset(s))) < 2e-3
    keeping = line_keeping(spans, t, s, cte, mission_time_s=float(t[-1]))
    first, line2 = keeping.lines[0], keeping.lines[1]
    assert first.cross_track_rms_m == pytest.approx(0.03, abs=1e-3)
    assert first.settle_distance_m == 0.0
    # within 5 cm where 0.20 - 0.17 x / 0.6 = 0.05: x = 0.529 m after the turn
    assert line2.settle_distance_m == pytest.approx(0.15 / 0.17 * 0.6, abs=0.03)
    assert line2.cross_track_max_m == pytest.approx(0.03, abs=1e-3)     # the decay ends before the line starts
    assert keeping.lines[1].time_on_line_s == pytest.approx(route.survey_lines[1].length_m / 0.8, abs=0.05)
    on_lines = sum(ln.length_m for ln in route.survey_lines) / 0.8
    assert keeping.share_on_lines == pytest.approx(on_lines / t[-1], abs=2e-3)
    summary = keeping.summary()
    assert summary["settle_distance_max_m"] == pytest.approx(line2.settle_distance_m, abs=1e-3)
    assert len(summary["per_line"]) == 4


def test_a_line_never_reached_within_the_tolerance_has_no_settle_distance(survey):
    route, path = survey
    spans = line_spans(route, path)
    t, n, e = offset_track(path, lambda s: np.where(s > spans[2].turn_end_s_m, 0.08, 0.0))
    s, cte = track_on_path(path, n, e)
    keeping = line_keeping(spans, t, s, cte, mission_time_s=float(t[-1]))
    assert math.isnan(keeping.lines[2].settle_distance_m)
    assert keeping.lines[2].cross_track_max_m == pytest.approx(0.08, abs=1e-3)
    assert keeping.summary()["settle_distance_max_m"] is None
