"""The `extra` sections of a launch config reach the parts that use them, and nothing else passes."""

import dataclasses
import secrets

import pytest

from lotsen.errors import ConfigError
from lotsen.runtime.config import LaunchConfig, WebSection
from lotsen.stack.launch import build_stack
from lotsen.stack.processes import validate
from lotsen.stack.stack import example_route
from lotsen.stack.web import add_web


def test_one_planner_config_for_the_route_the_return_and_the_page():
    config = LaunchConfig(route=example_route("figure_eight"), web=WebSection(enabled=True, port=0,
                                                                              pilot_token=secrets.token_urlsafe(24)),
                          extra={"planner": {"min_turn_radius_m": 2.5, "clearance_m": 0.8}})
    validate(config)
    stack = build_stack(config, realtime=False, parts=("state", "supervisor"))
    try:
        server = add_web(stack)
        sup = stack.nodes["supervisor"].config.planner
        page = server.hub.handler.planner_config
        assert sup == page and (sup.min_turn_radius_m, sup.clearance_m) == (2.5, 0.8)
    finally:
        stack.shutdown()


@pytest.mark.parametrize("extra, message", [
    ({"planner": {"min_turn_radius": 2}}, "extra.planner.min_turn_radius: unknown key (did you mean 'min_turn_radius_m'?)"),
    ({"planner": {"speed_max_mps": "fast"}}, "extra.planner.speed_max_mps"),
    ({"planer": {}}, "extra: unknown section(s) ['planer']"),
    ({"planer": {}}, "did you mean 'planner'?"),
])
def test_bad_sections_are_refused_naming_the_key(extra, message):
    with pytest.raises(ConfigError) as err:
        validate(dataclasses.replace(LaunchConfig(), extra=extra))
    assert message in str(err.value)
