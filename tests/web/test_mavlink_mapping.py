"""The MAVLink mapping without a network (lotsen.web.mavlink): Rover's mode numbers, commands as
operator actions, refusals with reasons, STATUSTEXT chunks, connection strings, the parameter table."""

from __future__ import annotations

import math

import pytest

from lotsen.errors import ConfigError
from lotsen.supervisor.failsafes import FailsafeConfig
from lotsen.web.mavlink import mapping as M
from lotsen.web.mavlink.options import MavlinkExtra, check_endpoint
from lotsen.web.mavlink.params import ParameterTable


@pytest.mark.parametrize("mode, armed, custom, flags", [
    ("MANUAL", False, 0, 0), ("AUTO", True, 10, 128), ("HOLD", True, 5, 128), ("RETURN", True, 11, 128),
    ("ESTOP", False, 4, 0), ("RC", True, 0, 128), ("CALIBRATE", True, 15, 128)])
def test_lotsen_modes_are_reported_with_rover_numbers(mode, armed, custom, flags):
    base, reported, status = M.heartbeat_fields(mode, armed)
    assert reported == custom and base & M.SAFETY_ARMED == flags and base & M.CUSTOM_MODE_ENABLED
    assert status == (M.STATE_EMERGENCY if mode == "ESTOP" else M.STATE_ACTIVE if armed else M.STATE_STANDBY)
    assert M.heartbeat_fields(mode, armed, ("link_lost",))[2] in (M.STATE_CRITICAL, M.STATE_EMERGENCY)


@pytest.mark.parametrize("command, params, action", [
    (400, (1, 0), "arm"), (400, (0, 0), "disarm"), (400, (0, 21196), "estop"), (176, (1, 10), "auto"),
    (176, (1, 4), "hold"), (176, (1, 5), "hold"), (176, (1, 11), "return"), (176, (1, 0), "manual"),
    (300, (0, 0), "auto"), (20, (0, 0), "return"), (185, (1, 0), "estop"), (185, (0, 0), "reset_estop"),
    (193, (0, 0), "hold"), (193, (1, 0), "auto"), (241, (0, 1), "calibrate_mag"), (42425, (0, 0), "mag_accept"),
    (2510, (0, 0), "logging_on"), (2511, (0, 0), "logging_off")])
def test_commands_become_the_pages_operator_actions(command, params, action):
    req = M.command_request(command, tuple(params) + (0.0,) * (7 - len(params)))
    assert req is not None and req.action == action and not req.refusal


@pytest.mark.parametrize("command, params, words", [
    (400, (1, 21196), "force-arm"), (176, (1, 1), "ACRO: lotsen has no such mode"),
    (176, (0, 10), "custom-mode flag"), (241, (1, 0), "only the magnetometer"), (224, (3, 0), "does not jump")])
def test_what_lotsen_does_not_do_is_refused_with_a_reason(command, params, words):
    req = M.command_request(command, tuple(params) + (0.0,) * (7 - len(params)))
    assert req is not None and not req.action and words in req.refusal


def test_expected_outcome_of_each_action():
    assert M.expected("arm", "MANUAL", True) and not M.expected("arm", "MANUAL", False)
    assert M.expected("hold", "HOLD", True) and not M.expected("hold", "AUTO", True)
    assert M.expected("reset_estop", "MANUAL", False) and not M.expected("reset_estop", "ESTOP", False)


def test_long_texts_are_chunked_on_character_boundaries():
    text = "PreArm: " + "ä" * 60
    chunks = M.statustext_chunks(text)
    assert "".join(chunks) == text and all(len(c.encode()) <= 50 for c in chunks) and len(chunks) == 3


def test_ground_velocity_turns_the_body_velocity_by_the_heading():
    vn, ve = M.ground_velocity(1.0, 0.0, math.pi / 2)
    assert (vn, ve) == pytest.approx((0.0, 1.0))


@pytest.mark.parametrize("url", ["udpout:127.0.0.1:14550", "udpin:0.0.0.0:14550", "tcpin:0.0.0.0:5760",
                                 "/dev/ttyUSB0", "/dev/ttyAMA0,57600"])
def test_connection_strings_accepted(url):
    assert check_endpoint(url) == url


@pytest.mark.parametrize("url, words", [("udp:14550", "not a MAVLink connection"), ("udpout:x:70000", "port"),
                                        ("/dev/ttyUSB0,12", "not a MAVLink"), ("http://boat", "not a MAVLink")])
def test_bad_connection_strings_are_refused_naming_them(url, words):
    with pytest.raises(ConfigError, match=words):
        check_endpoint(url)
    with pytest.raises(ConfigError):
        MavlinkExtra(endpoints=(url,))


def test_the_parameter_table_has_short_names_stable_indices_and_writable_limits():
    table = ParameterTable(lambda k: {"planner.speed_max_mps": 1.5}.get(k, 0.3), {"m11": 14.0, "kappa": 0.02},
                           FailsafeConfig(), "mpc", 10.0, 0.5, 3.0, 1, lambda: 0.5)
    names = [p.name for p in table.params]
    assert len(set(names)) == len(names) and all(len(n) <= 16 for n in names)
    assert table.value("PLN_SPEED_MAX") == 1.5 and table.value("MDL_M11") == 14.0 and table.value("CTRL_TYPE") == 0
    assert table.by_name["PLN_SPEED_MAX"].writable and table.by_name["WP_SPEED"].writable
    assert not table.by_name["MDL_M11"].writable and not table.by_name["FS_LINK_TMO"].writable
    assert table.index("WP_SPEED") == 0


def test_only_the_endpoint_imports_pymavlink():
    """The core and every other process stay without pymavlink (18 MB resident in the web
    process, docs/mavlink.md): one module imports it, loaded only with an endpoint configured."""
    import ast
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "lotsen"
    importers = []
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            if any(n.split(".")[0] == "pymavlink" for n in names):
                importers.append(str(path.relative_to(root)))
    assert sorted(set(importers)) == ["web/mavlink/endpoint.py"]
