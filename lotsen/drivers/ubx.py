"""u-blox byte streams: framing of mixed UBX / NMEA / RTCM3 input, NAV-PVT to `GnssFix`, and
the receiver configuration (UBX-CFG-VALSET).

Framing is an incremental state machine fed with whatever bytes the port returned (a serial
read, a replayed file chunk): it never raises, counts what it throws away, and finds valid
frames embedded in garbage (after a bad checksum it resynchronises one byte after the false
sync, so a frame that began inside the bad one is still found). Decoding of UBX payloads is
done by pyubx2, the reference implementation of the u-blox interface description.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from typing import Iterator

from lotsen.messages import GnssFix, GnssFixType

UBX_SYNC = b"\xb5\x62"
RTCM_PREAMBLE = 0xD3
MAX_UBX_PAYLOAD = 8192  # longer "lengths" are garbage (the largest F9P message is ~2 kB)
MAX_NMEA = 120  # NMEA 0183 4.x allows 82 characters; some u-blox PUBX lines are longer


def ubx_checksum(data: bytes) -> bytes:
    """8-bit Fletcher checksum over class, id, length and payload (u-blox interface description)."""
    a = b = 0
    for byte in data:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return bytes((a, b))


def crc24q(data: bytes) -> int:
    """CRC-24Q of RTCM3 (pyrtcm's implementation)."""
    from pyrtcm.rtcmhelpers import calc_crc24q

    return calc_crc24q(data)


def nmea_checksum_ok(line: bytes) -> bool:
    """`$...*HH` with HH the XOR of the characters between '$' and '*'."""
    star = line.rfind(b"*")
    if not line.startswith(b"$") or star < 0 or len(line) < star + 3:
        return False
    x = 0
    for ch in line[1:star]:
        x ^= ch
    try:
        return int(line[star + 1:star + 3], 16) == x
    except ValueError:
        return False


@dataclass
class FramerCounters:
    ubx_frames: int = 0
    nmea_sentences: int = 0
    rtcm_frames: int = 0
    garbage_bytes: int = 0
    bad_checksums: int = 0
    bytes_in: int = 0


@dataclass
class Frame:
    kind: str  # "ubx", "nmea", "rtcm"
    data: bytes  # the whole frame, sync to checksum


class StreamFramer:
    """Split a byte stream into UBX, NMEA and RTCM3 frames. `feed(chunk)` returns complete frames."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.counters = FramerCounters()

    def feed(self, chunk: bytes) -> list[Frame]:
        self.counters.bytes_in += len(chunk)
        self._buf += chunk
        out: list[Frame] = []
        buf = self._buf
        i = 0
        n = len(buf)
        while i < n:
            b0 = buf[i]
            if b0 == 0xB5:
                if i + 1 >= n:
                    break
                if buf[i + 1] != 0x62:
                    i = self._skip(i)
                    continue
                if i + 6 > n:
                    break
                length = buf[i + 4] | (buf[i + 5] << 8)
                if length > MAX_UBX_PAYLOAD:
                    i = self._skip(i)
                    continue
                end = i + 6 + length + 2
                if end > n:
                    if self._complete_frame_after(i + 1, n):
                        i = self._skip(i)  # a false sync with a long "length" must not hold up real frames
                        continue
                    break
                frame = bytes(buf[i:end])
                if ubx_checksum(frame[2:-2]) != frame[-2:]:
                    self.counters.bad_checksums += 1
                    i = self._skip(i)
                    continue
                self.counters.ubx_frames += 1
                out.append(Frame("ubx", frame))
                i = end
            elif b0 == RTCM_PREAMBLE:
                if i + 3 > n:
                    break
                if buf[i + 1] & 0xFC:  # 6 reserved bits must be zero
                    i = self._skip(i)
                    continue
                length = ((buf[i + 1] & 0x03) << 8) | buf[i + 2]
                end = i + 3 + length + 3
                if end > n:
                    if self._complete_frame_after(i + 1, n):
                        i = self._skip(i)
                        continue
                    break
                frame = bytes(buf[i:end])
                if crc24q(frame) != 0:  # CRC over the frame including its CRC is zero
                    self.counters.bad_checksums += 1
                    i = self._skip(i)
                    continue
                self.counters.rtcm_frames += 1
                out.append(Frame("rtcm", frame))
                i = end
            elif b0 == 0x24:  # '$'
                lf = buf.find(b"\n", i, i + MAX_NMEA)
                if lf < 0:
                    if n - i >= MAX_NMEA:
                        i = self._skip(i)
                        continue
                    break
                line = bytes(buf[i:lf + 1]).rstrip(b"\r\n")
                if nmea_checksum_ok(line):
                    self.counters.nmea_sentences += 1
                    out.append(Frame("nmea", line))
                    i = lf + 1
                else:
                    self.counters.bad_checksums += 1
                    i = self._skip(i)
            else:
                i = self._skip(i)
        del buf[:i]
        return out

    def _complete_frame_after(self, start: int, n: int) -> bool:
        """Is there a complete, checksum-valid UBX or RTCM3 frame in buf[start:n]? (bytes.find
        does the scanning, so waiting on a long candidate costs little.)"""
        buf = self._buf
        j = start
        while True:
            j = buf.find(b"\xb5\x62", j, n)
            if j < 0 or j + 8 > n:
                break
            end = j + 8 + (buf[j + 4] | (buf[j + 5] << 8))
            if end <= n and ubx_checksum(bytes(buf[j + 2:end - 2])) == bytes(buf[end - 2:end]):
                return True
            j += 1
        j = start
        while True:
            j = buf.find(b"\xd3", j, n)
            if j < 0 or j + 6 > n:
                return False
            end = j + 6 + (((buf[j + 1] & 0x03) << 8) | buf[j + 2])
            if not buf[j + 1] & 0xFC and end <= n and crc24q(bytes(buf[j:end])) == 0:
                return True
            j += 1

    def _skip(self, i: int) -> int:
        self.counters.garbage_bytes += 1
        return i + 1

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buf)


# -- NAV-PVT ----------------------------------------------------------------------------------

# NAV-PVT flags3.lastCorrectionAge code -> upper bound of the age interval in seconds
_CORRECTION_AGE_S = (math.nan, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, math.inf)


@dataclass(frozen=True)
class NavPvt:
    """The fields of UBX-NAV-PVT that the boat uses, in SI units."""

    itow_ms: int
    utc: datetime | None  # None unless validDate and validTime
    fix: GnssFix

    @property
    def itow_s(self) -> float:
        return self.itow_ms / 1000.0


def fix_type_of(fix_type: int, carr_soln: int, gnss_fix_ok: int) -> GnssFixType:
    """u-blox fixType (0 none, 1 DR, 2 2D, 3 3D, 4 GNSS+DR, 5 time only) and carrSoln (0 none,
    1 RTK float, 2 RTK fixed) folded into one `GnssFixType`. A fix without gnssFixOk is NO_FIX."""
    if fix_type in (3, 4) and gnss_fix_ok:
        if carr_soln == 2:
            return GnssFixType.RTK_FIXED
        if carr_soln == 1:
            return GnssFixType.RTK_FLOAT
        return GnssFixType.FIX_3D
    if fix_type == 2 and gnss_fix_ok:
        return GnssFixType.FIX_2D
    if fix_type == 1:
        return GnssFixType.DEAD_RECKONING
    return GnssFixType.NO_FIX


def decode_nav_pvt(frame: bytes, stamp_s: float = math.nan) -> NavPvt | None:
    """A NAV-PVT frame (sync to checksum) -> NavPvt; None for any other or undecodable frame."""
    if len(frame) < 8 or frame[2] != 0x01 or frame[3] != 0x07:
        return None
    from pyubx2 import UBXReader

    try:
        msg = UBXReader.parse(frame)
    except Exception:  # noqa: BLE001 - pyubx2 raises several types on bad payloads; caller counts
        return None
    if getattr(msg, "identity", "") != "NAV-PVT" or not hasattr(msg, "fixType"):
        return None
    ft = fix_type_of(msg.fixType, msg.carrSoln, msg.gnssFixOk)
    usable = ft >= GnssFixType.FIX_2D and not getattr(msg, "invalidLlh", 0)
    nan = math.nan
    age_code = int(getattr(msg, "lastCorrectionAge", 0) or 0)
    fix = GnssFix(
        stamp_s=stamp_s,
        lat_deg=float(msg.lat) if usable else nan,  # pyubx2 applies the 1e-7 deg scale
        lon_deg=float(msg.lon) if usable else nan,
        height_m=msg.height / 1000.0 if usable else nan,  # ellipsoidal height (mm)
        fix_type=ft,
        h_acc_m=msg.hAcc / 1000.0 if usable else math.inf,
        v_acc_m=msg.vAcc / 1000.0 if usable else math.inf,
        vel_n_mps=msg.velN / 1000.0 if usable else nan,
        vel_e_mps=msg.velE / 1000.0 if usable else nan,
        num_sv=int(msg.numSV),
        correction_age_s=_CORRECTION_AGE_S[age_code] if 0 <= age_code < len(_CORRECTION_AGE_S) else nan,
    )
    utc = None
    if msg.validDate and msg.validTime:
        try:
            utc = datetime(msg.year, msg.month, msg.day, msg.hour, msg.min, min(msg.second, 59),
                           tzinfo=timezone.utc) + timedelta(microseconds=int(msg.nano) // 1000)  # nano is signed
        except (ValueError, OverflowError):
            utc = None
    return NavPvt(itow_ms=int(msg.iTOW), utc=utc, fix=fix)


def _deg7(deg: float) -> float:
    """Degrees such that pyubx2's truncating int(deg / 1e-7) gives the *rounded* 1e-7 count."""
    k = round(float(deg) * 1e7)
    return (k + math.copysign(0.5, k if k else 1.0)) / 1e7


def encode_nav_pvt(fix: GnssFix, itow_ms: int, utc: datetime | None = None) -> bytes:
    """A NAV-PVT frame for `fix` (emulated receiver, test fixtures). Inverse of decode_nav_pvt."""
    from pyubx2 import GET, UBXMessage

    ft = fix.fix_type
    fix_type = {GnssFixType.NO_FIX: 0, GnssFixType.DEAD_RECKONING: 1, GnssFixType.FIX_2D: 2}.get(ft, 3)
    carr = {GnssFixType.RTK_FLOAT: 1, GnssFixType.RTK_FIXED: 2}.get(ft, 0)
    ok = ft >= GnssFixType.FIX_2D

    def mm(v: float, default: int = 0) -> int:
        return int(round(v * 1000.0)) if math.isfinite(v) else default

    age = fix.correction_age_s
    age_code = 0  # not available
    if age >= 0:  # NaN compares False
        age_code = next((k for k in range(1, 12) if age < _CORRECTION_AGE_S[k]), 12)
    kw = dict(iTOW=itow_ms % 604_800_000, fixType=fix_type, gnssFixOk=int(ok), diffSoln=int(carr > 0),
              carrSoln=carr, numSV=fix.num_sv,
              lat=_deg7(fix.lat_deg) if ok else 0.0, lon=_deg7(fix.lon_deg) if ok else 0.0,
              height=mm(fix.height_m), hMSL=mm(fix.height_m), hAcc=min(mm(fix.h_acc_m, 0xFFFFFFFF), 0xFFFFFFFF),
              vAcc=min(mm(fix.v_acc_m, 0xFFFFFFFF), 0xFFFFFFFF), velN=mm(fix.vel_n_mps), velE=mm(fix.vel_e_mps),
              velD=0, gSpeed=int(round(1000 * math.hypot(fix.vel_n_mps, fix.vel_e_mps)))
              if math.isfinite(fix.vel_n_mps) and math.isfinite(fix.vel_e_mps) else 0,
              sAcc=50, pDOP=1.2, lastCorrectionAge=age_code)
    if utc is not None:
        kw.update(year=utc.year, month=utc.month, day=utc.day, hour=utc.hour, min=utc.minute,
                  second=utc.second, nano=utc.microsecond * 1000, validDate=1, validTime=1, fullyResolved=1)
    return UBXMessage("NAV", "NAV-PVT", GET, **kw).serialize()


# -- configuration ----------------------------------------------------------------------------

def configuration_items(rate_hz: float = 8.0, nmea_off: bool = True, output: str = "UART1") -> list[tuple[str, int]]:
    """CFG-VALSET key/values: navigation rate, NAV-PVT on `output` (UART1 as in the seed, or
    USB), RTCM3 in on UART2 (seed sec. 1)."""
    out = {"UART1": "UART1", "USB": "USB"}[output.upper()]
    items = [
        ("CFG_RATE_MEAS", int(round(1000.0 / rate_hz))),  # ms between measurements: 125 -> 8 Hz
        ("CFG_RATE_NAV", 1),  # one navigation solution per measurement
        (f"CFG_{out}OUTPROT_UBX", 1),
        (f"CFG_MSGOUT_UBX_NAV_PVT_{out}", 1),  # every navigation epoch
        ("CFG_UART2INPROT_RTCM3X", 1),  # corrections in on UART2
    ]
    if nmea_off:
        items.append((f"CFG_{out}OUTPROT_NMEA", 0))
    return items


def valset_message(rate_hz: float = 8.0, nmea_off: bool = True, output: str = "UART1") -> bytes:
    """UBX-CFG-VALSET to RAM and battery-backed RAM (not flash: a config file stays the truth)."""
    from pyubx2 import SET_LAYER_BBR, SET_LAYER_RAM, TXN_NONE, UBXMessage

    return UBXMessage.config_set(SET_LAYER_RAM | SET_LAYER_BBR, TXN_NONE,
                                 configuration_items(rate_hz, nmea_off, output)).serialize()


def ack_of(frame: bytes) -> tuple[str, int, int] | None:
    """("ACK"|"NAK", clsID, msgID) for a UBX-ACK frame, else None."""
    if len(frame) == 10 and frame[2] == 0x05 and frame[3] in (0x00, 0x01):
        return ("ACK" if frame[3] == 0x01 else "NAK", frame[6], frame[7])
    return None


def ubx_frame(cls_id: int, msg_id: int, payload: bytes) -> bytes:
    body = bytes((cls_id, msg_id)) + len(payload).to_bytes(2, "little") + payload
    return UBX_SYNC + body + ubx_checksum(body)


# -- replay -----------------------------------------------------------------------------------

@dataclass
class ReplayResult:
    fixes: list[NavPvt] = field(default_factory=list)
    counters: FramerCounters = field(default_factory=FramerCounters)
    undecodable: int = 0


def replay_stream(chunks: Iterator[bytes]) -> ReplayResult:
    """All NAV-PVT solutions of a recorded byte stream (any mix of UBX, NMEA, RTCM, garbage)."""
    framer = StreamFramer()
    result = ReplayResult(counters=framer.counters)
    for chunk in chunks:
        for frame in framer.feed(chunk):
            if frame.kind == "ubx" and frame.data[2:4] == b"\x01\x07":
                pvt = decode_nav_pvt(frame.data)
                if pvt is None:
                    result.undecodable += 1
                else:
                    result.fixes.append(pvt)
    return result
