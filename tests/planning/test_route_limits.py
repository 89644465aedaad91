"""The physical limits of a route (one place: lotsen.planning.route), the same for a route file
of the CLI and a route of the page, and `lotsen plan` under the page's planning budget."""

from __future__ import annotations

import math
import time

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.errors import ConfigError, LotsenError
from lotsen.planning import route as route_limits
from lotsen.planning.io import route_from_dict

BASE = {"harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
        "nodes": [{"north": 20.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5}],
        "area": [[-10.0, -10.0], [40.0, -10.0], [40.0, 10.0], [-10.0, 10.0]]}


def _with(**changes) -> dict:
    d = {k: (list(v) if isinstance(v, list) else dict(v)) for k, v in BASE.items()}
    d["nodes"] = [dict(n) for n in BASE["nodes"]]
    for key, value in changes.items():
        if key == "node":
            d["nodes"][0].update(value)
        elif key == "harbour":
            d["harbour"].update(value)
        else:
            d[key] = value
    return d


@pytest.mark.parametrize("changes, where", [
    ({"node": {"heading_deg": 1e308}}, "nodes[0].heading_deg"),
    ({"node": {"heading_deg": 361.0}}, "nodes[0].heading_deg"),
    ({"harbour": {"heading_deg": -1e6}}, "harbour.heading_deg"),
    ({"node": {"north": 1e7}, "area": [[-1e7, -1e7], [1e7, -1e7], [1e7, 1e7], [-1e7, 1e7]]}, "nodes[0].north"),
    ({"area": [[-10.0, -10.0], [1e308, -10.0], [40.0, 10.0], [-10.0, 10.0]]}, "area[1].north"),
    ({"area": None, "node": {"north": 1999.0, "east": 1999.0}, "harbour": {"north": -1999.0}}, "nodes[0]: "),
    ({"area": None, "node": {"north": 127_000.0}}, "nodes[0].north"),
    ({"node": {"speed_mps": 1e9}}, "nodes[0].speed_mps"),
    ({"obstacles": [[[0.0, 3000.0], [1.0, 3000.0], [1.0, 3001.0]]]}, "obstacles[0][0].east"),
])
def test_routes_beyond_the_physical_limits_are_refused_at_once_naming_the_place(changes, where):
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as exc:
        route_from_dict(_with(**changes))
    assert time.perf_counter() - t0 < 0.5
    assert str(exc.value).startswith(where), str(exc.value)


def test_routes_within_the_limits_are_accepted():
    m = route_limits.MAX_COORDINATE_M
    route_from_dict(_with(node={"heading_deg": -360.0, "speed_mps": route_limits.MAX_SPEED_MPS}))
    route_from_dict(_with(area=[[-m, -m], [m, -m], [m, m], [-m, m]], node={"north": 1500.0}, harbour={"north": -450.0}))


def test_the_page_validator_uses_the_same_coordinate_limit():
    from lotsen.web import validation

    assert validation.MAX_EXTENT_M == route_limits.MAX_COORDINATE_M


finite = st.floats(allow_nan=True, allow_infinity=True)
huge = st.one_of(finite, st.floats(-1e4, 1e4), st.sampled_from([1e308, -1e308, 1e7, -1e7, 2000.0, 2000.0001]))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(huge, huge, huge, huge, st.one_of(huge, st.floats(0, 10)))
def test_fuzzed_numbers_are_accepted_only_within_the_limits(north, east, heading, corner, speed):
    data = _with(node={"north": north, "east": east, "heading_deg": heading, "speed_mps": speed},
                 area=[[-10.0, -10.0], [corner, -10.0], [40.0, 10.0], [-10.0, 10.0]])
    t0 = time.perf_counter()
    try:
        route = route_from_dict(data)
    except LotsenError as exc:
        assert str(exc).strip()
    else:
        n = route.nodes[0]
        assert abs(n.north_m) <= route_limits.MAX_COORDINATE_M and abs(n.east_m) <= route_limits.MAX_COORDINATE_M
        assert abs(n.heading_rad) <= route_limits.MAX_HEADING_RAD + 1e-9 and n.speed_mps <= route_limits.MAX_SPEED_MPS
        assert all(abs(v) <= route_limits.MAX_COORDINATE_M for p in route.area for v in p)
        assert math.hypot(n.north_m, n.east_m) <= route_limits.MAX_LEG_M
    assert time.perf_counter() - t0 < 1.0
