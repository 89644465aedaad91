"""Survey patterns (lotsen.planning.survey): lines that cover the polygon at the spacing and angle
asked, entry corner, crosshatch, one-sided racetracks, obstacles, turnaround; the planned path
flies each line straight, at the line speed and on its heading; bad parameters are named."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, Polygon

from lotsen.errors import ConfigError
from lotsen.planning import plan_route
from lotsen.planning.exchange import route_id
from lotsen.planning.io import route_from_dict, route_to_dict
from lotsen.planning.survey import coverage_polygon, strip_of

AREA = [[-15, -15], [55, -15], [55, 45], [-15, 45]]
BOX = [[0, 0], [40, 0], [40, 30], [0, 30]]


def survey_route(harbour=(-5.0, -5.0, 0.0), area=AREA, obstacles=None, **survey):
    d = {"harbour": {"north": harbour[0], "east": harbour[1], "heading_deg": harbour[2]},
         "survey": {"polygon": BOX, "spacing_m": 2.0, "speed_mps": 0.8, **survey}}
    if area is not None:
        d["area"] = area
    if obstacles:
        d["obstacles"] = obstacles
    return route_from_dict(d)


def offsets(route, axis):
    """Each line's cross position: its mean coordinate on `axis` (0 north, 1 east)."""
    return [np.mean([p[axis] for piece in ln.pieces for p in piece]) for ln in route.survey_lines]


def test_lines_run_at_the_angle_and_spacing_and_cover_the_polygon():
    r = survey_route(angle_deg=0.0)          # north-south lines over 30 m of east: 15 lines
    lines = r.survey_lines
    assert len(lines) == 15
    east = offsets(r, 1)
    assert sorted(east) == pytest.approx([1.0 + 2.0 * k for k in range(15)], abs=1e-6)
    for ln in lines:
        assert abs(math.sin(ln.heading_rad)) < 1e-9                      # north or south
        assert ln.length_m == pytest.approx(40.0, abs=1e-3)              # edge to edge
    headings = [math.cos(ln.heading_rad) for ln in lines]
    assert all(a * b < 0 for a, b in zip(headings, headings[1:]))        # back and forth
    poly = Polygon(BOX)
    assert poly.difference(coverage_polygon(list(lines))).area < 1e-6 * poly.area


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(angle=st.integers(-1800, 1800).map(lambda a: a / 10), spacing=st.integers(15, 80).map(lambda s: s / 10),
       corners=st.lists(st.tuples(st.integers(0, 300), st.integers(0, 300)), min_size=3, max_size=7))
def test_any_convex_polygon_is_covered_by_its_strips_at_any_angle(angle, spacing, corners):
    hull = Polygon([(n / 10, e / 10) for n, e in corners]).convex_hull
    if not isinstance(hull, Polygon) or hull.area < 20 or min(*np.ptp(np.asarray(hull.exterior.coords), axis=0)) < 3:
        return
    ring = [list(c) for c in hull.exterior.coords[:-1]]
    r = route_from_dict({"harbour": {"north": -10, "east": -10}, "area": [[-20, -20], [50, -20], [50, 50], [-20, 50]],
                         "survey": {"polygon": ring, "spacing_m": spacing, "angle_deg": angle, "turnaround_m": 1.0}})
    lines = list(r.survey_lines)
    u = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle))])
    for ln in lines:   # every line along the angle, either way
        assert abs(abs(np.dot(u, [math.cos(ln.heading_rad), math.sin(ln.heading_rad)])) - 1) < 1e-9
    gaps = np.diff(sorted(np.dot([-u[1], u[0]], ln.start) for ln in lines))
    assert gaps == pytest.approx(np.full(len(gaps), spacing), abs=1e-3)
    assert hull.difference(coverage_polygon(lines).buffer(1e-3)).area < 1e-9   # no gap wider than 1 mm


