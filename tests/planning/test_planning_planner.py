"""Planner: every returned path satisfies seed eqs. (40a-h), clearance and speed limits; detours;
return-to-harbour; the seed's method for comparison."""

from __future__ import annotations

import math
from pathlib import Path as FilePath

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon

from lotsen.errors import PlanningError
from lotsen.planning import (HarbourNode, Path, PlannerConfig, Region, Route, RouteNode, plan_return_route,
                             plan_route)
from lotsen.planning.dubins import dubins_waypoints, dubins_words
from lotsen.planning.io import load_route, route_from_dict
from lotsen.planning.route import MIN_SPEED_MPS

EXAMPLES = FilePath(__file__).resolve().parents[2] / "examples" / "routes"
AREA = ((-5.0, -5.0), (45.0, -5.0), (45.0, 45.0), (-5.0, 45.0))


# --- independent checks of seed eqs. (40a-h), clearance and speed limits ---------------------
def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def assert_path_ok(path: Path, route: Route, cfg: PlannerConfig, nodes=None) -> None:
    """nodes: the planner's node list (default harbour + route nodes) that the path must visit."""
    nodes = route.all_nodes() if nodes is None else nodes
    P = np.column_stack([path.north_m, path.east_m])
    # 40a-f: the path passes through every node, in order, with the node's heading
    last = -1
    for k, n in enumerate(nodes):
        d = np.hypot(P[:, 0] - n.north_m, P[:, 1] - n.east_m)
        cand = np.flatnonzero(d < 1e-6)
        cand = cand[cand > last] if k else cand
        assert cand.size, f"node {k} not on the path (closest {d.min():.3g} m)"
        i = int(cand[0])
        assert abs(wrap(path.heading_rad[i] - n.heading_rad)) < 1e-6, f"node {k} heading"
        last = i
    assert np.allclose(P[0], [nodes[0].north_m, nodes[0].east_m], atol=1e-9)
    assert np.allclose(P[-1], [nodes[-1].north_m, nodes[-1].east_m], atol=1e-9)
    # spacing (seed: max 1 cm) and arc length consistent with the points
    step = np.hypot(*np.diff(P, axis=0).T)
    assert step.max() <= cfg.spacing_m + 1e-12
    assert np.allclose(np.diff(path.s_m), step)
    # 40g per planned segment, recomputed from the points
    for m in path.segments:
        i0 = int(np.argmin(np.abs(path.s_m - m.s_start_m)))
        i1 = int(np.argmin(np.abs(path.s_m - m.s_end_m)))
        straight = math.hypot(*(P[i1] - P[i0]))
        assert path.s_m[i1] - path.s_m[i0] <= cfg.length_ratio_max * straight + 1e-9, m.label
    # 40h: curvature bound, and the heading turns no faster than it allows between points (a cusp,
    # where the curve stops and reverses, has finite sampled curvature but a heading jump)
    assert np.abs(path.curvature_1pm).max() <= 1.0 / cfg.min_turn_radius_m + 1e-12
    dpsi = np.abs(np.diff(np.unwrap(path.heading_rad)))
    assert np.all(dpsi <= 1.5 * step / cfg.min_turn_radius_m + 1e-3), "heading jump (cusp)"
    # inside the area and clear of obstacles by the clearance
    line = LineString(P)
    if route.area is not None:
        area = Polygon(route.area)
        assert area.covers(line)
        assert area.exterior.distance(line) >= cfg.clearance_m - 1e-9
    for r in route.obstacles:
        poly = Polygon(r.polygon)
        if r.forbidden == "inside":
            assert poly.distance(line) >= cfg.clearance_m - 1e-9
        else:
            assert poly.covers(line) and poly.exterior.distance(line) >= cfg.clearance_m - 1e-9
    # speed: bounds, lateral and longitudinal acceleration
    v = path.speed_mps
    assert v.min() >= 0 and v.max() <= cfg.speed_max_mps + 1e-12
    assert np.all(v**2 * np.abs(path.curvature_1pm) <= cfg.a_lat_max_mps2 * (1 + 1e-9) + 1e-12)
    a_long = np.diff(v**2) / (2 * np.diff(path.s_m))
    assert np.abs(a_long).max() <= cfg.a_long_max_mps2 * (1 + 1e-6)
    node_speeds = [n.speed_mps for n in nodes]
    assert v.max() <= max(node_speeds) + 1e-12
    if nodes[0].speed_mps == 0:
        assert v[0] == 0.0
    assert shapely.is_valid(line)



