"""Fuzz the file loaders at the boundary (issue: input robustness): whatever a YAML file holds,
the route, launch-config, experiment and schedule loaders either accept it or refuse it with a
LotsenError that says what is wrong; no other exception escapes."""

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.errors import LotsenError
from lotsen.planning.io import route_from_dict
from lotsen.runtime.config import LaunchConfig, from_mapping
from lotsen.stack.schedule import InputSchedule
from lotsen.sysid.experiment import parse_experiment

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8))
yamlish = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(st.text(max_size=12), inner, max_size=5)), max_leaves=25)

# documents close to valid ones find the deeper checks
near_route = st.fixed_dictionaries({
    "harbour": st.one_of(yamlish, st.fixed_dictionaries(
        {"north": scalars, "east": scalars, "heading_deg": scalars})),
    "nodes": st.lists(st.one_of(yamlish, st.fixed_dictionaries(
        {"north": st.floats(-50, 50), "east": st.floats(-50, 50), "heading_deg": scalars, "speed_mps": scalars})),
        max_size=4),
    "area": st.one_of(yamlish, st.lists(st.lists(st.floats(-60, 60), min_size=2, max_size=2), max_size=5)),
}, optional={"obstacles": yamlish, "extra": yamlish})
near_experiment = st.fixed_dictionaries({
    "name": scalars,
    "pieces": st.lists(st.one_of(yamlish, st.fixed_dictionaries(
        {"type": st.sampled_from(["constant", "steps", "ramp", "zigzag", "prbs", "multisine", "x"]),
         "duration_s": scalars}, optional={"n_rps": scalars, "levels": yamlish, "alpha_deg": scalars})),
        max_size=3),
}, optional={"area": yamlish, "start": yamlish, "command_rate_hz": scalars})
near_config = st.fixed_dictionaries({}, optional={
    "mode": st.one_of(scalars, st.sampled_from(["sim", "hardware"])), "seed": scalars,
    "sim": st.one_of(yamlish, st.fixed_dictionaries({}, optional={"dt_s": scalars, "initial_state": yamlish,
                                                                  "environment": yamlish})),
    "nodes": yamlish, "web": yamlish, "extra": yamlish})

FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _accepts_or_explains(fn, data):
    try:
        fn(data)
    except LotsenError as exc:
        assert str(exc).strip(), "a refusal must say what is wrong"


@FUZZ
@given(st.one_of(yamlish, near_route))
def test_route_loader(data):
    _accepts_or_explains(route_from_dict, data)


@FUZZ
@given(st.one_of(yamlish, near_experiment))
def test_experiment_loader(data):
    _accepts_or_explains(parse_experiment, data)


@FUZZ
@given(st.one_of(yamlish, near_config))
def test_launch_config_loader(data):
    _accepts_or_explains(lambda d: from_mapping(LaunchConfig, d), data)


@FUZZ
@given(st.one_of(yamlish, st.fixed_dictionaries({"segments": yamlish})))
def test_schedule_loader(data):
    def load(d):
        sched = from_mapping(InputSchedule, d)
        assert all(math.isfinite(s.duration_s) for s in sched.segments)
    _accepts_or_explains(load, data)


# -- issue 14: hostile documents, GeoJSON routes, parameter files --------------------------------
import json  # noqa: E402

import yaml  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from lotsen.errors import ConfigError  # noqa: E402
from lotsen.files import check_structure, parse_json, parse_yaml  # noqa: E402
from lotsen.model.parameters import VesselParameters  # noqa: E402
from lotsen.planning.io import load_route, route_from_geojson  # noqa: E402

huge_ints = st.integers(min_value=10**300, max_value=10**420) | st.integers(min_value=-10**420, max_value=-10**300)
numbers = st.one_of(st.floats(-100, 100), st.integers(-10**6, 10**6), huge_ints, scalars)
point = st.one_of(st.lists(numbers, max_size=3), yamlish)
feature = st.fixed_dictionaries({
    "type": st.just("Feature"),
    "geometry": st.one_of(yamlish, st.fixed_dictionaries({
        "type": st.sampled_from(["Point", "Polygon", "LineString", 3]),
        "coordinates": st.one_of(point, st.lists(st.lists(point, max_size=5), max_size=2))})),
    "properties": st.one_of(yamlish, st.fixed_dictionaries({
        "role": st.one_of(st.sampled_from(["harbour", "node", "area", "obstacle", "x"]), yamlish)},
        optional={"heading_deg": numbers, "speed_mps": numbers, "index": numbers, "forbidden": scalars})),
})
near_geojson = st.fixed_dictionaries({"type": st.just("FeatureCollection"), "features": st.lists(feature, max_size=5)},
                                     optional={"lotsen_origin": st.one_of(yamlish, st.fixed_dictionaries(
                                         {"lat_deg": numbers, "lon_deg": numbers}))})