def test_the_planned_path_flies_each_line_straight_at_its_speed_and_heading():
    r = survey_route(angle_deg=30.0, turnaround_m=3.0, polygon=[[0, 0], [30, 0], [30, 20], [0, 20]])
    path = plan_route(r)
    for ln in r.survey_lines:
        h = ln.heading_rad
        u = np.array([math.cos(h), math.sin(h)])
        a, b = np.asarray(ln.start), np.asarray(ln.end)
        lead_in = a - 3.0 * u
        i = int(np.argmin(np.hypot(path.north_m - lead_in[0], path.east_m - lead_in[1])))
        j = int(np.argmin(np.hypot(path.north_m - b[0], path.east_m - b[1])))
        assert i < j
        pts = np.column_stack([path.north_m[i:j + 1], path.east_m[i:j + 1]]) - a
        cross = pts @ np.array([-u[1], u[0]])
        assert np.abs(cross).max() < 1e-3                                  # on the line from its lead-in
        assert np.abs(np.angle(np.exp(1j * (path.heading_rad[i:j + 1] - h)))).max() < 1e-3
        k = int(np.argmin(np.hypot(path.north_m - a[0], path.east_m - a[1])))
        assert path.speed_mps[k:j + 1] == pytest.approx(0.8, abs=1e-6)    # at speed where the line starts
        assert path.speed_mps[i:k].min() > 0.9 * 0.8                     # and nearly so at its lead-in


@pytest.mark.parametrize("entry,corner", [("top_left", (30, 0)), ("top_right", (30, 20)),
                                          ("bottom_left", (0, 0)), ("bottom_right", (0, 20))])
def test_the_entry_corner_is_where_the_first_line_starts(entry, corner):
    r = survey_route(entry=entry, polygon=[[0, 0], [30, 0], [30, 20], [0, 20]], harbour=(-8, -8, 0))
    first = r.survey_lines[0]
    assert math.hypot(first.start[0] - corner[0], first.start[1] - corner[1]) < 1.5


def test_without_an_entry_corner_the_survey_starts_at_the_corner_nearest_the_harbour():
    for harbour, corner in (((-8, -8, 0), (0, 0)), ((38, 28, 0), (30, 20)), ((38, -8, 0), (30, 0))):
        r = survey_route(polygon=[[0, 0], [30, 0], [30, 20], [0, 20]], harbour=harbour)
        s = r.survey_lines[0].start
        assert math.hypot(s[0] - corner[0], s[1] - corner[1]) < 1.5, (harbour, s)


def test_crosshatch_flies_the_area_again_at_ninety_degrees():
    r = survey_route(crosshatch=True, spacing_m=4.0)
    main = [ln for ln in r.survey_lines if ln.pass_index == 0]
    cross = [ln for ln in r.survey_lines if ln.pass_index == 1]
    assert len(main) == 8 and len(cross) == 10                     # 30 m / 4 -> 8, 40 m / 4 -> 10
    assert all(abs(math.cos(ln.heading_rad)) < 1e-9 for ln in cross)
    assert Polygon(BOX).difference(coverage_polygon(cross)).area < 1e-6 * 1200
    plan_route(r)


@pytest.mark.parametrize("side", ["port", "starboard"])
def test_a_one_sided_sensor_covers_each_strip_once_on_its_side(side):
    r = survey_route(side=side, spacing_m=3.0, turnaround_m=1.0)
    lines = list(r.survey_lines)
    assert len(lines) == 10
    strips = [strip_of(ln, p) for ln in lines for p in ln.pieces]
    union = coverage_polygon(lines)
    assert Polygon(BOX).difference(union).area < 1e-6 * 1200
    assert sum(s.area for s in strips) == pytest.approx(union.area, rel=1e-6)   # no strip twice
    for ln in lines:
        assert ln.swath_m == ((3.0, 0.0) if side == "port" else (0.0, 3.0))
    plan_route(r)


def test_obstacles_split_lines_and_the_path_goes_round_them():
    obstacle = [[18, 12], [22, 12], [22, 16], [18, 16]]
    r = survey_route(obstacles=[obstacle], spacing_m=3.0)
    blocked = Polygon(obstacle).buffer(0.5)
    split = [ln for ln in r.survey_lines if len(ln.pieces) > 1]
    assert split, "lines across the obstacle are cut in two"
    for ln in r.survey_lines:
        for a, b in ln.pieces:
            assert not blocked.buffer(-1e-3).intersects(Polygon([a, b, b]).buffer(1e-6))
    path = plan_route(r)
    assert not Polygon(obstacle).buffer(0.49).contains(Point(0, 0))
    d = [Polygon(obstacle).distance(Point(n, e)) for n, e in zip(path.north_m[::50], path.east_m[::50])]
    assert min(d) >= 0.49


def test_explicit_lines_are_flown_in_order():
    r = route_from_dict({"harbour": {"north": 0, "east": 0}, "area": AREA,
                         "survey": {"lines": [[[5, 5], [5, 25]], [[20, 20], [30, 20]]], "speed_mps": 0.6}})
    assert [ln.start for ln in r.survey_lines] == [(5, 5), (20, 20)]
    path = plan_route(r)
    assert path.length_m > 30


