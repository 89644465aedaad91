"""Recovery of unclosed recordings (issue 14 item 7) and the recorder's config checks (item 8)."""

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lotsen.cli.main import main
from lotsen.errors import ConfigError, LotsenError
from lotsen.logs import LogReader, McapRecorder, RecorderConfig, next_log_path
from lotsen.logs.recover import needs_recovery, recover_directory, recover_mcap
from lotsen.messages import ImuSample
from lotsen.runtime import Bus
from lotsen.runtime.config import from_mapping

REPO = Path(__file__).resolve().parents[2]


def _record(path: Path, n: int, stop: bool = True, **cfg) -> McapRecorder:
    bus = Bus()
    rec = McapRecorder(RecorderConfig(foxglove_views=False, fsync=False, **cfg)).attach(bus)
    rec.start(path)
    for i in range(n):
        bus.publish("imu/data_raw", ImuSample(stamp_s=float(i), gyro_radps=(0.0, 0.0, 0.0), accel_mps2=(0.0, 0.0, -9.81)))
    if stop:
        rec.close()
    return rec


def _seek_stamps(path: Path) -> list[float]:
    """Messages through the standard seeking reader (what Foxglove does): index + summary needed."""
    from mcap.reader import make_reader

    from lotsen.transport import codec

    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        stamps = [codec.decode_json("ImuSample", m.data).stamp_s for _, _, m in reader.iter_messages()]
    assert summary.statistics.message_count == len(stamps) and bool(summary.chunk_indexes) == bool(stamps)
    return stamps


@pytest.fixture(scope="module")
def complete_log(tmp_path_factory):
    p = tmp_path_factory.mktemp("rec") / "full.mcap"
    _record(p, 3000, chunk_size=8_000)  # zstd, many chunks
    return p


# ---------------------------------------------------------------------------------- SIGKILL
@pytest.mark.skipif(sys.platform != "linux", reason="kill -9 semantics")
def test_sigkilled_recording_is_recovered_for_the_seeking_reader_with_at_most_one_second_lost(tmp_path):
    rate_hz = 200.0
    p = tmp_path / "killed.mcap"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, str(Path(__file__).with_name("crash_writer.py")), str(p), str(rate_hz), "0.5"],
                            stdout=subprocess.PIPE, text=True, env=env)
    handed = 0
    try:
        for line in proc.stdout:
            handed = int(line)
            if handed >= 2.5 * rate_hz:
                break
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(10)
    assert needs_recovery(p)
    from mcap.reader import make_reader

    with pytest.raises(Exception):  # the symptom: RecordLengthLimitExceeded
        with open(p, "rb") as f:
            list(make_reader(f).iter_messages())
    out = tmp_path / "fixed.mcap"
    stats = recover_mcap(p, out)
    stamps = _seek_stamps(out)
    assert stamps == [float(i) for i in range(len(stamps))]  # in order, no gap
    lost_s = (handed - len(stamps)) / rate_hz
    assert lost_s <= 1.0, (handed, len(stamps))
    assert stats.messages == len(stamps) and not needs_recovery(out)
    r = LogReader(out)
    list(r.messages())
    assert r.complete and "lotsen" in r.metadata and r.metadata["lotsen_recovery"]["source"] == "killed.mcap"


# ---------------------------------------------------------------------------------- cut files
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(0.0, 1.0))
def test_a_file_cut_anywhere_recovers_to_an_indexed_prefix(complete_log, tmp_path, frac):
    data = complete_log.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:max(8, int(len(data) * frac))])
    out = tmp_path / "out.mcap"
    stats = recover_mcap(cut, out, fsync=False)
    stamps = _seek_stamps(out)
    assert stamps == [float(i) for i in range(len(stamps))]
    streamed = [m.stamp_s for _, m in LogReader(cut).messages()]
    assert len(stamps) >= len(streamed)  # never less than a stream reader gets
    assert stats.messages == len(stamps) and stats.bytes_read + stats.tail_bytes_lost == len(cut.read_bytes())