def _nested(depth: int, open_: str = "[", close: str = "]") -> str:
    return open_ * depth + close * depth


def _alias_bomb(levels: int) -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x]"]
    for k in range(1, levels):
        lines.append(f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


ROUTE_HEAD = "harbour: {north: 0, east: 0, heading_deg: 0}\n"
# depths around the limit (64) here; 5000 levels (pyyaml needs ~1 s to fail) in one test below
depths = st.integers(1, 200)
hostile_texts = st.one_of(
    depths.map(lambda d: ROUTE_HEAD + "nodes: " + _nested(d)),
    depths.map(lambda d: "harbour: " + _nested(d, "{a: ", "}")),
    st.integers(1, 9).map(lambda k: ROUTE_HEAD + _alias_bomb(k).replace("a0:", "nodes:", 0) + "nodes: *a0\n"),
    st.integers(1, 9).map(lambda k: _alias_bomb(k)),
    st.just("a: &a [1, *a]\nharbour: *a\n"),
    st.integers(300, 5000).map(lambda n: ROUTE_HEAD + "nodes:\n  - {north: " + "7" * n
                               + ", east: 0, heading_deg: 0, speed_mps: 0.5}\n"),
    st.integers(300, 5000).map(lambda n: ROUTE_HEAD + "area: [[0, 0], [1, 0], [0, -" + "9" * n + "]]\nnodes: []\n"),
    st.text(max_size=40).map(lambda t: ROUTE_HEAD + t),
)


HOSTILE = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _load_route_text(text: str, suffix: str):
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"route{suffix}"
        p.write_text(text)
        return load_route(p)


@HOSTILE
@given(hostile_texts)
def test_route_files_with_hostile_structures(text):
    _accepts_or_explains(lambda t: _load_route_text(t, ".yaml"), text)
    try:  # the same structure as JSON, where YAML could build it (and it is small enough to write)
        as_json = json.dumps(check_structure(yaml.safe_load(text), "probe", ConfigError))
    except (yaml.YAMLError, ValueError, RecursionError, ConfigError):
        return
    _accepts_or_explains(lambda t: _load_route_text(t, ".json"), as_json)


def test_the_issues_hostile_routes_are_refused_naming_where(tmp_path):
    """issue 14: a 400-digit integer (OverflowError) and 5000 nested '[' (RecursionError)."""
    cases = {
        "big.yaml": (ROUTE_HEAD + "nodes:\n  - {north: " + "1" * 400 + ", east: 0, heading_deg: 0, speed_mps: 0.5}\n",
                     "nodes[0].north: integer with 400 digits is too large"),
        "big.json": ('{"harbour": {"north": ' + "1" * 400 + ', "east": 0}, "nodes": []}', "harbour.north: integer"),
        "deep.yaml": (ROUTE_HEAD + "nodes: " + _nested(5000), "nested too deeply"),
        "deep.json": ('{"nodes": ' + _nested(5000) + "}", "nested too deeply"),
        "deep100.json": ('{"nodes": ' + _nested(100) + "}", "nodes[0][0][0]"),
        "bomb.yaml": (_alias_bomb(9), "alias bomb"),
        "self.yaml": ("a: &a [1, *a]\nharbour: *a\n", "contains itself"),
    }
    for name, (text, expected) in cases.items():
        (tmp_path / name).write_text(text)
        try:
            load_route(tmp_path / name)
        except ConfigError as exc:
            assert str(exc).startswith(str(tmp_path / name)) and expected in str(exc), (name, str(exc))
        else:
            raise AssertionError(f"{name} accepted")


@FUZZ
@given(st.one_of(yamlish, near_geojson))
def test_geojson_route_loader(data):
    _accepts_or_explains(route_from_geojson, data)


@FUZZ
@given(st.one_of(yamlish, st.dictionaries(st.sampled_from(list(VesselParameters.names()) + ["std", "m44"]),
                                          numbers, max_size=6)))
def test_parameter_loader(data):
    try:
        p = VesselParameters.from_dict(data, "params.json")
    except LotsenError as exc:
        assert str(exc).startswith("params.json")
        return
    assert not p.physical_violations() or any(v.endswith("(seed eq. 16)") for v in p.physical_violations())


@HOSTILE
@given(st.one_of(hostile_texts, st.text(max_size=60)))
def test_parsers_refuse_hostile_text_with_a_lotsen_error(text):
    for parse in (parse_yaml, parse_json):
        try:
            parse(text, "f", ConfigError)
        except ConfigError as exc:
            assert str(exc).startswith("f: ")


# -- issue 14 point 8, case by case through the command line: exit code 2 and `error: ...` naming
# the bad value, never a traceback and never a wrong success ------------------------------------
import pytest  # noqa: E402

from lotsen.cli.main import main  # noqa: E402


def _run_refused(monkeypatch, capsys, config_text: str, tmp_path) -> str:
    """`lotsen run CONFIG` must refuse before anything starts; the error line it printed."""
    import lotsen.cli.run as run_cli
    import lotsen.stack.processes as processes

    def launched(*a, **k):
        raise AssertionError("the stack was started with a bad config")

    monkeypatch.setattr(processes, "Launcher", launched)
    monkeypatch.setattr(run_cli, "_run_one_process", launched)
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(config_text)
    assert main(["run", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "Traceback" not in err
    return err


@pytest.mark.parametrize("config_text, expected", [
    ("extra:\n  logs: {queue_maxlen: -5}\n", "extra.logs.queue_maxlen"),
    ("extra:\n  logs: {queue_maxlen: 0}\n", "extra.logs.queue_maxlen"),  # would record nothing
    ("extra:\n  origin: here\n", "origin"),
    ("seed: -1\n", "seed"),
    ("origin: {lat_deg: 95, lon_deg: 11}\n", "lat_deg"),
    ("origin: here\n", "origin"),
])
def test_run_refuses_the_issues_bad_configs_naming_the_key(config_text, expected, monkeypatch, capsys, tmp_path):
    err = _run_refused(monkeypatch, capsys, config_text, tmp_path)
    assert expected in err, err


def test_run_refuses_an_uncreatable_log_directory_naming_it(monkeypatch, capsys, tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    err = _run_refused(monkeypatch, capsys, f"logging: {{enabled: true, directory: {blocker / 'logs'}}}\n", tmp_path)
    assert "logging.directory" in err and str(blocker / "logs") in err, err


def test_plan_cli_refuses_hostile_routes_and_plans_a_straight_route_without_area(tmp_path, capsys):
    big = tmp_path / "big.yaml"
    big.write_text(ROUTE_HEAD + "nodes:\n  - {north: 1" + "0" * 400 + ", east: 0, heading_deg: 0, speed_mps: 0.5}\n")
    assert main(["plan", str(big)]) == 2
    assert "nodes[0].north: integer with 401 digits is too large" in capsys.readouterr().err
    deep = tmp_path / "deep.json"
    deep.write_text('{"harbour": {"north": 0, "east": 0}, "nodes": ' + _nested(5000) + "}")
    assert main(["plan", str(deep)]) == 2
    assert "nested too deeply" in capsys.readouterr().err
    straight = tmp_path / "straight.yaml"
    straight.write_text(ROUTE_HEAD + "nodes:\n  - {north: 20, east: 0, heading_deg: 0, speed_mps: 0.5}\n")
    assert main(["plan", str(straight)]) == 0
    assert "path: 20.00 m" in capsys.readouterr().out


def test_model_check_refuses_a_negative_mass_naming_parameter_and_range(tmp_path, capsys):
    params = tmp_path / "params.json"
    params.write_text('{"m11": -14}')
    assert main(["model", "check", "--params", str(params)]) == 2
    err = capsys.readouterr().err
    assert "m11: -14 outside the allowed range 1 to 200 kg" in err and str(params) in err


point8_config = st.fixed_dictionaries({}, optional={
    "seed": st.one_of(scalars, huge_ints, st.integers(-5, 5)),
    "origin": st.one_of(yamlish, st.just("here"), st.fixed_dictionaries(
        {"lat_deg": numbers, "lon_deg": numbers}, optional={"height_m": numbers})),
    "logging": st.one_of(yamlish, st.fixed_dictionaries({}, optional={"enabled": scalars, "directory": scalars})),
    "extra": st.one_of(yamlish, st.fixed_dictionaries({}, optional={
        "origin": st.one_of(yamlish, st.just("here")),
        "logs": st.one_of(yamlish, st.fixed_dictionaries({}, optional={
            "queue_maxlen": st.one_of(numbers, st.integers(-10, 10)), "flush_period_s": numbers,
            "compression": scalars, "geo_origin": st.lists(numbers, max_size=4)}))})),
})


@FUZZ
@given(point8_config)
def test_launch_configs_of_point_8_are_refused_with_a_message_or_are_sane(data):
    """issue 14 point 8: seed, origin, extra.origin, extra.logs: what `lotsen run` checks before
    anything starts (from_mapping + stack.processes.validate) refuses with a LotsenError, or what
    it accepts is in range (a recorder that records something, an origin on the Earth)."""
    from lotsen.stack.logs import recorder_config
    from lotsen.stack.processes import validate

    try:
        cfg = validate(from_mapping(LaunchConfig, data))
        rc = recorder_config(cfg)
    except LotsenError as exc:
        assert str(exc).strip()
        return
    assert 0 <= cfg.seed < 2**32 and rc.queue_maxlen >= 1 and rc.flush_period_s > 0
    if cfg.origin is not None:
        assert -90 <= cfg.origin.lat_deg <= 90 and -180 <= cfg.origin.lon_deg <= 180