@st.composite
def routes(draw):
    """Random routes: nodes 4-15 m apart inside the area, headings within +-40 deg of the leg."""
    n_nodes = draw(st.integers(1, 4))
    pts = [(draw(st.floats(5, 35)), draw(st.floats(5, 35)))]
    for _ in range(n_nodes):
        for _attempt in range(20):
            d = draw(st.floats(4.0, 15.0))
            bearing = draw(st.floats(-math.pi, math.pi))
            q = (pts[-1][0] + d * math.cos(bearing), pts[-1][1] + d * math.sin(bearing))
            if 1 < q[0] < 39 and 1 < q[1] < 39:
                pts.append(q)
                break
        else:
            break
    if len(pts) < 2:
        pts.append((pts[0][0] + 5.0 if pts[0][0] < 20 else pts[0][0] - 5.0, pts[0][1]))
    headings = []
    for k, p in enumerate(pts):
        q = pts[k + 1] if k + 1 < len(pts) else p
        r = pts[k - 1] if k > 0 else p
        leg = math.atan2(q[1] - r[1], q[0] - r[0])
        headings.append(leg + math.radians(draw(st.floats(-40, 40))))
    speeds = [draw(st.one_of(st.just(0.0), st.floats(MIN_SPEED_MPS, 1.2))) for _ in pts[1:]]  # 0: at rest
    obstacles = ()
    if draw(st.booleans()):
        c = (draw(st.floats(5, 35)), draw(st.floats(5, 35)))
        w = draw(st.floats(0.5, 3.0))
        poly = ((c[0] - w, c[1] - w), (c[0] + w, c[1] - w), (c[0] + w, c[1] + w), (c[0] - w, c[1] + w))
        if all(Polygon(poly).distance(Point(p)) > 1.5 for p in pts):
            obstacles = (Region(poly, "inside"),)
    return Route(HarbourNode(pts[0][0], pts[0][1], headings[0]),
                 tuple(RouteNode(p[0], p[1], h, v) for p, h, v in zip(pts[1:], headings[1:], speeds)),
                 area=AREA, obstacles=obstacles)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(routes())
def test_every_returned_path_satisfies_the_constraints(route):
    cfg = PlannerConfig()
    try:
        path = plan_route(route, cfg)
    except PlanningError as exc:
        # allowed only with a message naming the segment or node and the reason
        assert "segment" in str(exc) or "nodes[" in str(exc) or "harbour" in str(exc)
        return
    assert_path_ok(path, route, cfg)


@pytest.mark.parametrize("name", ["figure_eight", "harbour_approach", "square_with_obstacle", "survey_lake"])
def test_example_routes_plan_and_satisfy_constraints(name):
    route = load_route(EXAMPLES / f"{name}.yaml")
    cfg = PlannerConfig()
    path = plan_route(route, cfg)
    assert_path_ok(path, route, cfg)
    assert path.length_m > 50


def test_harbour_approach_ends_near_the_harbour_at_rest():
    route = load_route(EXAMPLES / "harbour_approach.yaml")
    path = plan_route(route)
    h = route.harbour
    assert math.hypot(path.north_m[-1] - h.north_m, path.east_m[-1] - h.east_m) < 5.0
    assert path.speed_mps[-1] == 0.0 and path.speed_mps[0] == 0.0


