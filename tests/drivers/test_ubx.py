import math
from pathlib import Path

from hypothesis import given, settings, strategies as st
from pyubx2 import SET, UBXReader

from lotsen.cli.main import main
from lotsen.drivers.ubx import (
    StreamFramer, decode_nav_pvt, encode_nav_pvt, fix_type_of, replay_stream, valset_message,
)
from lotsen.messages import GnssFix, GnssFixType

from .capture import EXPECTED, make_capture, nav_pvt, rtcm_frame

DATA = Path(__file__).with_name("data") / "capture.ubx"


def test_stored_capture_is_the_generated_one():
    assert DATA.read_bytes() == make_capture()


def test_framer_finds_every_frame_in_a_mixed_stream_fed_in_any_chunking():
    data = make_capture()
    for size in (1, 3, 64, len(data)):
        framer = StreamFramer()
        frames = [f for i in range(0, len(data), size) for f in framer.feed(data[i:i + size])]
        kinds = [f.kind for f in frames]
        assert kinds.count("nmea") == 5 and kinds.count("rtcm") == 5
        assert kinds.count("ubx") == 6  # 5 NAV-PVT + 1 ACK; the corrupted NAV-PVT is dropped
        assert framer.counters.bad_checksums >= 1 and framer.counters.garbage_bytes > 0


def test_nav_pvt_decode_folds_carrier_solution_into_the_fix_type():
    result = replay_stream(iter([make_capture()]))
    assert [p.itow_ms for p in result.fixes] == [r[0] for r in EXPECTED]
    types = [p.fix.fix_type for p in result.fixes]
    assert types == [GnssFixType.FIX_3D, GnssFixType.RTK_FLOAT, GnssFixType.RTK_FIXED, GnssFixType.RTK_FIXED,
                     GnssFixType.NO_FIX]
    f = result.fixes[2].fix
    assert abs(f.lat_deg - 57.690502) < 1e-9 and abs(f.lon_deg - 11.976004) < 1e-9
    assert f.height_m == 10.02 and f.h_acc_m == 0.014 and f.vel_n_mps == 0.12 and f.vel_e_mps == -0.03
    assert math.isnan(result.fixes[4].fix.lat_deg) and not result.fixes[4].fix.usable
    assert fix_type_of(3, 2, 0) == GnssFixType.NO_FIX  # no gnssFixOk: not a fix


def test_encode_decode_round_trip():
    fix = GnssFix(stamp_s=0.0, lat_deg=57.6905123, lon_deg=11.9760456, height_m=12.345,
                  fix_type=GnssFixType.RTK_FLOAT, h_acc_m=0.15, v_acc_m=0.3, vel_n_mps=0.5, vel_e_mps=-0.25,
                  num_sv=19, correction_age_s=3.0)
    pvt = decode_nav_pvt(encode_nav_pvt(fix, 123_456))
    g = pvt.fix
    assert pvt.itow_ms == 123_456 and g.fix_type == fix.fix_type and g.num_sv == 19
    assert abs(g.lat_deg - fix.lat_deg) < 1e-7 and abs(g.lon_deg - fix.lon_deg) < 1e-7
    assert (g.height_m, g.h_acc_m, g.v_acc_m, g.vel_n_mps, g.vel_e_mps) == (12.345, 0.15, 0.3, 0.5, -0.25)
    assert g.correction_age_s == 5.0  # the receiver reports intervals: 2-5 s -> 5


def test_valset_sets_8hz_navpvt_on_uart1_rtcm_on_uart2():
    msg = UBXReader.parse(valset_message(8.0), msgmode=SET)
    assert msg.identity == "CFG-VALSET" and msg.ram == 1 and msg.bbr == 1
    assert msg.CFG_RATE_MEAS == 125 and msg.CFG_MSGOUT_UBX_NAV_PVT_UART1 == 1
    assert msg.CFG_UART2INPROT_RTCM3X == 1 and msg.CFG_UART1OUTPROT_NMEA == 0
    usb = UBXReader.parse(valset_message(8.0, output="USB"), msgmode=SET)
    assert usb.CFG_MSGOUT_UBX_NAV_PVT_USB == 1 and usb.CFG_USBOUTPROT_NMEA == 0


def test_gnss_replay_cli_prints_csv(tmp_path, capsys):
    assert main(["gnss-replay", str(DATA)]) == 0
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert lines[0] == "t,lat,lon,height,fix_type,h_acc"
    assert lines[3] == "379200.250,57.690502000,11.976004000,10.020,RTK_FIXED,0.014"
    assert lines[5] == "379200.500,,,,NO_FIX,"
    assert "1 bad checksums" in err
    assert main(["gnss-replay", str(DATA), "--time", "utc", "--out", str(tmp_path / "f.csv")]) == 0
    assert (tmp_path / "f.csv").read_text().splitlines()[2].startswith("1780305600.125,")


