"""Every file reader at the boundary reports a file that is not UTF-8 text (UTF-16, Latin-1, a
binary, random bytes) and a YAML key given twice as a LotsenError naming the file and the place."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.errors import ConfigError, DataError, LotsenError
from lotsen.files import decode_text, parse_yaml, read_json, read_yaml

REPO = Path(__file__).resolve().parents[2]
ROUTE = (REPO / "examples" / "routes" / "figure_eight.yaml").read_text(encoding="utf-8")
CONFIG = "mode: sim\nseed: 3\nweb:\n  port: 0\n"
PARAMS = '{"m11": 15.0}'
CSV = "t,n1,n2\n0.0,1.0,2.0\n"


def _loaders():
    from lotsen.cli.calibrate import load_mag_csv
    from lotsen.harness.fault_injection import load_scenarios
    from lotsen.planning.io import load_route
    from lotsen.runtime.config import load_config
    from lotsen.stack.stack import load_parameters
    from lotsen.sysid.data import load_csv
    from lotsen.sysid.experiment import load_experiment

    return {  # name: (loader, file suffix, a valid text for it)
        "route": (load_route, ".yaml", ROUTE),
        "geojson route": (load_route, ".geojson", '{"type": "FeatureCollection", "features": []}'),
        "launch config": (load_config, ".yaml", CONFIG),
        "parameters": (load_parameters, ".json", PARAMS),
        "experiment": (load_experiment, ".yaml", "name: x\npieces: []\n"),
        "fault scenarios": (load_scenarios, ".yaml", "[]\n"),
        "identification CSV": (load_csv, ".csv", CSV),
        "magnetometer CSV": (load_mag_csv, ".csv", "t,mag_x,mag_y\n0,1,2\n"),
    }


LOADERS = _loaders()


@pytest.mark.parametrize("name", sorted(LOADERS))
@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-le", "utf-16-be", "latin-1", "cp1252"])
def test_a_file_not_in_utf8_is_a_clear_error(tmp_path, name, encoding):
    loader, suffix, text = LOADERS[name]
    text = text.replace("\n", " # Größe\n", 1) if suffix != ".json" and not name.endswith("CSV") else text + " "
    if name.endswith("CSV") or suffix == ".json" or suffix == ".geojson":
        text = "\u00e9" + text if encoding in ("latin-1", "cp1252") else text
    path = tmp_path / f"file{suffix}"
    path.write_bytes(text.encode(encoding))
    with pytest.raises(LotsenError) as exc:
        loader(path)
    message = str(exc.value)
    assert str(path) in message and ("UTF-8" in message), message


@pytest.mark.parametrize("name", sorted(LOADERS))
def test_a_utf8_byte_order_mark_is_accepted_where_the_text_is(tmp_path, name):
    loader, suffix, text = LOADERS[name]
    plain, bom = tmp_path / f"plain{suffix}", tmp_path / f"bom{suffix}"
    plain.write_text(text, encoding="utf-8")
    bom.write_text(text, encoding="utf-8-sig")
    try:
        expected = repr(loader(plain))
    except LotsenError as exc:  # the sample may not be a complete file of its kind: the same answer
        with pytest.raises(type(exc)):
            loader(bom)
        return
    assert repr(loader(bom)).replace(str(bom), str(plain)) == expected


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=200))
def test_fuzzed_bytes_are_text_or_a_clear_error(data):
    try:
        text = decode_text(data, "f.yaml", ConfigError, "route file")
    except ConfigError as exc:
        assert str(exc).startswith("f.yaml: ") and "UTF-8" in str(exc)
    else:
        assert "\x00" not in text and text == data.decode("utf-8-sig")


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.text(max_size=60), st.sampled_from(["utf-16", "utf-16-le", "utf-16-be", "utf-32"]))
def test_fuzzed_utf16_text_is_always_refused(text, encoding):
    # a file of ours holds ASCII (keys, digits): in UTF-16/32 each ASCII letter brings NUL bytes. A text
    # of astral characters alone need not: U+3AC80 in UTF-16-BE is D8 AB DC 80, valid UTF-8 ("\u062b\u0700")
    data = ("a: " + text).encode(encoding)
    with pytest.raises(DataError, match="UTF-8"):
        decode_text(data, "f.csv", DataError, "data file")


# ------------------------------------------------------------------------------------------------
# duplicate keys
# ------------------------------------------------------------------------------------------------
def test_a_duplicate_top_level_key_is_refused_with_the_key_and_lines(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("mode: sim\nseed: 1\nweb: {port: 0}\nseed: 2\n")
    with pytest.raises(ConfigError, match=r"line 4.*duplicate key 'seed' \(first at line 2\)"):
        read_yaml(path, ConfigError)
    from lotsen.runtime.config import load_config

    with pytest.raises(ConfigError, match="duplicate key 'seed'"):
        load_config(path)


def test_a_duplicate_nested_key_in_a_route_is_refused(tmp_path):
    from lotsen.planning.io import load_route

    path = tmp_path / "r.yaml"
    path.write_text("harbour: {north: 0, east: 0, heading_deg: 0, north: 5}\nnodes: []\n")
    with pytest.raises(ConfigError, match=r"r.yaml.*line 1.*duplicate key 'north'"):
        load_route(path)


def test_the_page_import_refuses_duplicate_keys_too():
    from lotsen.web.planning_api import import_route

    for text in ("harbour: {north: 0, east: 0}\nnodes: []\nharbour: {north: 1, east: 0}\n",
                 "a: &x 1\nharbour: {north: *x, east: 0, east: 1}\nnodes: []\n"):
        with pytest.raises(ConfigError, match="duplicate key|aliases"):
            import_route(text, "yaml")


def test_the_page_import_refuses_duplicate_geojson_keys_and_yaml_aliases():
    from lotsen.web.planning_api import import_route

    with pytest.raises(ConfigError, match="import: not valid JSON: duplicate key 'harbour'"):
        import_route('{"harbour": 1, "harbour": 2}', "geojson")
    with pytest.raises(ConfigError, match=r"import: .*aliases \(\*a\) are not allowed"):
        import_route("a: &a {north: 0, east: 0}\nharbour: *a\nnodes: []\n", "yaml")


def test_yaml_and_json_text_is_parsed_only_by_lotsen_files():
    """One loader: every other module reads YAML/JSON files and pasted text through lotsen.files
    (encodings, duplicate keys, hostile structures); json.loads stays for messages on the wire."""
    offenders = []
    for path in sorted((REPO / "lotsen").rglob("*.py")) + sorted((REPO / "bench").rglob("*.py")):
        if path.name == "files.py" and path.parent.name == "lotsen":
            continue
        text = path.read_text(encoding="utf-8")
        for needle in ("yaml.safe_load(", "yaml.load(", "yaml.full_load(", "json.load("):
            if needle in text:
                offenders.append(f"{path.relative_to(REPO)}: {needle}")
    assert not offenders, offenders


def test_merge_keys_may_still_be_overridden():
    assert parse_yaml("base: &b {k: 1, j: 2}\nd:\n  <<: *b\n  k: 3\n", "f") == {"base": {"k": 1, "j": 2},
                                                                              "d": {"k": 3, "j": 2}}


keys = st.text(alphabet="abcxyz_", min_size=1, max_size=4)


@settings(max_examples=200, deadline=None)
@given(st.lists(keys, min_size=1, max_size=8), st.integers(0, 3))
def test_fuzzed_mappings_are_refused_exactly_when_a_key_repeats(names, depth):
    body = "".join(f"{'  ' * depth}{k}: {i}\n" for i, k in enumerate(names))
    head = "".join(f"{'  ' * d}n{d}:\n" for d in range(depth))
    text = head + body
    if len(set(names)) == len(names):
        data = parse_yaml(text, "f.yaml", ConfigError)
        for d in range(depth):
            data = data[f"n{d}"]
        assert data == {k: i for i, k in enumerate(names)}
    else:
        dup = next(k for i, k in enumerate(names) if k in names[:i])
        with pytest.raises(ConfigError, match=f"duplicate key '{dup}'"):
            parse_yaml(text, "f.yaml", ConfigError)


def test_json_with_a_duplicate_key_is_refused_too(tmp_path):
    path = tmp_path / "p.json"
    path.write_text('{"m11": 15.0, "m22": 20.0, "m11": 1.0}')
    with pytest.raises(ConfigError, match="duplicate key 'm11'"):
        read_json(path, ConfigError)


# ------------------------------------------------------------------------------------------------
# numbers in exponent form
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("text, value", [("1e9", 1e9), ("3e-2", 0.03), ("1.0e9", 1e9), ("-2.5E+3", -2500.0),
                                         (".5e1", 5.0)])
def test_a_number_in_exponent_form_is_a_number(text, value):
    """PyYAML (YAML 1.1) reads these as text; an operator writing m22: 1e9 or a latency of 3e-2
    got "expected a number, got '3e-2'" for a number. Quoted, it stays text."""
    assert parse_yaml(f"a: {text}", "t.yaml") == {"a": value}
    assert parse_yaml(f"a: {text}\nb: &x 1\nc: *x\n", "t.yaml") == {"a": value, "b": 1, "c": 1}  # Python loader
    assert parse_yaml(f"a: '{text}'", "t.yaml") == {"a": text}
    assert parse_yaml("a: 1e9x", "t.yaml") == {"a": "1e9x"}


def test_a_config_value_in_exponent_form_is_read_and_a_map_of_numbers_is_checked_at_load(tmp_path):
    """sim.boat.parameters is a map of numbers: a value that is not one is refused when the file
    is read, with the file and the key path (it used to surface at start-up without the file)."""
    from lotsen.runtime.config import load_config

    path = tmp_path / "c.yaml"
    path.write_text("sim:\n  boat:\n    command_latency_s: 3e-2\n    parameters: {m22: 2.5e1}\n")
    cfg = load_config(path)
    assert cfg.sim.boat.command_latency_s == 0.03 and cfg.sim.boat.parameters == {"m22": 25.0}
    path.write_text("sim:\n  boat:\n    parameters: {m22: abc}\n")
    with pytest.raises(ConfigError, match=r"c.yaml: sim.boat.parameters.m22: expected a number, got 'abc'"):
        load_config(path)
