import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from lotsen.errors import DataError, LotsenError
from lotsen.logs import CorruptLogError, LogReader, McapRecorder, RecorderConfig, TruncatedLogError
from lotsen.logs.export import export_topics, sysid_record
from lotsen.stack.logs import add_recorder
from lotsen.logs.replay import ReplayNode
from lotsen.messages import GnssFix, GnssFixType, ImuSample, LogEvent, OperatorCommand, PathMessage, Topic, VesselState
from lotsen.runtime import Bus, SimExecutor
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.launch import build_stack

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def sim_log(tmp_path_factory):
    """A 6 s simulated run recorded with the part, plus what was published on the bus."""
    d = tmp_path_factory.mktemp("logs")
    stack = build_stack(LaunchConfig(), realtime=False, parts=())
    published = []
    stack.bus.subscribe_all(lambda t, m: published.append((t, m)))
    rec = add_recorder(stack, RecorderConfig(directory=str(d), geo_origin=(57.69, 11.97, 10.0)), start=True)
    stack.executor.run_until(3.0)
    stack.bus.publish(Topic.STATE, VesselState(stamp_s=3.0, north_m=1.0, east_m=2.0, heading_rad=0.5, u_mps=0.3,
                                               v_mps=0.0, r_radps=0.0, source="test", std=(0.1,) * 6))
    stack.bus.publish(Topic.PATH, PathMessage(stamp_s=3.0, north_m=(0.0, 5.0, 10.0), east_m=(0.0, 1.0, 0.0),
                                              speed_mps=(0.5, 0.5, 0.5)))
    stack.bus.publish(Topic.LOG, LogEvent(stamp_s=3.0, level="warning", source="test", text="hello", data={"k": 1}))
    stack.executor.run_until(4.0)
    stack.bus.publish(Topic.STATE, VesselState(stamp_s=4.0, north_m=1.5, east_m=2.0, heading_rad=0.5, u_mps=0.3,
                                               v_mps=0.0, r_radps=0.0, source="test", std=(0.1,) * 6))
    stack.executor.run_until(6.0)
    path = rec.path
    for close in stack.services["on_shutdown"]:
        close()
    return path, published


def test_every_topic_round_trips_to_lotsen_types(sim_log, same):
    path, published = sim_log
    got = list(LogReader(path).messages())
    assert len(got) == len(published)
    assert all(t1 == t2 and same(m1, m2) for (t1, m1), (t2, m2) in zip(got, published))
    gnss = [m for t, m in got if t == Topic.GNSS]
    assert gnss and isinstance(gnss[0].fix_type, GnssFixType)
    imu = [m for t, m in got if t == Topic.IMU_RAW]
    assert isinstance(imu[0].gyro_radps, tuple)
    assert re.fullmatch(r"\d{4}-\d\d-\d\d_\d\d-\d\d-\d\d_run001\.mcap", path.name)


def test_file_is_indexed_with_schemas_and_foxglove_views(sim_log):
    from mcap.reader import make_reader

    path, _ = sim_log
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics.message_count > 0  # indexed, with a summary
    schemas = {summary.schemas[c.schema_id].name for c in summary.channels.values()}
    by_topic = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert by_topic[Topic.GNSS] == "lotsen.GnssFix"
    assert summary.schemas[next(c.schema_id for c in summary.channels.values() if c.topic == Topic.GNSS)].encoding == "jsonschema"
    for name in ("foxglove.LocationFix", "foxglove.FrameTransform", "foxglove.PoseInFrame", "foxglove.SceneUpdate",
                 "foxglove.Log", "lotsen.RtkStatus"):
        assert name in schemas, name
    assert by_topic["foxglove/gnss_rtk"] == "lotsen.RtkStatus"
    assert by_topic["foxglove/estimate_fix"] == "foxglove.LocationFix"


def test_replay_republishes_in_order_at_speed(sim_log, same):
    path, published = sim_log
    ex = SimExecutor()
    got = []
    ex.bus.subscribe_all(lambda t, m: got.append((ex.clock.now(), t, m)) if t != Topic.LOG else None)
    node = ReplayNode(path, speed=2.0, exclude=[Topic.LOG])
    ex.add_node(node)
    ex.run_until(10.0, stop=lambda: node.finished)
    want = [(t, m) for t, m in published if t != Topic.LOG]
    assert [t for _, t, _ in got] == [t for t, _ in want]
    assert all(same(a, b) for (_, _, a), (_, b) in zip(got, want))
    assert got[-1][0] == pytest.approx(6.0 / 2.0, abs=0.02)  # recorded 6 s played at 2x


def test_replay_topic_selection_and_restamp(sim_log):
    path, _ = sim_log
    ex = SimExecutor()
    ex.clock.set(100.0)
    got = []
    ex.bus.subscribe(Topic.GNSS, got.append)
    ex.bus.subscribe(Topic.IMU_RAW, got.append)
    ex.add_node(ReplayNode(path, topics=[Topic.GNSS], restamp=True))
    ex.run_until(110.0)
    assert got and all(isinstance(m, GnssFix) for m in got)
    assert got[0].stamp_s == pytest.approx(100.0)
    assert got[1].stamp_s - got[0].stamp_s == pytest.approx(0.125, abs=0.02)