def test_custom_bounds_are_respected():
    route = load_route(EXAMPLES / "figure_eight.yaml")
    cfg = PlannerConfig(length_ratio_max=1.10, min_turn_radius_m=1.5, clearance_m=1.0,
                        spacing_m=0.02, a_lat_max_mps2=0.1, a_long_max_mps2=0.05, speed_max_mps=0.45)
    route = Route(route.harbour, tuple(RouteNode(n.north_m, n.east_m, n.heading_rad, 0.45) for n in route.nodes),
                  route.area)
    path = plan_route(route, cfg)
    assert_path_ok(path, route, cfg)
    assert path.speed_mps.max() <= 0.45
    # tight lobes with a_lat 0.1 m/s^2 must slow the vessel below the node speed
    assert path.speed_mps[len(path) // 2:].min() < 0.45


def _blocked_route(width: float = 3.0) -> Route:
    return Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(30.0, 0.0, 0.0, 0.5),),
                 area=((-5.0, -15.0), (40.0, -15.0), (40.0, 15.0), (-5.0, 15.0)),
                 obstacles=(Region(((12.0, -width), (16.0, -width), (16.0, width), (12.0, width))),))


def test_obstacle_on_the_straight_line_gives_a_detour_around_it():
    route = _blocked_route()
    cfg = PlannerConfig()
    path = plan_route(route, cfg)
    assert_path_ok(path, route, cfg)
    assert any(m.detour for m in path.segments)
    assert len(path.segments) >= 2
    # the straight line is blocked, so the path must leave it by more than the obstacle half-width
    assert np.abs(path.east_m).max() > 3.0 + cfg.clearance_m
    # and it is not wildly long
    assert path.length_m < 1.6 * 30.0


def test_without_detours_a_blocked_segment_is_reported():
    with pytest.raises(PlanningError, match=r"segment 0 \(harbour -> nodes\[0\]\).*obstacles\[0\]"):
        plan_route(_blocked_route(), PlannerConfig(detour=False))


def test_a_wall_across_the_water_is_reported_with_segment_and_reason():
    route = Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(30.0, 0.0, 0.0, 0.5),),
                  area=((-5.0, -15.0), (40.0, -15.0), (40.0, 15.0), (-5.0, 15.0)),
                  obstacles=(Region(((12.0, -16.0), (14.0, -16.0), (14.0, 16.0), (12.0, 16.0))),))
    with pytest.raises(PlanningError, match=r"segment 0 \(harbour -> nodes\[0\]\): .*no detour"):
        plan_route(route)


def test_u_turn_between_close_nodes_is_reported_not_relaxed():
    route = Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(10.0, 0.0, 0.0, 0.5), RouteNode(10.0, 3.0, math.pi, 0.5)),
                  area=AREA)
    with pytest.raises(PlanningError, match=r"segment 1 \(nodes\[0\] -> nodes\[1\]\): a heading change of 180 deg "
                                            r"over 3.00 m cannot be met"):
        plan_route(route)


def test_outside_forbidden_region_keeps_the_path_inside():
    channel = ((-2.0, -4.0), (32.0, -4.0), (32.0, 4.0), (-2.0, 4.0))
    route = Route(HarbourNode(0.0, 0.0, 0.0), (RouteNode(15.0, 1.0, 0.0, 0.6), RouteNode(30.0, -1.0, 0.0, 0.6)),
                  area=AREA, obstacles=(Region(channel, "outside"),))
    cfg = PlannerConfig(clearance_m=1.0)
    path = plan_route(route, cfg)
    assert_path_ok(path, route, cfg)


def test_optimised_cost_not_worse_than_grid_and_seed_method_is_available():
    route = load_route(EXAMPLES / "figure_eight.yaml")
    v = {ref: sum(m.cost for m in plan_route(route, PlannerConfig(refine=ref)).segments)
         for ref in ("none", "zoom", "nelder-mead")}
    assert v["zoom"] <= v["none"] + 1e-9
    assert v["nelder-mead"] <= v["none"] + 1e-9
    seed = plan_route(route, method="seed")
    assert_path_ok(seed, route, PlannerConfig())
    # the default candidate set contains the seed's, so its cost can only be lower
    assert v["zoom"] <= sum(m.cost for m in seed.segments) + 1e-9


@pytest.mark.parametrize("pose", [(30.0, 30.0, 0.0), (30.0, 30.0, math.pi), (20.0, 5.0, math.pi / 2),
                                  (10.0, 30.0, -math.pi / 2)])
