"""Route files: YAML and GeoJSON round trips, and a clear error naming the place for each bad input."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path as FilePath

import numpy as np
import pytest
import yaml

from lotsen.errors import ConfigError, LotsenError, PlanningError
from lotsen.planning import GeoOrigin, PlannerConfig, plan_route
from lotsen.planning.io import (load_route, route_from_dict, route_from_geojson, route_to_dict,
                                route_to_geojson, save_route)

EXAMPLES = FilePath(__file__).resolve().parents[2] / "examples" / "routes"

BASE = {
    "harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
    "nodes": [
        {"north": 20.0, "east": 5.0, "heading_deg": 30.0, "speed_mps": 0.6},
        {"north": 30.0, "east": 25.0, "heading_deg": 90.0, "speed_mps": 0.5},
        {"north": 20.0, "east": 35.0, "heading_deg": 180.0, "speed_mps": 0.5},
    ],
    "area": [[-5, -5], [40, -5], [40, 40], [-5, 40]],
    "obstacles": [[[10, 10], [14, 10], [14, 14], [10, 14]]],
}


def test_base_route_is_valid_and_plans():
    plan_route(route_from_dict(copy.deepcopy(BASE)))


def _set(d, path, value):
    *head, last = path
    for k in head:
        d = d[k]
    if value is _DELETE:
        del d[last]
    else:
        d[last] = value


_DELETE = object()

BAD = [
    # (where, new value, expected message fragment)
    (("nodes",), [], "at least two nodes"),
    (("nodes", 1, "north"), 20.0, None),  # placeholder replaced below
    (("nodes", 2, "speed_mps"), -0.5, "nodes[2].speed_mps: -0.5 is negative"),
    (("nodes", 0, "north"), "abc", "nodes[0].north: expected a number, got 'abc'"),
    (("nodes", 0, "east"), float("nan"), "nodes[0].east: nan is not a finite number"),
    (("nodes", 1, "heading_deg"), True, "nodes[1].heading_deg: expected a number, got True"),
    (("nodes", 0, "sped_mps"), 0.5, "nodes[0]: unknown key(s) ['sped_mps']"),
    (("nodes", 0, "speed_mps"), _DELETE, "nodes[0]: missing key(s) ['speed_mps']"),
    (("colour",), "red", "route: unknown key(s) ['colour']"),
    (("harbour", "speed_mps"), 0.0, "harbour: unknown key(s) ['speed_mps']"),
    (("nodes", 2, "north"), 50.0, "nodes[2] (north 50, east 35) is outside the navigable area"),
    (("nodes", 0, "north"), 12.0, None),
    (("obstacles", 0), [[10, 10], [14, 14], [14, 10], [10, 14]], "obstacles[0]: polygon is self-intersecting"),
    (("area",), [[0, 0], [40, 40], [40, 0], [0, 40]], "area: polygon is self-intersecting"),
    (("obstacles", 0), [[10, 10], [14, 10]], "obstacles[0]: a polygon needs at least 3 vertices"),
    (("obstacles", 0), {"polygon": [[10, 10], [14, 10], [14, 14]], "forbidden": "both"},
     "obstacles[0].forbidden: must be 'inside' or 'outside', got 'both'"),
    (("obstacles", 0), {"polygon": [[10, 10], [14, 10], [14, 14]], "side": "inside"},
     "obstacles[0]: unknown key(s) ['side']"),
    (("area", 1), [40, "x"], "area[1][1]: expected a number, got 'x'"),
    (("nodes",), {"north": 1}, "nodes: expected a list of nodes, got dict"),
    (("origin",), {"lat_deg": 95.0, "lon_deg": 18.0}, "origin: latitude 95 / longitude 18 out of range"),
]
# a node duplicating its predecessor, and a node inside an obstacle
BAD[1] = (("nodes", 1), {"north": 20.0, "east": 5.0, "heading_deg": 0.0, "speed_mps": 0.5},
          "nodes[1]: duplicates nodes[0]")
BAD[11] = (("nodes", 0), {"north": 12.0, "east": 12.0, "heading_deg": 30.0, "speed_mps": 0.5},
           "nodes[0] (north 12, east 12) is inside obstacles[0]")


@pytest.mark.parametrize("where,value,message", BAD, ids=[m[:40] for _, _, m in BAD])
def test_bad_input_is_a_config_error_naming_the_place(where, value, message):
    d = copy.deepcopy(BASE)
    _set(d, where, value)
    with pytest.raises(ConfigError) as exc:
        route_from_dict(d)
    assert message in str(exc.value)


def test_excessive_speed_names_the_node():
    d = copy.deepcopy(BASE)
    d["nodes"][1]["speed_mps"] = 2.5
    with pytest.raises(ConfigError, match=r"nodes\[1\]\.speed_mps: 2.5 exceeds speed_max_mps 1.5"):
        plan_route(route_from_dict(d))


def test_node_too_close_to_an_obstacle_names_node_and_obstacle():
    d = copy.deepcopy(BASE)
    d["nodes"][0] = {"north": 9.8, "east": 12.0, "heading_deg": 0.0, "speed_mps": 0.5}
    with pytest.raises(PlanningError, match=r"nodes\[0\] \(north 9.8, east 12\) is 0.20 m from obstacles\[0\], "
                                            r"closer than the clearance 0.5 m"):
        plan_route(route_from_dict(d))


def test_bad_planner_config():
    with pytest.raises(ConfigError, match="planner.min_turn_radius_m"):
        PlannerConfig(min_turn_radius_m=0.0)
    with pytest.raises(ConfigError, match="planner.length_ratio_max"):
        PlannerConfig(length_ratio_max=0.9)
    with pytest.raises(ConfigError, match="planner.clearance_m"):
        PlannerConfig(clearance_m=float("nan"))


def test_file_errors_are_config_errors(tmp_path):
    with pytest.raises(ConfigError, match="cannot read route file"):
        load_route(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("harbour: {north: 0, east: [\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: not valid YAML at line"):
        load_route(bad)
    nan = tmp_path / "nan.yaml"
    nan.write_text(yaml.safe_dump(BASE).replace("speed_mps: 0.6", "speed_mps: .nan"))
    with pytest.raises(ConfigError, match=r"nan.yaml: nodes\[0\].speed_mps: nan is not a finite number"):
        load_route(nan)
    with pytest.raises(ConfigError, match="route: expected a mapping"):
        route_from_dict([1, 2])


@pytest.mark.parametrize("name", ["figure_eight", "harbour_approach", "square_with_obstacle"])
def test_yaml_round_trip(tmp_path, name):
    route = load_route(EXAMPLES / f"{name}.yaml")
    save_route(route, tmp_path / "r.yaml")
    again = load_route(tmp_path / "r.yaml")
    assert route_to_dict(again) == route_to_dict(route)
    assert again.obstacles == route.obstacles and again.area == route.area
    for a, b in zip(again.all_nodes(), route.all_nodes()):
        assert a.north_m == b.north_m and a.east_m == b.east_m and a.speed_mps == b.speed_mps
        assert math.isclose(a.heading_rad, b.heading_rad, abs_tol=1e-12)


@pytest.mark.parametrize("name", ["figure_eight", "harbour_approach", "square_with_obstacle"])
def test_geojson_round_trip(tmp_path, name):
    route = load_route(EXAMPLES / f"{name}.yaml")
    origin = route.origin or GeoOrigin(57.7089, 11.9746, 10.0)
    gj = route_to_geojson(route, origin)
    assert gj["type"] == "FeatureCollection"
    # RFC 7946 order is [lon, lat]: near the origin the harbour's longitude is close to lon_deg
    harbour = next(f for f in gj["features"] if f["properties"]["role"] == "harbour")
    assert abs(harbour["geometry"]["coordinates"][0] - origin.lon_deg) < 1e-3
    assert abs(harbour["geometry"]["coordinates"][1] - origin.lat_deg) < 1e-3
    (tmp_path / "r.geojson").write_text(json.dumps(gj))
    again = load_route(tmp_path / "r.geojson")
    a, b = route_to_dict(again), route_to_dict(route)
    for n1, n2 in zip(again.all_nodes(), route.all_nodes()):
        assert math.hypot(n1.north_m - n2.north_m, n1.east_m - n2.east_m) < 1e-6
        assert math.isclose(n1.heading_rad, n2.heading_rad, abs_tol=1e-9) and n1.speed_mps == n2.speed_mps
    if route.area:
        assert np.allclose(a["area"], b["area"], atol=1e-6)
    assert len(again.obstacles) == len(route.obstacles)
    for o1, o2 in zip(again.obstacles, route.obstacles):
        assert o1.forbidden == o2.forbidden and np.allclose(o1.polygon, o2.polygon, atol=1e-6)


def test_geojson_known_point_and_origin_required():
    route = route_from_dict(copy.deepcopy(BASE))
    with pytest.raises(ConfigError, match="route has no origin"):
        route_to_geojson(route)
    # 1 km north of the origin: 1000 m / M(59 deg) = 1000 / 6382479 m rad = 0.0089771 deg (WGS84 meridian radius)
    d = copy.deepcopy(BASE)
    d["area"] = [[-5, -5], [2000, -5], [2000, 40], [-5, 40]]
    d["nodes"] = [{"north": 1000.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5}]
    d["obstacles"] = []
    gj = route_to_geojson(route_from_dict(d), GeoOrigin(59.0, 18.0))
    lon, lat = gj["features"][1]["geometry"]["coordinates"]
    assert lon == pytest.approx(18.0, abs=1e-9) and lat == pytest.approx(59.0 + 0.0089771, abs=1e-6)
    # a file without the lotsen_origin member takes the harbour as origin
    del gj["lotsen_origin"]
    r = route_from_geojson(gj)
    assert (r.origin.lat_deg, r.origin.lon_deg) == pytest.approx((59.0, 18.0))
    # GeoJSON is 2-D: the point comes back at the origin's height instead of 7.8 cm above the
    # ellipsoid (the tangent plane rises over 1 km), which moves it ~d^2/R * d/R = 12 um
    assert r.nodes[0].north_m == pytest.approx(1000.0, abs=1e-4)


def test_bad_geojson():
    with pytest.raises(ConfigError, match="expected a FeatureCollection"):
        route_from_geojson({"type": "Feature"})
    with pytest.raises(ConfigError, match=r"features\[0\].properties.role"):
        route_from_geojson({"type": "FeatureCollection", "features": [
            {"type": "Feature", "geometry": {"type": "Point", "coordinates": [18, 59]}, "properties": {}}]})


def test_cli_plan_writes_json_and_plot(tmp_path, capsys):
    import argparse

    from lotsen.cli import plan as cli_plan
    from lotsen.planning import Path

    parser = argparse.ArgumentParser()
    cli_plan.register(parser.add_subparsers())
    out, png = tmp_path / "p.json", tmp_path / "p.png"
    args = parser.parse_args(["plan", str(EXAMPLES / "square_with_obstacle.yaml"), "--out", str(out),
                              "--plot", str(png)])
    assert args.func(args) == 0
    path = Path.from_dict(json.loads(out.read_text()))
    assert path.length_m > 50 and png.stat().st_size > 10_000
    assert "detour part" in capsys.readouterr().out
    args = parser.parse_args(["plan", str(tmp_path / "nope.yaml")])
    with pytest.raises(LotsenError):
        args.func(args)
    args = parser.parse_args(["plan", str(EXAMPLES / "harbour_approach.yaml"), "--return-from", "30", "30", "0"])
    assert args.func(args) == 0
