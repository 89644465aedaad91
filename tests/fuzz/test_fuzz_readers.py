"""Property tests of the readers and the number type (issue 42): whatever bytes a record holds,
a reader returns what it could read and counts the rest, or refuses with a LotsenError naming the
file and the place; never another exception. In-process and quick (Hypothesis), beside the
command-line fuzz of test_fuzz_cli.py."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.errors import ConfigError, DataError, LotsenError
from lotsen.files import atomic_output, check_output, write_output
from lotsen.settings import Number

FAST = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                         HealthCheck.function_scoped_fixture])


# ------------------------------------------------------------------------------------------- number
numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**400, 10**400), st.booleans(),
                    st.text(max_size=5), st.none(), st.just(5e-324), st.just(-1e-310))


@settings(max_examples=300, deadline=None)
@given(st.floats(-1e6, 1e6), st.floats(0, 1e6), st.booleans(), st.booleans(), numbers)
def test_number_check_returns_a_value_in_range_or_names_the_range(lo, span, integer, zero_ok, value):
    n = Number(math.floor(lo) if integer else lo, (math.floor(lo) if integer else lo) + span, "m", integer, zero_ok)
    try:
        v = n.check(value, "x.y")
    except ConfigError as exc:
        assert str(exc).startswith("x.y: ") and ("allowed" in str(exc) or "outside" in str(exc))
        return
    assert math.isfinite(v) and (n.lo <= v <= n.hi or (zero_ok and v == 0)) and (v == 0 or abs(v) >= sys.float_info.min)
    assert isinstance(v, int) if integer else isinstance(v, float)


def test_the_same_rule_for_a_flag_a_yaml_and_a_json_value():
    """One Number: the same refusal whether the value is text (a flag) or parsed (YAML, JSON)."""
    n = Number(0.2, 60.0, "s")
    for text, parsed in (("1e-320", 1e-320), ("nan", float("nan")), ("1e308", 1e308), ("-1", -1)):
        with pytest.raises(ConfigError) as a:
            n.parse(text, "node")
        with pytest.raises(ConfigError) as b:
            n.check(parsed, "node")
        assert str(a.value).split(":")[0] == str(b.value).split(":")[0] == "node"
        assert "0.2 to 60 s" in str(a.value) and "0.2 to 60 s" in str(b.value)


# ------------------------------------------------------------------------------------------- outputs
def test_an_output_is_never_an_input_nor_a_link_to_one(tmp_path):
    data = tmp_path / "run.csv"
    data.write_text("t\n1\n")
    (tmp_path / "soft.json").symlink_to(data)
    (tmp_path / "hard.json").hardlink_to(data)
    for out in (data, tmp_path / "soft.json", tmp_path / "hard.json", tmp_path / "." / "run.csv"):
        with pytest.raises(LotsenError, match="would overwrite the input"):
            check_output(out, [data])
    with pytest.raises(LotsenError, match="does not exist"):
        check_output(tmp_path / "nope" / "x.json", [])
    with pytest.raises(LotsenError, match="is a folder"):
        check_output(tmp_path, [])
    with pytest.raises(LotsenError, match="not a regular file"):
        check_output("/dev/null", [])  # as root, a rename would have replaced the device with a file
    assert data.read_text() == "t\n1\n"


def test_a_failed_write_leaves_the_old_file_whole_and_no_temporary(tmp_path):
    out = tmp_path / "params.json"
    out.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_output(out) as tmp:
            tmp.write_text("half of the new")
            raise RuntimeError("the command failed while writing")
    assert out.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["params.json"]
    write_output(out, "new")
    assert out.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == ["params.json"]


# ------------------------------------------------------------------------------------------- MCAP
@pytest.fixture(scope="module")
def small_log(tmp_path_factory):
    from lotsen.logs import McapRecorder, RecorderConfig
    from lotsen.messages import ImuSample
    from lotsen.runtime import Bus

    path = tmp_path_factory.mktemp("mcap") / "small.mcap"
    bus = Bus()
    rec = McapRecorder(RecorderConfig(foxglove_views=False, fsync=False, chunk_size=2000)).attach(bus)
    rec.start(path)
    for i in range(200):
        bus.publish("imu/data_raw", ImuSample(stamp_s=i * 0.01, gyro_radps=(0.0, 0.0, 0.1), accel_mps2=(0.0, 0.0, -9.81)))
    rec.close()
    return path.read_bytes()


damage = st.lists(st.tuples(st.integers(0, 10**9), st.integers(0, 7)), min_size=1, max_size=200)


@FAST
@given(damage, st.integers(0, 10**9), st.booleans())
def test_a_damaged_mcap_is_read_as_far_as_it_goes_never_a_crash(small_log, tmp_path_factory, flips, cut, do_cut):
    from lotsen.logs.reader import LogReader
    from lotsen.logs.recover import recover_mcap

    b = bytearray(small_log)
    for pos, bit in flips:
        b[8 + pos % (len(b) - 8)] ^= 1 << bit  # the magic intact: the records are what is damaged
    if do_cut:
        b = b[: 8 + cut % (len(b) - 8)]
    d = tmp_path_factory.mktemp("m")
    src = d / "bad.mcap"
    src.write_bytes(bytes(b))
    reader = LogReader(src)
    try:
        n = sum(1 for _ in reader.messages())
    except LotsenError:
        return
    assert n <= 200
    stats = recover_mcap(src, d / "fixed.mcap", fsync=False)
    assert stats.messages <= 200 and (stats.messages > 0 or stats.nothing_recovered)


@FAST
@given(st.binary(max_size=3000))
def test_random_bytes_after_the_magic_are_refused_or_read(tmp_path_factory, junk):
    from lotsen.logs.reader import LogReader
    from lotsen.logs.recover import recover_mcap

    d = tmp_path_factory.mktemp("j")
    src = d / "junk.mcap"
    src.write_bytes(b"\x89MCAP0\r\n" + junk)
    try:
        list(LogReader(src).messages())
        stats = recover_mcap(src, d / "out.mcap", fsync=False)
    except LotsenError:
        return
    assert stats.nothing_recovered or stats.messages >= 0


# ------------------------------------------------------------------------------------------- CSV records
csv_cells = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.sampled_from(["", "nan", "abc", "1e308",
                                                                                              "1e-320", "-0", "1" * 30]))


@FAST
@given(st.lists(st.lists(csv_cells, min_size=0, max_size=12), max_size=30))
def test_an_identification_csv_is_a_checked_record_or_a_data_error(tmp_path_factory, rows):
    from lotsen.sysid.data import INPUT_COLUMNS, OUTPUT_COLUMNS, VALUE_LIMITS, load_csv

    header = ["t", *INPUT_COLUMNS, *OUTPUT_COLUMNS]
    p = tmp_path_factory.mktemp("c") / "d.csv"
    p.write_text(",".join(header) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    try:
        rec = load_csv(p)
    except DataError as exc:
        assert str(p) in str(exc)
        return
    assert np.all(np.isfinite(rec.t)) and np.all(np.diff(rec.t) >= 0)
    for j, name in enumerate(INPUT_COLUMNS):
        col = rec.inputs[:, j]
        assert np.all(np.abs(col[np.isfinite(col)]) <= VALUE_LIMITS[name][0])


@FAST
@given(st.lists(st.lists(csv_cells, min_size=0, max_size=4), max_size=60))
def test_a_magnetometer_csv_is_read_skipping_and_naming_bad_rows_or_refused(tmp_path_factory, rows):
    from lotsen.cli.calibrate import MAX_FIELD, load_mag_csv
    from lotsen.fusion.magcal import CalibrationLimits, fit_mag_calibration

    p = tmp_path_factory.mktemp("g") / "m.csv"
    p.write_text("t,mag_x,mag_y\n" + "\n".join(",".join(r) for r in rows) + "\n")
    notes: list[str] = []
    try:
        t, x, y, skipped = load_mag_csv(p, notes)
    except DataError as exc:
        assert str(p) in str(exc)
        return
    assert len(notes) == min(skipped, 5) and all(n.startswith("line ") for n in notes)
    assert all(abs(v) <= MAX_FIELD for v in x + y)
    try:
        fit_mag_calibration(x, y, CalibrationLimits(min_points=6))
    except DataError:
        pass


@FAST
@given(st.lists(st.floats(-1e7, 1e7), min_size=0, max_size=80), st.floats(-1e7, 1e7), st.floats(0, 1e7),
       st.one_of(st.none(), st.lists(st.floats(-1e7, 1e7), min_size=80, max_size=80)))
def test_the_magnetometer_fit_returns_a_calibration_or_a_calibration_error(xs, cx, r, free):
    """Any samples: a calibration or a CalibrationError (found: a radius of 6e-276 reached
    scipy's eig with NaNs, a ValueError)."""
    from lotsen.fusion.magcal import CalibrationError, CalibrationLimits, fit_mag_calibration

    ys = [cx + r * math.sin(k) for k in range(len(xs))] if free is None else free[:len(xs)]
    try:
        cal = fit_mag_calibration(xs, ys, CalibrationLimits(min_points=6, min_coverage_deg=90))
    except CalibrationError:
        return
    assert all(math.isfinite(v) for v in cal.center)


# ------------------------------------------------------------------------------------------- parameter files
coefficient = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30), st.just(1e-320),
                        st.text(max_size=3), st.none(), st.lists(st.integers(), max_size=2))


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(st.sampled_from(["m11", "m22", "X_u", "N_r", "kappa", "mu_t", "C_N", "defaults_for", "verdict",
                                        "std", "zz"]), coefficient, max_size=8),
       st.booleans(), st.sampled_from([None, "ok", "weak", "predictive", "refused", "maybe", 3]))
