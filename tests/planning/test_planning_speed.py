"""Speed profile at rest nodes (issue 17): leaving the harbour the boat accelerates at the
longitudinal limit to the first node's speed instead of crawling along a linear ramp."""

from __future__ import annotations

import math

import numpy as np

from lotsen.planning import PlannerConfig, plan_route
from lotsen.planning.io import route_from_dict
from lotsen.planning.speed import leg_speeds, speed_profile


def _travel_time(s: np.ndarray, v: np.ndarray) -> float:
    ds = np.diff(s)
    v_mid = 0.5 * (v[1:] + v[:-1])
    return float(np.sum(ds / np.maximum(v_mid, 1e-3)))


def test_leaving_the_harbour_accelerates_at_the_limit_then_holds_the_node_speed():
    s = np.linspace(0.0, 100.0, 10001)
    v = speed_profile(s, np.zeros_like(s), np.array([0.0, 100.0]), np.array([0.0, 0.5]),
                      a_lat_max_mps2=0.3, a_long_max_mps2=0.2, speed_max_mps=1.5)
    assert v[0] == 0.0
    ramp_end_m = 0.5**2 / (2 * 0.2)                         # 0.625 m
    assert np.allclose(v[s <= ramp_end_m], np.sqrt(2 * 0.2 * s[s <= ramp_end_m]), atol=1e-9)
    assert np.allclose(v[s > ramp_end_m + 0.02], 0.5)
    assert np.abs(np.diff(v**2) / (2 * np.diff(s))).max() <= 0.2 + 1e-9
    # 100 m at 0.5 m/s plus the 2.5 s ramp (half of it lost): ~201 s, not the 660 s of the linear ramp
    assert 200.0 < _travel_time(s, v) < 202.0


def test_a_stop_node_brakes_and_accelerates_at_the_limit():
    s = np.linspace(0.0, 40.0, 4001)
    v = speed_profile(s, np.zeros_like(s), np.array([0.0, 20.0, 40.0]), np.array([0.6, 0.0, 0.4]),
                      1.0, 0.2, 1.5)
    i_stop = int(np.argmin(np.abs(s - 20.0)))
    assert v[i_stop] == 0.0
    assert math.isclose(v[int(np.argmin(np.abs(s - 10.0)))], 0.6)   # full speed up to the braking
    assert math.isclose(v[int(np.argmin(np.abs(s - 30.0)))], 0.4)
    assert np.abs(np.diff(v**2) / (2 * np.diff(s))).max() <= 0.2 + 1e-9


def test_between_moving_nodes_it_is_still_seed_eq_42():
    start, end = leg_speeds(np.array([0.0, 0.5, 0.7, 0.0]))
    assert start.tolist() == [0.5, 0.5, 0.7] and end.tolist() == [0.5, 0.7, 0.7]
    s = np.linspace(0.0, 20.0, 2001)
    v = speed_profile(s, np.zeros_like(s), np.array([0.0, 20.0]), np.array([0.5, 0.7]), 1.0, 10.0, 2.0)
    assert np.allclose(v, 0.5 + 0.2 * s / 20.0)


def test_planned_route_leaves_the_harbour_at_the_node_speed():
    route = route_from_dict({"harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
                             "nodes": [{"north": 100.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5}],
                             "area": [[-10.0, -10.0], [110.0, -10.0], [110.0, 10.0], [-10.0, 10.0]]})
    path = plan_route(route, PlannerConfig())
    assert path.speed_mps[0] == 0.0
    assert np.all(path.speed_mps[(path.s_m > 1.0) & (path.s_m < path.s_m[-1] - 1.0)] > 0.49)
    assert _travel_time(path.s_m, path.speed_mps) < 205.0


def test_the_path_comes_to_rest_at_the_last_node_unless_told_otherwise():
    route = route_from_dict({"harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
                             "nodes": [{"north": 30.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5}],
                             "area": [[-10.0, -10.0], [40.0, -10.0], [40.0, 10.0], [-10.0, 10.0]]})
    a = 0.2
    path = plan_route(route, PlannerConfig(a_long_max_mps2=a))
    to_go = path.s_m[-1] - path.s_m
    assert path.speed_mps[-1] == 0.0
    # braking within the longitudinal limit: v <= sqrt(2 a s_to_go), and at cruise speed until then
    assert np.all(path.speed_mps <= np.sqrt(2.0 * a * to_go) + 1e-9)
    assert np.all(path.speed_mps[(to_go > 0.7) & (path.s_m > 1.0)] > 0.49)
    keep = plan_route(route, PlannerConfig(a_long_max_mps2=a, stop_at_end=False))
    assert abs(keep.speed_mps[-1] - 0.5) < 1e-6