@pytest.mark.parametrize("compression", ["none", "zstd"])
def test_a_chunk_cut_short_gives_its_complete_messages_and_the_time_lost(tmp_path, compression):
    from mcap.reader import make_reader

    full = tmp_path / "full.mcap"
    # zstd decodes whole blocks (128 kB): only a chunk with several blocks has some to salvage
    # flush_period_s 60: chunks closed by size, not by the time a loaded machine takes to publish
    _record(full, 6000, chunk_size=20_000 if compression == "none" else 600_000, compression=compression,
            flush_period_s=60.0)
    with open(full, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    ci = chunks[len(chunks) // 2] if compression == "none" else chunks[0]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(full.read_bytes()[:ci.chunk_start_offset + ci.chunk_length * 2 // 3])
    stats = recover_mcap(cut, tmp_path / "out.mcap", fsync=False)
    streamed = [m.stamp_s for _, m in LogReader(cut).messages()]
    assert stats.salvaged_from_partial_chunk > 0
    assert stats.messages == len(streamed) + stats.salvaged_from_partial_chunk
    assert 0.0 < stats.tail_lost_s and stats.end_ns < ci.message_end_time
    assert any("cut short" in p for p in stats.problems)


def test_damaged_chunk_is_skipped_and_the_rest_kept(complete_log, tmp_path):
    from mcap.reader import make_reader

    data = bytearray(complete_log.read_bytes())
    with open(complete_log, "rb") as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    bad = chunks[3].chunk_start_offset
    data[bad + 80:bad + 120] = b"\xff" * 40
    src = tmp_path / "damaged.mcap"
    src.write_bytes(bytes(data[:len(data) - 200]))  # and unclosed
    stats = recover_mcap(src, tmp_path / "out.mcap", fsync=False)
    stamps = _seek_stamps(tmp_path / "out.mcap")
    assert stats.damaged_chunks == 1 and stamps[-1] == 2999.0 and 2000 < len(stamps) < 3000


def test_schemas_channels_metadata_and_attachments_are_kept(tmp_path):
    from mcap.reader import make_reader
    from mcap.writer import Writer

    src = tmp_path / "foreign.mcap"
    with open(src, "wb") as f:
        w = Writer(f, chunk_size=2000)
        w.start(profile="x-test", library="hand")
        s1 = w.register_schema("a.A", "jsonschema", b'{"type": "object"}')
        s2 = w.register_schema("b.B", "protobuf", b"\x0a\x01x")
        c1 = w.register_channel("/a", "json", s1, {"qos": "reliable"})
        c2 = w.register_channel("/b", "protobuf", s2)
        c3 = w.register_channel("/raw", "cbor", 0)
        w.add_metadata("run", {"boat": "lotsen", "k": "v"})
        w.add_attachment(5, 6, "calib.json", "application/json", b'{"gain": 1}')
        for i in range(300):
            w.add_message((c1, c2, c3)[i % 3], log_time=1000 + i, data=f"{i}".encode(), publish_time=2000 + i, sequence=i)
        w.flush()
        f.flush()
        unclosed = src.read_bytes()  # what a kill leaves: no summary, no footer
        w.finish()
    full = src.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(unclosed)
    out = tmp_path / "out.mcap"
    recover_mcap(cut, out, fsync=False)

    def content(path):
        with open(path, "rb") as f:
            r = make_reader(f)
            s = r.get_summary()
            chans = sorted((c.topic, c.message_encoding, dict(c.metadata), s.schemas[c.schema_id].name if c.schema_id else "",
                            s.schemas[c.schema_id].data if c.schema_id else b"") for c in s.channels.values())
            msgs = [(ch.topic, m.log_time, m.publish_time, m.sequence, m.data) for _, ch, m in r.iter_messages()]
            meta = {m.name: m.metadata for m in r.iter_metadata() if m.name != "lotsen_recovery"}
            att = [(a.name, a.media_type, a.data, a.log_time, a.create_time) for a in r.iter_attachments()]
            return chans, msgs, meta, att, r.get_header().profile
    assert full != unclosed and content(out) == content(src)
    assert len(content(out)[1]) == 300


# ---------------------------------------------------------------------------------- directory
def test_recover_directory_recovers_unclosed_runs_and_leaves_the_rest(tmp_path, complete_log):
    d = tmp_path / "logs"
    d.mkdir()
    good = d / "2026-01-01_10-00-00_run001.mcap"
    good.write_bytes(complete_log.read_bytes())
    unclosed = d / "2026-01-01_10-05-00_run002.mcap"
    unclosed.write_bytes(complete_log.read_bytes()[:40_000])
    (d / "2026-01-01_10-06-00_run003.mcap").write_bytes(b"")
    (d / "notes.mcap").write_bytes(b"not a log at all")
    live = _record(d / "2026-01-01_10-07-00_run004.mcap", 10, stop=False)  # being written right now
    try:
        results = recover_directory(d, fsync=False)
        by_name = {Path(r.source).name: r for r in results}
        assert set(by_name) == {unclosed.name, "2026-01-01_10-06-00_run003.mcap", "notes.mcap"}
        r = by_name[unclosed.name]
        assert not r.error and Path(r.output).name == "2026-01-01_10-05-00_run002.recovered.mcap"
        assert _seek_stamps(Path(r.output))[:3] == [0.0, 1.0, 2.0]
        assert (d / (unclosed.name + ".unclosed")).read_bytes() == complete_log.read_bytes()[:40_000]
        assert not unclosed.exists() and good.exists()
        assert "not an MCAP" in by_name["notes.mcap"].error and "empty" in by_name["2026-01-01_10-06-00_run003.mcap"].error
        # the next start: nothing new to do; run numbering continues after the recovered run
        again = recover_directory(d, fsync=False)
        assert [Path(x.source).name for x in again] == ["notes.mcap"]
        assert next_log_path(d).name.endswith("_run005.mcap")
    finally:
        live.close()
    assert not needs_recovery(d / "2026-01-01_10-07-00_run004.mcap")


def test_cli_recover(tmp_path, complete_log, capsys):
    cut = tmp_path / "run.mcap"
    cut.write_bytes(complete_log.read_bytes()[:30_000])
    assert main(["recover", str(cut), "--out", str(tmp_path / "fixed.mcap")]) == 0
    assert "messages over" in capsys.readouterr().out and not needs_recovery(tmp_path / "fixed.mcap")
    assert main(["recover", str(cut)]) == 0 and (tmp_path / "run.recovered.mcap").is_file()
    assert main(["recover", str(cut)]) == 2 and "exists" in capsys.readouterr().err
    assert main(["recover", str(complete_log)]) == 0 and "nothing to recover" in capsys.readouterr().out
    assert main(["recover", str(tmp_path / "missing.mcap")]) == 2
    assert "no such log file" in capsys.readouterr().err
    d = tmp_path / "dir"
    d.mkdir()
    (d / "a_run001.mcap").write_bytes(complete_log.read_bytes()[:30_000])
    assert main(["recover", str(d)]) == 0 and (d / "a_run001.recovered.mcap").is_file()


# ---------------------------------------------------------------------------------- recorder config
@pytest.mark.parametrize("key, value", [("queue_maxlen", -5), ("queue_maxlen", 0), ("flush_period_s", 0.0),
                                        ("flush_period_s", -1.0), ("chunk_size", 0), ("compression", "gzip"),
                                        ("geo_origin", [91.0, 0.0, 0.0]), ("queue_maxlen", 10**400)])
def test_recorder_config_refuses_bad_values_naming_the_key(key, value):
    with pytest.raises(ConfigError, match=key):
        from_mapping(RecorderConfig, {key: value}, "extra.logs")


def test_recorder_config_direct_construction_is_checked_too():
    with pytest.raises(ConfigError, match="queue_maxlen"):
        RecorderConfig(queue_maxlen=0)
    assert RecorderConfig(queue_maxlen=1).queue_maxlen == 1


def test_uncreatable_log_directory_is_a_config_error_naming_it(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    for d in (blocker / "logs", blocker):
        rec = McapRecorder(RecorderConfig(directory=str(d)))
        with pytest.raises(ConfigError, match=str(d)):
            rec.start()
        assert not rec.recording


def test_uncreatable_log_directory_through_the_stack_and_cli(tmp_path, capsys):
    from lotsen.runtime.config import LaunchConfig, LoggingSection
    from lotsen.stack.launch import build_stack

    blocker = tmp_path / "a_file"
    blocker.write_text("x")
    cfg = LaunchConfig(logging=LoggingSection(enabled=True, directory=str(blocker / "logs")))
    with pytest.raises(ConfigError, match="a_file"):
        build_stack(cfg, realtime=False, parts=("logs",))
    bad = LaunchConfig(extra={"logs": {"queue_maxlen": -5}})
    with pytest.raises(ConfigError, match="extra.logs.queue_maxlen"):
        build_stack(bad, realtime=False, parts=("logs",))


@settings(max_examples=100, deadline=None)
@given(st.dictionaries(st.sampled_from(["queue_maxlen", "flush_period_s", "fsync", "compression", "chunk_size",
                                        "foxglove_views", "topics", "geo_origin", "directory", "bogus"]),
                       st.one_of(st.none(), st.booleans(), st.integers(-10**30, 10**30), st.floats(),
                                 st.text(max_size=6), st.lists(st.floats(-200, 200), max_size=4)), max_size=4))
def test_recorder_config_fuzz(data):
    try:
        rc = from_mapping(RecorderConfig, data, "extra.logs")
    except LotsenError as exc:
        assert str(exc).startswith(("extra.logs", "recorder"))
        return
    assert rc.queue_maxlen >= 1 and rc.flush_period_s > 0 and rc.chunk_size >= 1024