def test_a_survey_route_round_trips_as_its_pattern():
    r = survey_route(angle_deg=15.0, crosshatch=True, spacing_m=5.0, entry="bottom_right", turnaround_m=2.5)
    d = route_to_dict(r)
    assert "nodes" not in d and d["survey"]["entry"] == "bottom_right" and d["survey"]["crosshatch"] is True
    back = route_from_dict(d)
    assert back.nodes == r.nodes and back.survey_lines == r.survey_lines
    assert route_id(back) == route_id(r)


def test_without_a_polygon_the_lines_keep_room_to_turn_inside_the_area():
    r = route_from_dict({"harbour": {"north": 0, "east": 0}, "area": [[-5, -5], [45, -5], [45, 35], [-5, 35]],
                         "survey": {"spacing_m": 3.0, "speed_mps": 0.5, "turnaround_m": 1.0}})
    path = plan_route(r)
    area = Polygon([[-5, -5], [45, -5], [45, 35], [-5, 35]])
    assert all(area.buffer(-0.5).covers(Point(n, e)) for n, e in zip(path.north_m[::100], path.east_m[::100]))


@pytest.mark.parametrize("survey,words", [
    ({"spacing_m": 0}, ["survey.spacing_m", "0", "0.1 to 100 m"]),
    ({"polygon": [[0, 0], [10, 0]]}, ["survey.polygon", "do not close a polygon"]),
    ({"polygon": [[0, 0], [10, 10], [10, 0], [0, 10]]}, ["survey.polygon", "edges cross"]),
    ({"polygon": [[0, 0], [80, 0], [80, 30], [0, 30]]}, ["survey.polygon", "outside the navigable water"]),
    ({"turnaround_m": 40}, ["line 1", "lead-in", "shorter turnaround"]),
    ({"speed_mps": 9}, ["survey.speed_mps", "9"]),
    ({"side": "left"}, ["survey.side", "port, starboard"]),
    ({"spacing_m": 0.1, "polygon": [[-10, -10], [50, -10], [50, 40], [-10, 40]]}, ["more than a survey may have"]),
    ({"lines": [[[0, 0], [0, 0]]], "polygon": None}, ["survey.lines[0]", "apart"]),
    ({"bogus": 1}, ["unknown key", "bogus"]),
])
def test_bad_survey_parameters_are_named(survey, words):
    with pytest.raises(ConfigError) as exc:
        survey_route(**survey)
    for w in words:
        assert w in str(exc.value), str(exc.value)


def test_a_turn_that_does_not_fit_the_area_is_named():
    tight = [[-3, -3], [43, -3], [43, 33], [-3, 33]]   # 3 m around the polygon: no room for a 2.35 m turn
    with pytest.raises(ConfigError, match=r"turn from line \d+ to line \d+ leaves the navigable water"):
        survey_route(area=tight, turnaround_m=0.5, harbour=(-0.5, 1.0, 0))   # at line 1's lead-in


def test_nodes_and_a_survey_together_are_refused():
    with pytest.raises(ConfigError, match="nodes or a survey, not both"):
        route_from_dict({"harbour": {"north": 0, "east": 0}, "area": AREA,
                         "nodes": [{"north": 5, "east": 5, "heading_deg": 0, "speed_mps": 0.5}],
                         "survey": {"polygon": BOX}})


def test_lines_closer_than_a_turn_are_flown_in_blocks_of_plain_u_turns():
    r = survey_route(spacing_m=2.0, speed_mps=0.8)                  # turn radius 2.35 m: a bulb turn between neighbours
    diameter = 2 * r.survey.turn_radius()
    east = [np.mean([p[1] for piece in ln.pieces for p in piece]) for ln in r.survey_lines]
    assert sorted(east) == pytest.approx([1.0 + 2.0 * k for k in range(15)])   # every line once
    steps = np.abs(np.diff(east))
    short = int(np.sum(steps < diameter))
    assert short <= 1 and np.all(steps <= 4 * 2.0 + 1e-9)             # one short hop between the two blocks
    from lotsen.planning.survey.lines import interleaved_order
    assert interleaved_order(15, 5.0, 2.35) == list(range(15))         # wide spacing: in order
    seq = plan_route(r)
    flat = survey_route(spacing_m=5.0, speed_mps=0.8)                   # a plain back and forth for scale
    assert seq.length_m < 600 + 15 * 4 * 2.0 + 140                      # turns of a few metres, not bulbs
    assert plan_route(flat).length_m < seq.length_m