def test_a_parameter_file_gives_every_coefficient_physical_or_is_refused(partial, fill, verdict):
    from lotsen.model import DEFAULT_PARAMETERS, VesselParameters, parameters_from_file

    data = {**(DEFAULT_PARAMETERS.to_dict() if fill else {}), **partial}
    if verdict is not None:
        data["verdict"] = verdict
    try:
        loaded = parameters_from_file(data, "p.json")
    except ConfigError as exc:
        assert str(exc).startswith("p.json: ")
        return
    assert data.get("verdict") in (None, "ok", "weak", "predictive")
    for f in VesselParameters.__dataclass_fields__.values():
        v = getattr(loaded.parameters, f.name)
        lo, hi = f.metadata["range"]
        assert math.isfinite(v) and lo <= v <= hi and (v == 0 or abs(v) >= sys.float_info.min)
        assert f.name in data or f.name in loaded.defaults_for


def test_a_parameter_file_names_every_missing_coefficient_and_the_way_to_take_defaults(tmp_path, capsys):
    from lotsen.cli.main import main
    from lotsen.model import DEFAULT_PARAMETERS

    d = DEFAULT_PARAMETERS.to_dict()
    for name in ("m11", "C_N", "mu_t"):
        del d[name]
    p = tmp_path / "p.json"
    import json

    p.write_text(json.dumps(d))
    assert main(["model", "check", "--params", str(p)]) == 2
    err = capsys.readouterr().err
    assert "missing coefficient(s) m11, C_N, mu_t" in err and '"defaults_for"' in err
    p.write_text(json.dumps({**d, "defaults_for": ["m11", "C_N", "mu_t"]}))
    assert main(["model", "check", "--params", str(p)]) == 0
    out = capsys.readouterr().out
    assert f"Model: {p} (defaults for m11, C_N, mu_t)" in out and "m11    =         14" in out
    assert out.count("(default)") == 3