def test_export_tables_and_sysid_csv(sim_log, tmp_path):
    from lotsen.sysid.data import load_csv, save_csv

    path, published = sim_log
    files = export_topics(path, tmp_path, [Topic.IMU_RAW, Topic.GNSS])
    assert set(files) == {Topic.IMU_RAW, Topic.GNSS}
    header = files[Topic.GNSS].read_text().splitlines()[0].split(",")
    assert {"log_time_s", "lat_deg", "fix_type", "fix_type_name"} <= set(header)
    imu_rows = files[Topic.IMU_RAW].read_text().splitlines()
    assert imu_rows[0].startswith("log_time_s,stamp_s,gyro_radps_0,gyro_radps_1,gyro_radps_2")
    assert len(imu_rows) - 1 == sum(t == Topic.IMU_RAW for t, _ in published)

    # the identification record: one row per message at its own stamp (docs/sysid.md, "Data")
    achieved = any(tp == Topic.ACTUATORS for tp, _ in published)
    rec = sysid_record(path, outputs="truth")
    assert rec.output_names == ("north", "east", "psi", "r", "u", "v")
    assert rec.input_kind == ("sample" if achieved else "held")  # readings are interpolated, commands held
    in_topic = Topic.ACTUATORS if achieved else Topic.SHIP_COMMAND
    assert len(rec.t) == sum(tp in (in_topic, Topic.TRUTH) for tp, _ in published)
    save_csv(rec, tmp_path / "truth.csv")
    back = load_csv(tmp_path / "truth.csv")
    assert back.input_kind == rec.input_kind and len(back.t) == len(set(rec.t))  # equal stamps merge into one row


def test_export_parquet_says_pyarrow_is_missing(sim_log, tmp_path):
    try:
        import pyarrow  # noqa: F401
        pytest.skip("pyarrow installed")
    except ImportError:
        pass
    with pytest.raises(LotsenError, match="pyarrow"):
        export_topics(sim_log[0], tmp_path, fmt="parquet")


def test_cli_export_and_fast_replay(sim_log, tmp_path, capsys):
    from lotsen.cli.main import main

    path, _ = sim_log
    assert main(["export", str(path), "--out", str(tmp_path / "x")]) == 0
    assert (tmp_path / "x" / "sysid.csv").is_file() and (tmp_path / "x" / "imu.data_raw.csv").is_file()
    assert main(["replay", str(path), "--fast", "--record", str(tmp_path / "re"), "--topics", Topic.GNSS]) == 0
    (copy,) = list((tmp_path / "re").glob("*.mcap"))
    assert [t for t, _ in LogReader(copy).messages() if t != Topic.LOG] == [t for t, _ in LogReader(path).messages([Topic.GNSS])]
    assert main(["export", str(tmp_path / "nope.mcap"), "--info"]) == 2
    assert "no such log file" in capsys.readouterr().err


# ---------------------------------------------------------------- robustness
def _record(path: Path, n: int, **cfg) -> None:
    bus = Bus()
    rec = McapRecorder(RecorderConfig(foxglove_views=False, fsync=False, **cfg)).attach(bus)
    rec.start(path)
    for i in range(n):
        bus.publish("imu/data_raw", ImuSample(stamp_s=float(i), gyro_radps=(0.0, 0.0, 0.0), accel_mps2=(0.0, 0.0, -9.81)))
    rec.close()


def _chunk_offsets(path: Path) -> list[int]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [ci.chunk_start_offset for ci in make_reader(f).get_summary().chunk_indexes]