def test_return_route_reaches_the_harbour_inside_the_area(pose):
    route = load_route(EXAMPLES / "harbour_approach.yaml")
    cfg = PlannerConfig()
    path = plan_return_route(route, *pose, config=cfg)
    h = route.harbour
    start = RouteNode(pose[0], pose[1], pose[2], 0.5)
    # arrives at the harbour with the harbour heading or its reverse
    psi_end = path.heading_rad[-1]
    assert min(abs(math.remainder(psi_end - h.heading_rad, 2 * math.pi)),
               abs(math.remainder(psi_end - h.heading_rad - math.pi, 2 * math.pi))) < 1e-6
    goal = RouteNode(h.north_m, h.east_m, psi_end, 0.0)
    assert_path_ok(path, route, cfg, nodes=[start, goal])
    assert path.speed_mps[-1] == 0.0
    assert path.speed_mps[0] > 0.0


def test_return_route_around_an_obstacle():
    route = _blocked_route()
    path = plan_return_route(route, 30.0, 0.0, math.pi, speed_mps=0.4, arrival_heading_rad=math.pi)
    assert_path_ok(path, route, PlannerConfig(),
                   nodes=[RouteNode(30.0, 0.0, math.pi, 0.4), RouteNode(0.0, 0.0, math.pi, 0.0)])


@settings(max_examples=40, deadline=None)
@given(st.floats(-20, 20), st.floats(-20, 20), st.floats(-math.pi, math.pi), st.floats(-math.pi, math.pi),
       st.floats(0.5, 3.0))
def test_dubins_waypoints_end_at_the_goal(n, e, h0, h1, radius):
    assume(math.hypot(n, e) > 0.05)
    words = dubins_words((0.0, 0.0, h0), (n, e, h1), radius)
    assert words, "at least one Dubins word always exists"
    for length, word, params in words[:1]:
        poses = dubins_waypoints((0.0, 0.0, h0), word, params, radius)
        assert np.allclose(poses[-1][:2], (n, e), atol=1e-6)
        assert abs(math.remainder(poses[-1][2] - h1, 2 * math.pi)) < 1e-6
        assert length >= math.hypot(n, e) - 1e-9


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.floats(15.0, 35.0), st.floats(0.3, 0.7), st.floats(0.5, 4.0), st.floats(0.5, 3.0),
       st.floats(-1.5, 1.5), st.floats(-20, 20))
def test_detours_around_random_obstacles_on_the_line_satisfy_the_constraints(d, frac, half_w, half_l, shift, hdg):
    """An obstacle across the straight leg: the planner goes around it (or says why it cannot)."""
    c = frac * d
    obstacle = ((c - half_l, shift - half_w), (c + half_l, shift - half_w), (c + half_l, shift + half_w),
                (c - half_l, shift + half_w))
    assume(c - half_l > 3.0 and c + half_l < d - 3.0)
    route = Route(HarbourNode(0.0, 0.0, math.radians(hdg)), (RouteNode(d, 0.0, 0.0, 0.6),),
                  area=((-5.0, -15.0), (d + 5.0, -15.0), (d + 5.0, 15.0), (-5.0, 15.0)),
                  obstacles=(Region(obstacle),))
    cfg = PlannerConfig()
    try:
        path = plan_route(route, cfg)
    except PlanningError as exc:
        assert str(exc).startswith("segment 0 (harbour -> nodes[0]): ")
        return
    assert_path_ok(path, route, cfg)
    assert not LineString(np.column_stack([path.north_m, path.east_m])).intersects(Polygon(obstacle))


def test_return_route_never_reverses_in_a_cusp():
    """Regression: harbour behind the boat; the best-cost cubic used to stop and reverse in place."""
    route = route_from_dict({
        "harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0},
        "nodes": [{"north": 20.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5}],
        "area": [[0, 0], [40, 0], [40, 40], [0, 40]]})
    path = plan_return_route(route, 10.12, 19.85, math.radians(-2.8))
    dpsi = np.abs(np.diff(np.unwrap(path.heading_rad)))
    assert dpsi.max() < 0.02  # at 1 cm spacing and R_min = 1 m: 0.01 rad
    assert path.length_m > 10.0  # it must turn around, not jump
