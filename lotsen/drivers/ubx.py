"""u-blox byte streams: framing of mixed UBX / NMEA / RTCM3 input, NAV-PVT to `GnssFix`, and
the receiver configuration (UBX-CFG-VALSET).

Framing is an incremental state machine fed with whatever bytes the port returned (a serial
read, a replayed file chunk): it never raises, counts what it throws away, and finds valid
frames embedded in garbage (after a bad checksum it resynchronises one byte after the false
sync, so a frame that began inside the bad one is still found). Decoding of UBX payloads is
done by pyubx2, the reference implementation of the u-blox interface description.
"""

from __future__ import annotations

import bisect
import heapq
import math
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
from typing import Iterator

import numpy as np

from lotsen.messages import GnssFix, GnssFixType

UBX_SYNC = b"\xb5\x62"
RTCM_PREAMBLE = 0xD3
MAX_UBX_PAYLOAD = 8192  # longer "lengths" are garbage (the largest F9P message is ~2 kB)
MAX_NMEA = 120  # NMEA 0183 4.x allows 82 characters; some u-blox PUBX lines are longer


def _fletcher_py(data: bytes) -> bytes:
    a = b = 0
    for byte in data:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return bytes((a, b))


def ubx_checksum(data: bytes) -> bytes:
    """8-bit Fletcher checksum over class, id, length and payload (u-blox interface description).

    ck_a = sum d_k, ck_b = sum of the running sums = sum (n - k) d_k (mod 256): one numpy dot
    product for long frames, so a false sync claiming 8 kB costs microseconds, not milliseconds."""
    n = len(data)
    if n < 64:
        return _fletcher_py(data)
    v = np.frombuffer(data, dtype=np.uint8).astype(np.int64)
    return bytes((int(v.sum()) & 0xFF, int(v @ np.arange(n, 0, -1, dtype=np.int64)) & 0xFF))


def _crc24q_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 16
        for _ in range(8):
            crc <<= 1
            if crc & 0x1000000:
                crc ^= 0x1864CFB  # CRC-24Q polynomial (RTCM 10403.3, Qualcomm)
        table.append(crc & 0xFFFFFF)
    return tuple(table)


_CRC24Q = _crc24q_table()


def crc24q(data: bytes) -> int:
    """CRC-24Q of RTCM3, table driven (same values as pyrtcm's bitwise calc_crc24q, ~10x faster);
    over a whole frame including its CRC the result is 0."""
    crc = 0
    table = _CRC24Q
    for byte in data:
        crc = ((crc << 8) & 0xFFFFFF) ^ table[(crc >> 16) ^ byte]
    return crc


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


def _rtcm_number_ok(number: int) -> bool:
    """RTCM 10403.x message numbers: 1001-1230 assigned (1299 allowed for new ones), 4001-4095
    proprietary (u-blox 4072). Random bytes hit these ~10 % of the time."""
    return 1001 <= number <= 1299 or 4001 <= number <= 4095


_MARKERS = frozenset(b"\xb5\xd3$\n")


def _has_marker(chunk: bytes) -> bool:
    """Can `chunk` start a frame (UBX sync, RTCM3 preamble, '$') or end an NMEA sentence?"""
    if len(chunk) == 1:
        return chunk[0] in _MARKERS
    return b"\xb5" in chunk or b"\xd3" in chunk or b"$" in chunk or b"\n" in chunk


# classification of a candidate frame start
_BAD, _INCOMPLETE, _COMPLETE = 0, 1, 2