def test_gnss_replay_missing_file_is_an_error_message(capsys):
    assert main(["gnss-replay", "/nonexistent.ubx"]) == 2
    assert capsys.readouterr().err.startswith("error: /nonexistent.ubx: no such capture file")


# -- fuzzing ------------------------------------------------------------------------------------

VALID = [nav_pvt(*EXPECTED[2]), rtcm_frame(b"\x3e\xd0" + bytes(5))]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.binary(max_size=60) | st.sampled_from(VALID), max_size=12), st.integers(1, 50))
def test_framer_never_raises_and_finds_frames_separated_from_garbage(parts, chunk):
    framer = StreamFramer()
    data = b"".join(parts)
    frames = [f for i in range(0, len(data), chunk) for f in framer.feed(data[i:i + chunk])]
    # every emitted frame is well formed
    for f in frames:
        assert f.kind in ("ubx", "rtcm", "nmea")
    # a valid frame that follows a separator nothing can continue from is found
    tail = b"".join(parts) + b"\x00" * 2000 + VALID[0]
    framer2 = StreamFramer()
    found = framer2.feed(tail)
    assert any(f.data == VALID[0] for f in found)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=120))
def test_nav_pvt_decoder_never_raises(payload):
    """Any bytes: the decoder returns None or a fix (never raises); a fix only from a whole NAV-PVT
    frame of the right length, never from bare bytes."""
    from lotsen.drivers.ubx import ubx_frame

    assert decode_nav_pvt(payload) is None  # not a frame at all
    pvt = decode_nav_pvt(ubx_frame(0x01, 0x07, payload))
    if len(payload) != 92:  # NAV-PVT's payload is 92 bytes: anything else is refused
        assert pvt is None
    if pvt is not None:
        assert isinstance(pvt.fix.fix_type, GnssFixType)


@settings(max_examples=100, deadline=None)
@given(st.binary(min_size=1, max_size=300), st.integers(0, 299))
def test_corrupting_one_byte_never_yields_a_wrong_fix(noise, pos):
    good = VALID[0]
    bad = bytearray(good)
    bad[pos % len(good)] ^= (noise[0] or 1)
    result = replay_stream(iter([bytes(bad)]))
    for p in result.fixes:  # either dropped or (if the flip hit nothing decoded) identical
        assert p.fix.fix_type == GnssFixType.RTK_FIXED and abs(p.fix.lat_deg - 57.690502) < 1e-6


def test_a_false_sync_with_a_long_length_does_not_hold_up_real_frames():
    framer = StreamFramer()
    false_sync = b"\xb5\x62\x01\x07\x00\x20"  # claims 8 kB of payload
    found = framer.feed(false_sync + VALID[0] + VALID[1])
    assert [f.data for f in found] == [VALID[0], VALID[1]]
    assert framer.pending == 0


# -- physically impossible fixes (issue 14 point 8) ---------------------------------------------

GOOD = EXPECTED[2]  # RTK_FIXED, 14 mm
IMPOSSIBLE = {  # (lat, lon, height mm, fixType, carrSoln, hAcc mm) -> what the refusal names
    "issue": ((91.0, 200.0, 10_000, 3, 2, 0), "latitude 91.0000000 deg"),
    "longitude": ((57.69, 200.0, 10_000, 3, 0, 1500), "longitude 200.0000000 deg"),
    "zero accuracy": ((57.69, 11.97, 10_000, 3, 2, 0), "horizontal accuracy 0 mm"),
    "rtk fixed at metres": ((57.69, 11.97, 10_000, 3, 2, 5_000), "RTK_FIXED with horizontal accuracy 5.000 m"),
    "in orbit": ((57.69, 11.97, 400_000_000, 3, 0, 1500), "height 400000.000 m"),
}


def test_gnss_replay_refuses_physically_impossible_fixes_naming_the_value(tmp_path, capsys):
    for name, (row, expected) in IMPOSSIBLE.items():
        capture = tmp_path / f"{name}.ubx"
        capture.write_bytes(nav_pvt(379_000_000, *row) + nav_pvt(*GOOD))
        assert main(["gnss-replay", str(capture)]) == 0, name
        out, err = capsys.readouterr()
        lines = out.strip().splitlines()
        assert lines[1:] == ["379200.250,57.690502000,11.976004000,10.020,RTK_FIXED,0.014"], name  # only the good one
        assert "1 refused as physically impossible" in err, name
        assert f"refused NAV-PVT at iTOW 379000.000 s: " in err and expected in err, (name, err)


