"""One typed launch config, validated once when it is loaded: every `extra` section a typed field,
a bad value of any section an error naming the file and its key path before anything starts."""

from pathlib import Path

import pytest
import yaml

from lotsen.errors import ConfigError
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.config import SECTIONS, ROS2_DEFAULT_PUBLISH, ExtraConfig, StackConfig, load_stack_config, stack_config
from lotsen.stack.launch import build_stack
from lotsen.web.options import WebOptions

REPO = Path(__file__).resolve().parents[2]

#: one bad value per section, and the key path the error must name
BAD = {
    "processes": ({"watchdog_s": 99}, "extra.processes.watchdog_s: 99.0 outside the allowed range"),
    "planning": ({"max_nodes": "many"}, "extra.planning.max_nodes: expected an integer"),
    "planner": ({"min_turn_radius_m": "tight"}, "extra.planner.min_turn_radius_m: expected a number"),
    "failsafes": ({"link_timeout_s": "soon"}, "extra.failsafes.link_timeout_s: expected a number"),
    "logs": ({"queue_maxlen": -5}, "extra.logs.queue_maxlen: -5 outside the allowed range"),
    "web": ({"max_viewers": 0}, "extra.web.max_viewers: 0 outside the allowed range"),
    "zenoh": ({"mode": "server"}, "extra.zenoh.mode: 'server' is not one of"),
    "ros2": ({"domain_id": "seven"}, "extra.ros2.domain_id: expected an integer"),
    "hardware": ({"gnss": {"baudrat": 9600}}, "extra.hardware.gnss.baudrat: unknown key (did you mean 'baudrate'?)"),
    "emulated": ("yes", "extra.emulated: expected true or false, got 'yes'"),
    "mavlink": ({"endpoints": ["udp:14550"]}, "extra.mavlink.endpoints[0]: 'udp:14550' is not a MAVLink connection"),
    "physics": ({"servos": {"n_full_rps": 0}}, "extra.physics.servos.n_full_rps: 0.0 outside the allowed range"),
}


def _write(tmp_path: Path, data: dict) -> Path:
    path = tmp_path / "launch.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_every_section_has_a_bad_value_case():
    assert set(BAD) == set(SECTIONS)


@pytest.mark.parametrize("section", sorted(BAD))
def test_a_bad_value_in_any_section_is_named_with_its_key_path_at_load(tmp_path, section):
    value, message = BAD[section]
    path = _write(tmp_path, {"mode": "sim", "extra": {section: value}})
    with pytest.raises(ConfigError) as err:
        load_stack_config(path)
    assert str(err.value).startswith(f"{path}: "), str(err.value)
    assert message in str(err.value)


def test_an_unknown_section_is_refused_with_the_known_ones(tmp_path):
    path = _write(tmp_path, {"extra": {"failsafe": {"link_timeout_s": 2.0}}})
    with pytest.raises(ConfigError) as err:
        load_stack_config(path)
    text = str(err.value)
    assert "extra: unknown section(s) ['failsafe']" in text and "did you mean 'failsafes'?" in text
    assert all(s in text for s in SECTIONS)


def test_ros2_pilot_token_is_refused_and_the_run_token_is_used(tmp_path):
    with pytest.raises(ConfigError, match="extra.ros2.pilot_token: not configurable"):
        load_stack_config(_write(tmp_path, {"extra": {"ros2": {"pilot_token": "x" * 30}}}))
    config = load_stack_config(_write(tmp_path, {"extra": {"ros2": None}}))
    assert config.extra.ros2 is not None and config.extra.ros2.publish == tuple(ROS2_DEFAULT_PUBLISH)
    assert config.extra.ros2.pilot_token is None  # the run's token is added where the ROS 2 process starts


