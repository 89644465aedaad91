import math

import numpy as np
import pytest

from lotsen.errors import DataError
from lotsen.sysid.data import IdRecord, load_csv, load_record, save_csv, split_segments, split_windows

HEADER = "t,alpha1,alpha2,n1,n2,nt,north,east,psi,r\n"


def _write(tmp_path, text, name="d.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_round_trip_with_nan(tmp_path):
    t = np.arange(10) * 0.125
    y = np.random.default_rng(0).normal(size=(10, 4))
    y[3] = np.nan
    rec = IdRecord(t, np.ones((10, 5)), y)
    save_csv(rec, tmp_path / "r.csv")
    back = load_record(tmp_path / "r.csv")
    assert np.allclose(back.t, t)
    assert np.isnan(back.outputs[3]).all()
    assert np.allclose(back.outputs[4:], y[4:])


@pytest.mark.parametrize("body", [
    # every cell a number (sample-aligned), then asynchronous rows (empty cells), CRLF, spaces, exponents
    "".join(f"{k * 0.125},0.1,-0.2,7.5,7.5,-10,{k * 0.3!r},{-k * 1e-3!r},0.5,1e-320\n" for k in range(20)),
    "".join(f"{k * 0.1},{'0.1,0.2,7,7,1,,,,' if k % 2 else ',,,,,' + repr(k / 7) + ',2.5e-3,-0,3'}\n" for k in range(20)),
    "".join(f" {k * 0.1} ,0.1,+0.2,7.,7,.5,{k / 3!r},1E2,0.1000000000000000055511151231257827021181583404541015625001,3\r\n"
            for k in range(20)),
])
def test_a_plain_body_reads_as_the_row_loop_reads_it(tmp_path, body, monkeypatch):
    """numpy's one pass over a body of numbers (data._plain_rows) and the row loop: the same arrays, bit
    for bit and in the same layout (the estimators' sums follow the strides)."""
    import lotsen.sysid.data as data

    p = _write(tmp_path, "# inputs: mean\n" + HEADER + body)
    assert data._plain_rows(body, 10, list(range(10))) is not None  # this body takes the one pass
    fast = load_csv(p)
    monkeypatch.setattr(data, "_plain_rows", lambda *_: None)
    loop = load_csv(p)
    for a, b in ((fast.t, loop.t), (fast.inputs, loop.inputs), (fast.outputs, loop.outputs)):
        assert a.strides == b.strides and np.array_equal(a.view(np.int64), b.view(np.int64))
    assert fast.input_kind == loop.input_kind == "mean"


def test_the_stamps_are_written_exactly(tmp_path):
    """Rows at one stamp are one instant (merged on reading), rows 1e-17 s apart are two (two streams'
    clocks): the CSV keeps every stamp to the last bit, so the file is the record it was written from;
    a POSIX stamp keeps its sub-second part (at 10 significant digits it kept whole seconds)."""
    t = np.array([0.0, 0.06, 0.060000000000000005, 0.1, 0.1, 1.8e9 + 0.123456789, 1.8e9 + 0.25])
    u = np.full((len(t), 5), np.nan)
    u[[0, 2, 4]] = 1.0
    y = np.full((len(t), 4), np.nan)
    y[[1, 3, 5, 6]] = 0.5
    rec = IdRecord(t, u, y, ("north", "east", "psi", "r"), input_kind="sample")
    save_csv(rec, tmp_path / "r.csv")
    back = load_csv(tmp_path / "r.csv")
    assert np.array_equal(back.t, np.unique(t))  # the two rows at 0.1 merged, nothing else


def test_optional_uv_columns(tmp_path):
    p = _write(tmp_path, "t,alpha1,alpha2,n1,n2,nt,north,east,psi,r,u,v\n0,0,0,1,1,0,0,0,0,0,0.5,0\n"
                         "0.1,0,0,1,1,0,0.05,0,0,0,0.5,0\n")
    rec = load_csv(p)
    assert rec.output_names == ("north", "east", "psi", "r", "u", "v")


@pytest.mark.parametrize("body, row, what", [
    ("0,0,0,0,0,0,0,0,0,0\n0.1,0,0,abc,0,0,0,0,0,0\n", 3, "n1"),
    ("0,0,0,0,0,0,0,0,0,0\n0,0,0,0,0,0,1,0,0,0\n", 3, "differs"),  # same stamp, conflicting value
    ("0.2,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0,0,0\n", 3, "before"),
    ("0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0,inf,0\n", 3, "infinite"),
    ("0,0,0,0,0,0,0,0,0,0\n0.1,0,0,0,0,0,0,0\n", 3, "fields"),
    ("0,0,0,0,0,0,0,0,0,0\n,0,0,0,0,0,0,0,0,0\n", 3, "time"),
])
def test_malformed_rows_name_file_and_row(tmp_path, body, row, what):
    p = _write(tmp_path, HEADER + body)
    with pytest.raises(DataError) as e:
        load_csv(p)
    msg = str(e.value)
    assert str(p) in msg and f"row {row}" in msg and what in msg


def test_missing_column_and_unknown_suffix(tmp_path):
    with pytest.raises(DataError, match="missing column.*psi"):
        load_csv(_write(tmp_path, "t,alpha1,alpha2,n1,n2,nt,north,east,r\n0,0,0,0,0,0,0,0,0\n"))
    with pytest.raises(DataError, match="unsupported"):
        load_record(tmp_path / "x.bag")


def test_gaps_split_segments_and_inputs_are_held():
    t = np.concatenate([np.arange(20) * 0.1, 5.0 + np.arange(20) * 0.1])
    u = np.ones((40, 5))
    u[5, 2] = np.nan  # held from the previous row
    u[19, :] = 2.0
    u[20, :] = np.nan  # first row after the gap: the inputs stamped before the gap still hold
    y = np.zeros((40, 4))
    segs = split_segments(IdRecord(t, u, y), gap_s=1.0)
    assert len(segs) == 2
    assert segs[0].inputs[5, 2] == 1.0
    assert np.all(segs[1].inputs[0] == 2.0) and segs[1].first_row == 20
    wins = split_windows(segs, 0.5)
    assert all(w.duration_s <= 0.5 + 1e-9 for w in wins)
    assert sum(len(w.t) for w in wins) == 40
    assert not math.isnan(wins[0].inputs.sum())


def test_asynchronous_rows_merge_hold_and_start_where_every_input_is_known(tmp_path):
    # inputs and outputs on their own stamps; nt first given at 0.2 s; two cells at one stamp merge
    body = ("0.0,0.1,0.1,10,10,,,,,\n"
            "0.05,,,,,,1.0,2.0,0.5,0.01\n"
            "0.2,,,,,5,,,,\n"
            "0.2,,,20,,,,,,\n"
            "0.25,,,,,,1.1,2.1,0.5,0.01\n")
    body += "".join(f"{0.25 + 0.125 * k:.3f},,,,,,{1.1 + 0.01 * k},2.1,0.5,0.01\n" for k in range(1, 12))
    rec = load_csv(_write(tmp_path, HEADER + body))
    assert len(rec.t) == 15 and np.isnan(rec.outputs[0]).all() and np.isnan(rec.inputs[1]).all()
    assert rec.inputs[2, 2] == 20.0 and rec.inputs[2, 4] == 5.0 and np.isnan(rec.inputs[2, 3])
    segs = split_segments(rec, gap_s=1.0)
    assert len(segs) == 1
    s = segs[0]
    assert s.t[0] == 0.25  # the measurement at 0.05 s comes before nt has a value: not usable
    assert s.inputs[0].tolist() == [0.1, 0.1, 20.0, 10.0, 5.0]  # each column held from its own stamp
    assert np.all(np.isfinite(s.inputs))