def test_the_driver_drops_an_impossible_fix_and_counts_it():
    from lotsen.drivers.config import GnssSection
    from lotsen.drivers.gnss import GnssReceiver

    rx = GnssReceiver(GnssSection(configure=False))
    fixes = rx.feed(nav_pvt(379_000_000, *IMPOSSIBLE["issue"][0]) + nav_pvt(*GOOD), now=1.0)
    assert [f.fix_type for f in fixes] == [GnssFixType.RTK_FIXED] and abs(fixes[0].lat_deg - 57.690502) < 1e-9
    assert rx.refused == 1 and "latitude 91" in rx.last_refusal and "iTOW 379000.000" in rx.last_refusal


@settings(max_examples=150, deadline=None)  # |lon| < 214.7 deg: an I4 of 1e-7 deg
@given(st.floats(-95, 95), st.floats(-214, 214), st.integers(-2_000_000, 20_000_000), st.integers(0, 5),
       st.integers(0, 2), st.integers(0, 2_000_000), st.integers(-30_000, 30_000), st.integers(0, 40))
def test_every_published_fix_is_physically_possible(lat, lon, height_mm, fix_type, carr, h_acc_mm, vel_mm, num_sv):
    """Whatever a checksum-valid NAV-PVT claims, a fix that gets through is on the Earth, at a
    sane height and speed, with a positive accuracy; the rest is refused with a reason."""
    from pyubx2 import GET, UBXMessage

    frame = UBXMessage("NAV", "NAV-PVT", GET, iTOW=1000, fixType=fix_type, gnssFixOk=int(fix_type >= 2),
                       carrSoln=carr, numSV=num_sv, lat=lat, lon=lon, height=height_mm, hMSL=height_mm,
                       hAcc=h_acc_mm, vAcc=h_acc_mm, velN=vel_mm * 5, velE=vel_mm, gSpeed=0).serialize()
    result = replay_stream(iter([frame]))
    assert len(result.fixes) + len(result.refused) + result.undecodable == 1
    for pvt, why in result.refused:
        assert why and pvt.fix.fix_type >= GnssFixType.FIX_2D
    for pvt in result.fixes:
        f = pvt.fix
        if f.fix_type < GnssFixType.FIX_2D:
            continue  # no position claimed
        assert -90 <= f.lat_deg <= 90 and -180 <= f.lon_deg <= 180 and f.h_acc_m > 0 and f.num_sv > 0
        assert math.hypot(f.vel_n_mps, f.vel_e_mps) <= 100.0
        if f.fix_type >= GnssFixType.FIX_3D:
            assert -1000 <= f.height_m <= 10_000 and f.v_acc_m > 0
        if f.fix_type == GnssFixType.RTK_FIXED:
            assert f.h_acc_m <= 1.0


NMEA_TXT = b"$GNTXT,01*00\r\n"  # the checksum is computed below
_x = 0
for _ch in NMEA_TXT[1:-5]:
    _x ^= _ch
NMEA_TXT = NMEA_TXT[:-4] + f"{_x:02X}".encode() + b"\r\n"
false_ubx = st.tuples(st.binary(min_size=2, max_size=2), st.integers(0, 400), st.binary(max_size=20)).map(
    lambda t: b"\xb5\x62" + t[0] + t[1].to_bytes(2, "little") + t[2])
false_rtcm = st.tuples(st.integers(0, 3), st.binary(max_size=20)).map(lambda t: bytes((0xD3, t[0])) + t[1])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.sampled_from(VALID + [NMEA_TXT]) | false_ubx | false_rtcm | st.binary(max_size=60)
                | st.binary(max_size=20).map(lambda b: b"$" + b), max_size=12),
       st.sampled_from([1, 2, 3, 7, 64]))
def test_frames_and_counts_do_not_depend_on_how_the_stream_is_read(parts, size):
    """Byte-by-byte reads take the framer's fast paths; they must find exactly what one read of
    the whole stream finds (trailing zeros: nothing may stay held back)."""
    data = b"".join(parts) + bytes(9000)
    whole = StreamFramer()
    expected = [f.data for f in whole.feed(data)]
    framer = StreamFramer()
    got = [f.data for i in range(0, len(data), size) for f in framer.feed(data[i:i + size])]
    assert got == expected and framer.pending == whole.pending == 0
    a, b = framer.counters, whole.counters  # bad_checksums may differ: a false sync given up before
    assert (a.garbage_bytes, a.bytes_in, a.ubx_frames) == (b.garbage_bytes, b.bytes_in, b.ubx_frames)  # its bytes came
    assert sum(p in VALID + [NMEA_TXT] for p in parts) <= len(expected)