def test_sections_are_typed_attributes_read_by_the_parts(tmp_path):
    path = _write(tmp_path, {"logging": {"directory": "my_logs"},
                             "extra": {"failsafes": {"link_timeout_s": 2.5}, "planner": {"clearance_m": 0.8},
                                       "logs": {"flush_period_s": 1.0}, "zenoh": {"enabled": False, "vessel": "x"}}})
    config = load_stack_config(path)
    assert isinstance(config, StackConfig) and isinstance(config.extra, ExtraConfig)
    assert config.extra.failsafes.link_timeout_s == 2.5 and config.extra.planner.clearance_m == 0.8
    # the recorder's directory is logging.directory, taken from the config file's folder
    assert config.extra.logs is not None and config.extra.logs.flush_period_s == 1.0
    assert config.extra.logs.directory == str(tmp_path / "my_logs")
    assert config.extra.zenoh is None  # disabled: no bridge
    # the web page's link timeout defaults to the supervisor's
    assert WebOptions.from_config(config, config.extra.web, config.extra.failsafes.link_timeout_s).link_timeout_s == 2.5


def test_a_launch_config_built_in_code_is_typed_once_by_the_stack():
    raw = LaunchConfig(extra={"failsafes": {"prearm_skip": ["pilot_link"]}})
    typed = stack_config(raw)
    assert typed.extra.failsafes.prearm_skip == ("pilot_link",) and stack_config(typed) is typed
    stack = build_stack(raw, realtime=False, parts=())
    try:
        assert stack.config == typed
    finally:
        stack.shutdown()
    with pytest.raises(ConfigError, match="extra.failsafes.link_timeout_s"):
        build_stack(LaunchConfig(extra={"failsafes": {"link_timeout_s": -1}}), realtime=False, parts=())


@pytest.mark.parametrize("path", sorted([*REPO.glob("config/*.yaml"), REPO / "deploy" / "hardware.yaml"]),
                         ids=lambda p: str(p.relative_to(REPO)))
def test_every_shipped_config_loads(path):
    config = load_stack_config(path)
    assert isinstance(config.extra, ExtraConfig)
    raw = yaml.safe_load(path.read_text()) or {}
    assert set(raw.get("extra") or {}) <= set(SECTIONS)


def test_the_logs_map_origin_is_the_stacks_one_origin(tmp_path):
    from lotsen.stack.logs import recorder_config
    from lotsen.stack.stack import resolve_origin

    with pytest.raises(ConfigError, match="extra.logs.geo_origin: not configurable.*`origin`"):
        load_stack_config(_write(tmp_path, {"extra": {"logs": {"geo_origin": [57.0, 11.0, 0.0]}}}))
    config = load_stack_config(_write(tmp_path, {"mode": "sim", "origin": {"lat_deg": 57.7, "lon_deg": 11.9},
                                                 "extra": {"logs": {"flush_period_s": 1.0}}}))
    assert recorder_config(config, resolve_origin(config)).geo_origin == (57.7, 11.9, 0.0)
    assert recorder_config(config, None).geo_origin is None  # a boat without a configured origin: no map views


def test_the_mpc_has_a_wall_clock_budget_only_at_wall_clock_pace():
    """On simulated time the MPC's answer may not depend on how busy (or emulated) the machine is:
    no OSQP time limit there; the real-time stack gives every solve REALTIME_SOLVE_LIMIT_S."""
    from lotsen.control.mpc import REALTIME_SOLVE_LIMIT_S
    from lotsen.runtime.executor import RealtimeExecutor

    config = LaunchConfig(mode="sim")
    for executor, limit in ((None, 0.0), (RealtimeExecutor(), REALTIME_SOLVE_LIMIT_S)):
        stack = build_stack(config, realtime=False, parts=("supervisor",), executor=executor)
        try:
            follower = stack.nodes["supervisor"].follower
            assert follower.config.time_limit_s == limit
            if limit:
                assert follower.solver.settings.time_limit == pytest.approx(limit)
        finally:
            stack.shutdown()