class StreamFramer:
    """Split a byte stream into UBX, NMEA and RTCM3 frames. `feed(chunk)` returns complete frames.

    Cost: candidate starts (0xB5 0x62, 0xD3, '$') are found with bytes.find, so garbage between
    them is skipped at C speed; every candidate is classified and checksummed at most once (the
    verdicts are kept by stream offset), so a false sync that claims a long length and waits for
    its bytes does not make each later read rescan the buffer. bench/bench_drivers.py measures it.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self._base = 0  # stream offset of _buf[0]
        self.counters = FramerCounters()
        # look-ahead past a candidate that waits for its bytes (all stream offsets):
        self._verdicts: dict[int, bool] = {}  # complete candidates: checksum valid?
        self._open: list[tuple[int, int]] = []  # heap of (offset where decidable, start) of undecided candidates
        self._valid_ahead: list[int] = []  # sorted starts of valid complete frames found ahead
        self._scanned_to = 0  # candidates starting before this have been classified by the look-ahead
        self._front_wait: int | None = None  # the first candidate waits for bytes up to this offset

    # -- candidates ---------------------------------------------------------------------------
    @staticmethod
    def _next_start(buf: bytearray, i: int, n: int) -> int:
        """First candidate frame start in buf[i:n], or n."""
        best = n
        for marker in (UBX_SYNC, b"\xd3", b"$"):
            p = buf.find(marker, i, best)
            if p >= 0:
                best = p
        return best

    def _classify(self, c: int, n: int) -> tuple[int, int]:
        """(_BAD | _INCOMPLETE | _COMPLETE, end) of the candidate at buf[c]; for _INCOMPLETE `end`
        is the buffer length at which it can be classified again."""
        buf = self._buf
        b0 = buf[c]
        if b0 == 0xB5:
            if c + 6 > n:
                return _INCOMPLETE, c + 6
            length = buf[c + 4] | (buf[c + 5] << 8)
            if length > MAX_UBX_PAYLOAD:
                return _BAD, 0
            end = c + 8 + length
        elif b0 == RTCM_PREAMBLE:
            if c + 3 > n:
                return _INCOMPLETE, c + 3
            if buf[c + 1] & 0xFC:  # 6 reserved bits must be zero
                return _BAD, 0
            length = ((buf[c + 1] & 0x03) << 8) | buf[c + 2]
            if length >= 2:  # the payload starts with the 12-bit message number
                if c + 5 > n:
                    return _INCOMPLETE, c + 5
                if not _rtcm_number_ok((buf[c + 3] << 4) | (buf[c + 4] >> 4)):
                    return _BAD, 0  # no CRC over up to 1 kB for a preamble in noise
            end = c + 6 + length
        else:  # '$'
            lf = buf.find(b"\n", c, min(n, c + MAX_NMEA))
            if lf < 0:
                return (_BAD, 0) if n - c >= MAX_NMEA else (_INCOMPLETE, c + MAX_NMEA)
            end = lf + 1
        return (_COMPLETE, end) if end <= n else (_INCOMPLETE, end)

    def _check(self, c: int, end: int) -> bool:
        """Is the complete candidate buf[c:end] a valid frame? (memoised by stream offset)"""
        key = self._base + c
        ok = self._verdicts.get(key)
        if ok is None:
            buf = self._buf
            b0 = buf[c]
            if b0 == 0xB5:
                ok = ubx_checksum(bytes(buf[c + 2:end - 2])) == bytes(buf[end - 2:end])
            elif b0 == RTCM_PREAMBLE:
                ok = crc24q(bytes(buf[c:end])) == 0
            else:
                ok = nmea_checksum_ok(bytes(buf[c:end]).rstrip(b"\r\n"))
            self._verdicts[key] = ok
        return ok

    def _valid_frame_after(self, c: int, n: int) -> bool:
        """Does a complete, valid frame start in buf[c+1:n]? Incremental: candidates classified
        by an earlier call are only looked at again once enough bytes arrived to decide them."""
        base = self._base
        while self._open and self._open[0][0] <= base + n:
            _, start = heapq.heappop(self._open)
            self._look(start - base, n)
        i = max(self._scanned_to - base, c + 1)
        while i < n:
            p = self._next_start(self._buf, i, n)
            if p >= n:
                break
            self._look(p, n)
            i = p + 1
        # a trailing 0xB5 may become a sync with the next byte: scan it again then
        self._scanned_to = max(self._scanned_to, base + n - (self._buf[n - 1] == 0xB5))
        k = bisect.bisect_right(self._valid_ahead, base + c)
        return k < len(self._valid_ahead)

    def _look(self, p: int, n: int) -> None:
        kind, end = self._classify(p, n)
        if kind == _COMPLETE:
            if self._check(p, end):
                bisect.insort(self._valid_ahead, self._base + p)
        elif kind == _INCOMPLETE:
            heapq.heappush(self._open, (self._base + end, self._base + p))

    # -- feeding ------------------------------------------------------------------------------
    def feed(self, chunk: bytes) -> list[Frame]:
        c_ = self.counters
        c_.bytes_in += len(chunk)
        buf = self._buf
        # fast paths for small reads (a port read byte by byte): bytes that cannot start or end
        # a frame (no sync, preamble, '$' or newline) change nothing while the buffer is empty
        # or while its first candidate and every look-ahead candidate still wait for bytes
        if not _has_marker(chunk) and not (buf and buf[-1] == 0xB5):
            if not buf:
                c_.garbage_bytes += len(chunk)
                return []
            wait = self._front_wait
            if wait is not None:
                reach = self._base + len(buf) + len(chunk)
                if reach < wait and (not self._open or reach < self._open[0][0]):
                    buf += chunk
                    return []
        self._front_wait = None
        buf += chunk
        n = len(buf)
        out: list[Frame] = []
        i = 0
        while i < n:
            c = self._next_start(buf, i, n)
            if c >= n:
                hold = 1 if buf[n - 1] == 0xB5 else 0  # may be the first half of a sync
                c_.garbage_bytes += n - hold - i
                i = n - hold
                break
            c_.garbage_bytes += c - i
            i = c
            kind, end = self._classify(c, n)
            if kind == _COMPLETE:
                if self._check(c, end):
                    b0 = buf[c]
                    if b0 == 0xB5:
                        c_.ubx_frames += 1
                        out.append(Frame("ubx", bytes(buf[c:end])))
                    elif b0 == RTCM_PREAMBLE:
                        c_.rtcm_frames += 1
                        out.append(Frame("rtcm", bytes(buf[c:end])))
                    else:
                        c_.nmea_sentences += 1
                        out.append(Frame("nmea", bytes(buf[c:end]).rstrip(b"\r\n")))
                    i = end
                    continue
                c_.bad_checksums += 1
            elif kind == _INCOMPLETE and not self._valid_frame_after(c, n):
                self._front_wait = self._base + end  # stream offset at which it can be decided
                break  # wait for the rest of this frame
            # a bad header, checksum, or a false sync that must not hold up the frames after it:
            # resynchronise one byte later (a real frame may begin inside the false one)
            c_.garbage_bytes += 1
            i = c + 1
        if i:
            del buf[:i]
            self._base += i
            self._forget_before(self._base)
        return out

    def _forget_before(self, offset: int) -> None:
        if self._verdicts:
            self._verdicts = {k: v for k, v in self._verdicts.items() if k >= offset}
        if self._valid_ahead and self._valid_ahead[0] < offset:
            self._valid_ahead = self._valid_ahead[bisect.bisect_left(self._valid_ahead, offset):]
        if self._open and min(s for _, s in self._open) < offset:
            self._open = [e for e in self._open if e[1] >= offset]
            heapq.heapify(self._open)

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
    # NAV-PVT's payload is 92 bytes: pyubx2 would fill a shorter one with defaults (a silent "no fix")
    if len(frame) != 8 + 92 or frame[2] != 0x01 or frame[3] != 0x07:
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


# Physical plausibility of a decoded fix. A checksum only proves the bytes arrived as sent: a
# receiver bug, a spoofer, an edited capture or a frame built by hand can still claim a position
# that cannot exist. Such a fix is refused (counted, never published as usable).
MIN_HEIGHT_M = -1_000.0  # ellipsoidal height: the Dead Sea shore is ~-430 m, the geoid ~-106 m
MAX_HEIGHT_M = 10_000.0  # higher than any water a boat floats on (and than a test flight)
MAX_GROUND_SPEED_MPS = 100.0  # 360 km/h: far beyond the boat, a car or a bike carrying the receiver
RTK_FIXED_MAX_H_ACC_M = 1.0  # ambiguity-fixed RTK is accurate to centimetres; 1 m contradicts it


def implausible_fix(fix: GnssFix) -> str | None:
    """Why a fix that claims a position (2D or better) is physically impossible; None when it is
    plausible or claims no position at all (NO_FIX / dead reckoning carry NaN coordinates)."""
    ft = fix.fix_type
    if ft < GnssFixType.FIX_2D:
        return None
    name = ft.name
    lat, lon = fix.lat_deg, fix.lon_deg
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        return f"{name} at latitude {lat:.7f} deg (outside [-90, 90])"
    if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
        return f"{name} at longitude {lon:.7f} deg (outside [-180, 180])"
    if not fix.h_acc_m > 0.0:  # NaN too
        return f"{name} with horizontal accuracy {fix.h_acc_m * 1000:.0f} mm (must be > 0)"
    if ft == GnssFixType.RTK_FIXED and fix.h_acc_m > RTK_FIXED_MAX_H_ACC_M:
        return (f"RTK_FIXED with horizontal accuracy {fix.h_acc_m:.3f} m (an ambiguity-fixed solution is "
                f"accurate to centimetres; > {RTK_FIXED_MAX_H_ACC_M:g} m contradicts it)")
    if ft >= GnssFixType.FIX_3D:
        if not fix.v_acc_m > 0.0:
            return f"{name} with vertical accuracy {fix.v_acc_m * 1000:.0f} mm (must be > 0)"
        if not MIN_HEIGHT_M <= fix.height_m <= MAX_HEIGHT_M:
            return f"{name} at height {fix.height_m:.3f} m (outside [{MIN_HEIGHT_M:g}, {MAX_HEIGHT_M:g}] m)"
    speed = math.hypot(fix.vel_n_mps, fix.vel_e_mps)
    if speed > MAX_GROUND_SPEED_MPS:  # NaN velocities (not reported) pass
        return f"{name} with ground speed {speed:.1f} m/s (more than {MAX_GROUND_SPEED_MPS:g} m/s)"
    if fix.num_sv <= 0:
        return f"{name} from {fix.num_sv} satellites"
    return None


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
    refused: list[tuple[NavPvt, str]] = field(default_factory=list)  # physically impossible, with the reason


def replay_stream(chunks: Iterator[bytes]) -> ReplayResult:
    """All NAV-PVT solutions of a recorded byte stream (any mix of UBX, NMEA, RTCM, garbage);
    physically impossible ones (`implausible_fix`) go to `refused`, not `fixes`."""
    framer = StreamFramer()
    result = ReplayResult(counters=framer.counters)
    for chunk in chunks:
        for frame in framer.feed(chunk):
            if frame.kind == "ubx" and frame.data[2:4] == b"\x01\x07":
                pvt = decode_nav_pvt(frame.data)
                if pvt is None:
                    result.undecodable += 1
                elif (why := implausible_fix(pvt.fix)) is not None:
                    result.refused.append((pvt, why))
                else:
                    result.fixes.append(pvt)
    return result
