"""Path queries the controller relies on: sample, project (cross-track sign), JSON; speed profile."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lotsen.errors import ConfigError
from lotsen.planning import HarbourNode, Path, Route, RouteNode, plan_route
from lotsen.planning.speed import speed_profile


def _straight_east(length=10.0, n=1001) -> Path:
    s = np.linspace(0.0, length, n)
    return Path(north_m=np.zeros(n), east_m=s, heading_rad=np.full(n, math.pi / 2),
                curvature_1pm=np.zeros(n), speed_mps=np.full(n, 0.5), s_m=s)


def test_cross_track_sign_on_an_east_going_line():
    path = _straight_east()
    north_of = path.project(1.0, 4.0)          # north of an east-going line is to port
    assert north_of.cross_track_error_m == pytest.approx(-1.0)
    assert north_of.s_m == pytest.approx(4.0)
    assert north_of.heading_rad == pytest.approx(math.pi / 2)
    south_of = path.project(-0.3, 7.25)       # south is to starboard
    assert south_of.cross_track_error_m == pytest.approx(0.3)
    assert south_of.s_m == pytest.approx(7.25)
    assert 720 <= south_of.index <= 725


@settings(max_examples=50, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(0.1, 9.9), st.floats(-3, 3))
def test_project_recovers_s_and_offset_on_any_straight_line(psi, s, offset):
    """A point offset to starboard by d from s on a line of any heading projects back to (s, d)."""
    n = 501
    ss = np.linspace(0.0, 10.0, n)
    path = Path(north_m=ss * math.cos(psi), east_m=ss * math.sin(psi), heading_rad=np.full(n, psi),
                curvature_1pm=np.zeros(n), speed_mps=np.ones(n), s_m=ss)
    starboard = (-math.sin(psi), math.cos(psi))  # heading rotated +90 deg (clockwise) in NED
    q = (s * math.cos(psi) + offset * starboard[0], s * math.sin(psi) + offset * starboard[1])
    p = path.project(*q)
    assert p.s_m == pytest.approx(s, abs=1e-9)
    assert p.cross_track_error_m == pytest.approx(offset, abs=1e-9)


def test_project_on_a_circle_and_window_keeps_the_branch():
    # clockwise circle (turning to starboard), radius 5, centre east of the start
    th = np.linspace(0.0, 2 * math.pi, 3001)
    n, e = 5 * np.sin(th), 5 - 5 * np.cos(th)
    path = Path(north_m=n, east_m=e, heading_rad=(th + np.pi) % (2 * np.pi) - np.pi,
                curvature_1pm=np.full_like(th, 0.2), speed_mps=np.ones_like(th), s_m=5 * th)
    inside = path.project(0.0, 1.0)            # towards the centre = starboard on a right turn
    assert inside.cross_track_error_m == pytest.approx(1.0, abs=1e-4)
    # start and end coincide: the hint chooses the end of the loop
    end = path.project(0.0, -0.2, s_hint_m=path.length_m - 1.0, window_m=2.0)
    assert end.s_m > path.length_m - 3.0
    assert end.cross_track_error_m == pytest.approx(-0.2, abs=1e-3)
    start = path.project(0.0, -0.2, s_hint_m=0.5, window_m=2.0)
    assert start.s_m < 1.0


def test_sample_interpolates_heading_across_the_wrap():
    # heading goes from +179 deg to -179 deg (southwards): the mid sample is 180, not 0
    s = np.array([0.0, 1.0])
    path = Path(north_m=np.array([0.0, -1.0]), east_m=np.zeros(2),
                heading_rad=np.radians([179.0, -179.0]), curvature_1pm=np.zeros(2),
                speed_mps=np.array([0.2, 0.4]), s_m=s)
    p = path.sample(0.5)
    assert abs(math.remainder(p.heading_rad - math.pi, 2 * math.pi)) < 1e-12
    assert p.speed_mps == pytest.approx(0.3) and p.north_m == pytest.approx(-0.5)
    arr = path.sample(np.array([-1.0, 0.25, 5.0]))       # clipped to [0, length]
    assert arr.s_m.tolist() == [0.0, 0.25, 1.0]
    assert np.all(np.abs(arr.heading_rad) > math.radians(178.9))


def test_json_round_trip_of_a_planned_path():
    route = Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(10.0, 3.0, 0.5, 0.6), RouteNode(20.0, 3.0, 0.0, 0.4)))
    path = plan_route(route)
    again = Path.from_dict(json.loads(json.dumps(path.to_dict())))
    for name in ("north_m", "east_m", "heading_rad", "curvature_1pm", "speed_mps", "s_m"):
        assert np.array_equal(getattr(path, name), getattr(again, name))
    assert again.segments == path.segments
    with pytest.raises(ConfigError):
        Path.from_dict({"format": "lotsen.path", "north_m": [0, 1]})
    with pytest.raises(ConfigError, match="strictly increasing"):
        Path.from_dict({**path.to_dict(), "s_m": [0.0] * len(path)})


def test_path_arrays_are_read_only():
    path = _straight_east()
    with pytest.raises(ValueError):
        path.north_m[0] = 1.0


def test_speed_profile_limits():
    s = np.linspace(0.0, 20.0, 2001)
    kappa = np.where((s > 9) & (s < 11), 1.0, 0.0)
    v = speed_profile(s, kappa, np.array([0.0, 20.0]), np.array([0.0, 1.0]), a_lat_max_mps2=0.3,
                      a_long_max_mps2=0.2, speed_max_mps=0.8)
    assert v[0] == 0.0
    assert v.max() <= 0.8
    assert np.all(v[(s > 9) & (s < 11)] <= math.sqrt(0.3) + 1e-12)
    assert np.abs(np.diff(v**2) / (2 * np.diff(s))).max() <= 0.2 + 1e-9
    # without limits in the way it is seed eq. (42): linear between node speeds
    v_lin = speed_profile(s, np.zeros_like(s), np.array([0.0, 20.0]), np.array([0.5, 0.7]), 1.0, 10.0, 2.0)
    assert np.allclose(v_lin, 0.5 + 0.2 * s / 20.0)