def test_truncated_file_reads_up_to_the_cut_and_names_the_offset(tmp_path):
    p = tmp_path / "a.mcap"
    _record(p, 5000, chunk_size=20_000, compression="none")
    data = p.read_bytes()
    offsets = _chunk_offsets(p)
    cut = offsets[len(offsets) // 2] + 100  # inside a chunk in the middle
    q = tmp_path / "cut.mcap"
    q.write_bytes(data[:cut])
    r = LogReader(q)
    stamps = [m.stamp_s for _, m in r.messages()]
    assert 0 < len(stamps) < 5000 and stamps == [float(i) for i in range(len(stamps))]
    assert len(r.problems) == 1 and isinstance(r.problems[0], TruncatedLogError)
    assert r.problems[0].offset == offsets[len(offsets) // 2] and f"offset {r.problems[0].offset}" in str(r.problems[0])
    assert isinstance(r.problems[0], DataError)
    strict = LogReader(q, strict=True)
    seen = []
    with pytest.raises(TruncatedLogError):
        for _, m in strict.messages():
            seen.append(m)
    assert len(seen) == len(stamps)


def test_corrupt_chunk_is_reported_by_offset_and_skipped(tmp_path):
    p = tmp_path / "b.mcap"
    _record(p, 5000, chunk_size=20_000)
    data = bytearray(p.read_bytes())
    offsets = _chunk_offsets(p)
    bad = offsets[2]
    data[bad + 80:bad + 120] = b"\xff" * 40  # garble compressed data of the third chunk
    p.write_bytes(bytes(data))
    r = LogReader(p)
    stamps = [m.stamp_s for _, m in r.messages()]
    assert 3000 < len(stamps) < 5000 and stamps[-1] == 4999.0  # what is readable is read, after the damage too
    assert any(isinstance(e, CorruptLogError) and e.offset == bad for e in r.problems)
    with pytest.raises(CorruptLogError, match=f"offset {bad}"):
        list(LogReader(p, strict=True).messages())


def test_not_an_mcap_file(tmp_path):
    p = tmp_path / "c.mcap"
    p.write_bytes(b"hello world, not a log")
    with pytest.raises(CorruptLogError, match="offset 0"):
        list(LogReader(p).messages())


def test_stalled_disk_drops_oldest_and_never_blocks_the_publisher(tmp_path, monkeypatch):
    from lotsen.logs import recorder as recmod

    gate = threading.Event()
    real_write = recmod._Session._write

    def stalled(self, *a):
        gate.wait(30)
        return real_write(self, *a)

    monkeypatch.setattr(recmod._Session, "_write", stalled)
    bus = Bus()
    rec = McapRecorder(RecorderConfig(queue_maxlen=100, foxglove_views=False, fsync=False)).attach(bus)
    rec.start(tmp_path / "d.mcap")
    for i in range(2000):  # would hang here if the bus waited for the disk
        bus.publish("imu/data_raw", ImuSample(stamp_s=float(i), gyro_radps=(0.0,) * 3, accel_mps2=(0.0,) * 3))
    gate.set()
    stats = rec.stop()
    # the writer may hold one batch when it stalls: the item it waited for + a whole queue (101)
    assert stats.dropped >= 2000 - (2 * 100 + 1)
    stamps = [m.stamp_s for _, m in LogReader(tmp_path / "d.mcap").messages()]
    assert stamps[-1] == 1999.0 and len(stamps) == 2000 - stats.dropped  # newest kept


def test_logging_on_off_from_the_operator(tmp_path):
    stack = build_stack(LaunchConfig(), realtime=False, parts=())
    rec = add_recorder(stack, RecorderConfig(directory=str(tmp_path), fsync=False), start=False)
    stack.executor.run_until(0.5)
    assert not rec.recording and not list(tmp_path.iterdir())
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=0.5, action="logging_on"))
    stack.executor.run_until(1.5)
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=1.5, action="logging_off"))
    stack.executor.run_until(2.5)
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=2.5, action="logging_on"))
    stack.executor.run_until(3.0)
    for close in stack.services["on_shutdown"]:
        close()
    files = sorted(tmp_path.glob("*.mcap"))
    assert [f.name[-12:] for f in files] == ["_run001.mcap", "_run002.mcap"]
    first = [m.stamp_s for t, m in LogReader(files[0]).messages() if t == Topic.TRUTH]
    second = [m.stamp_s for t, m in LogReader(files[1]).messages() if t == Topic.TRUTH]
    assert 0.5 <= first[0] and first[-1] <= 1.5 and 2.5 <= second[0]


@pytest.mark.skipif(sys.platform != "linux", reason="kill -9 semantics")
def test_killed_recorder_loses_at_most_the_last_second(tmp_path):
    rate_hz = 200.0
    p = tmp_path / "killed.mcap"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, str(Path(__file__).with_name("crash_writer.py")), str(p), str(rate_hz), "0.5"],
                            stdout=subprocess.PIPE, text=True, env=env)
    last = 0
    try:
        for line in proc.stdout:
            last = int(line)
            if last >= 3 * rate_hz:  # ~3 s of data handed to the recorder
                break
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(10)
    r = LogReader(p)
    stamps = [m.stamp_s for _, m in r.messages()]
    assert not r.complete and any(isinstance(e, TruncatedLogError) for e in r.problems)
    assert stamps == [float(i) for i in range(len(stamps))]  # no gaps, in order
    assert len(stamps) >= last - rate_hz * 1.0, (len(stamps), last)  # lost at most ~1 s


def test_the_pilot_token_never_reaches_the_log(tmp_path):
    from lotsen.runtime.config import LaunchConfig, LoggingSection, WebSection
    from lotsen.stack.launch import build_stack

    secret = "s3cret-pilot-token-xyz"
    cfg = LaunchConfig(web=WebSection(enabled=False, pilot_token=secret),
                       logging=LoggingSection(enabled=True, directory=str(tmp_path)))
    stack = build_stack(cfg, realtime=False, parts=("logs",))
    stack.executor.run_until(1.0)
    for close in stack.services["on_shutdown"]:
        close()
    files = list(tmp_path.glob("*.mcap"))
    assert files and secret.encode() not in files[0].read_bytes()
    assert b"<redacted>" in files[0].read_bytes()
