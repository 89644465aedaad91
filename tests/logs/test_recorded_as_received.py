"""The recorder of `lotsen run` writes what it receives from the core as it came (the envelope's
JSON payload), without decoding and re-encoding it: the file must be the one the decoded
messages would have made, and read back to what was published."""

import itertools
import math

import pytest

from lotsen import messages as M
from lotsen.logs import LogReader, McapRecorder, RecorderConfig
from lotsen.messages import Topic
from lotsen.transport import codec

PUBLISHED = [
    (Topic.IMU_RAW, M.ImuSample(stamp_s=1.25, gyro_radps=(0.1, -0.2, 0.3), accel_mps2=(0.05, 0.5, -9.81))),
    (Topic.GNSS, M.GnssFix(stamp_s=1.3, lat_deg=57.6905, lon_deg=11.976, height_m=10.0,
                           fix_type=M.GnssFixType.RTK_FLOAT, h_acc_m=0.05, v_acc_m=0.1, num_sv=17)),
    (Topic.GNSS, M.GnssFix(stamp_s=1.4, lat_deg=57.6905, lon_deg=11.976, height_m=10.0,
                           fix_type=M.GnssFixType.NO_FIX, h_acc_m=float("nan"))),
    (Topic.STATE, M.VesselState(stamp_s=1.5, north_m=1.0, east_m=-2.0, heading_rad=7.0, u_mps=1.2, v_mps=0.1,
                                r_radps=-0.2, source="ekf", std=(0.1, 0.2, 0.03, 0.04, 0.05, 0.006))),
    (Topic.TRUTH, M.VesselState(stamp_s=1.5, north_m=1.1, east_m=-2.0, heading_rad=0.3, u_mps=1.2, v_mps=0.1,
                                r_radps=-0.2, source="truth")),
    (Topic.SHIP_COMMAND, M.ThrustCommand(stamp_s=float("nan"), alpha1_rad=0.1, n1_rps=30.0, nt_rps=float("inf"))),
    (Topic.RC, M.RcOverride(stamp_s=float("inf"), active=True, command=M.ThrustCommand(stamp_s=1.0, n2_rps=-3.0))),
    (Topic.RTCM, M.RtcmData(stamp_s=1.6, data=b"\xd3\x00\x13abc")),
    (Topic.LOG, M.LogEvent(stamp_s=1.7, level="warning", source="x", text="t", data={"a": [1, 2], "b": None})),
    (Topic.PATH, M.PathMessage(stamp_s=1.8, north_m=(0.0, 1.0), east_m=(0.0, 0.5), speed_mps=(0.5, 0.5))),
    (Topic.SUPERVISOR, M.SupervisorStatus(stamp_s=1.9, mode="auto", warnings=("gnss", "battery"))),
]


def _record(path, feed) -> list[tuple]:
    """Record PUBLISHED through `feed(recorder, topic, msg)` on a clock of fixed steps; the file's
    records as (topic, schema, encoding, log_time_ns, publish_time_ns, data)."""
    steps = itertools.count()
    rec = McapRecorder(RecorderConfig(directory=str(path.parent), fsync=False, geo_origin=(57.69, 11.97, 10.0)),
                       clock=lambda: 0.25 * next(steps), epoch_at_clock_zero=1.7e9)
    rec.start(path)
    for topic, msg in PUBLISHED:
        feed(rec, topic, msg)
    stats = rec.stop()
    assert stats is not None and stats.encode_errors == 0, stats.last_error
    return [(ch.topic, ch.schema, ch.encoding, log_ns, pub_ns, data)
            for ch, log_ns, pub_ns, data in LogReader(path).iter_raw()]


def _as_received(rec: McapRecorder, topic: str, msg) -> None:
    rec.on_envelopes([(topic, codec.parse_envelope(codec.encode(msg, "json", origin="core:1")))])


def test_received_bytes_make_the_file_the_messages_make(tmp_path):
    decoded = _record(tmp_path / "decoded.mcap", lambda rec, topic, msg: rec.on_message(topic, msg))
    received = _record(tmp_path / "received.mcap", _as_received)
    assert received == decoded  # data, both times, channels and the Foxglove views
    assert any(topic.startswith("foxglove/") for topic, *_ in received)
    mine = [r for r in received if not r[0].startswith("foxglove/")]
    assert [r[0] for r in mine] == [t for t, _ in PUBLISHED]
    for (topic, msg), (_, _, _, log_ns, pub_ns, _) in zip(PUBLISHED, mine):
        stamp_ns = 1_700_000_000_000_000_000 + round(msg.stamp_s * 1e9) if math.isfinite(msg.stamp_s) else log_ns
        assert pub_ns == stamp_ns, topic  # the message's stamp, or the receipt time when it has none


def test_recorded_as_received_reads_back_to_what_was_published(tmp_path, same):
    path = tmp_path / "received.mcap"
    _record(path, _as_received)
    got = list(LogReader(path, strict=True).messages())
    assert len(got) == len(PUBLISHED)
    assert all(t1 == t2 and same(m1, m2) for (t1, m1), (t2, m2) in zip(got, PUBLISHED))
    assert isinstance(got[1][1].fix_type, M.GnssFixType) and got[7][1].data == b"\xd3\x00\x13abc"


def test_a_cdr_envelope_is_decoded_and_recorded_as_json(tmp_path):
    imu = PUBLISHED[0][1]
    steps = itertools.count()
    rec = McapRecorder(RecorderConfig(directory=str(tmp_path), fsync=False, foxglove_views=False),
                       clock=lambda: float(next(steps)))
    path = rec.start(tmp_path / "cdr.mcap")
    rec.on_envelopes([(Topic.IMU_RAW, codec.parse_envelope(codec.encode(imu, "cdr")))])
    rec.close()
    (msg,) = [m for m in LogReader(path).read()]
    assert (msg.schema, msg.encoding) == ("lotsen.ImuSample", "json")
    assert msg.message.gyro_radps == pytest.approx(imu.gyro_radps) and msg.message.stamp_s == pytest.approx(1.25)


def test_an_unknown_type_is_counted_not_recorded(tmp_path):
    rec = McapRecorder(RecorderConfig(directory=str(tmp_path), fsync=False, foxglove_views=False))
    rec.start(tmp_path / "bad.mcap")
    good = codec.parse_envelope(codec.encode(PUBLISHED[0][1], "json"))
    rec.on_envelopes([("x", codec.Envelope(1, codec.ENC_JSON, "NoSuchMessage", "", "", b'{"stamp_s":1.0}', b""))])
    rec.on_envelopes([(Topic.IMU_RAW, good)])
    stats = rec.stop()
    assert (stats.written, stats.encode_errors) == (1, 1) and "NoSuchMessage" in stats.last_error


@pytest.mark.parametrize("payload, stamp", [
    (b'{"stamp_s":1.25,"x":2}', 1.25), (b'{"stamp_s":3}', 3.0), (b'{"stamp_s":-1e-3,"y":[1]}', -1e-3),
    (b'{"stamp_s":null,"x":1}', math.nan), (b'{"stamp_s":"inf"}', math.nan), (b'{"x":{"stamp_s":9},"stamp_s":2.5}', 2.5),
    (b'{"x":1}', math.nan), (b'[1, 2]', math.nan), (b'not json', math.nan),
])
def test_the_stamp_is_read_from_the_json_without_decoding_it(payload, stamp):
    got = codec.json_stamp_s(payload)
    assert (math.isnan(got) and math.isnan(stamp)) or got == stamp
