"""NMEA 0183 depth sentences as single-beam echosounders send them (and Blue Robotics' Ping2
through an NMEA converter): DPT (depth below the transducer in metres, transducer offset, optional
maximum range) and DBT (depth below the transducer in feet, metres and fathoms), any talker
(SD sounder, II integrated instrumentation, ...).

`DepthParser.feed(bytes)` returns the pings in the bytes and never raises: garbage between
sentences, bad or missing checksums, over-long lines and fields that are not numbers are counted
(`counters`) and dropped. What it returns does not depend on how the stream is cut into reads.

    $SDDPT,3.42,0.10,50.0*5D        3.42 m below the transducer, transducer 0.10 m below the waterline
    $SDDBT,11.2,f,3.42,M,1.87,F*3A  the same depth in feet, metres and fathoms
    $SDDPT,,0.10*6E                 no bottom found (a dropout)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: NMEA 0183 limits a sentence to 82 characters with $ and CR LF
MAX_SENTENCE = 82
#: a depth a sounder can report (the 200 kHz single-beams reach ~100 m, some 300 m)
MAX_DEPTH_M = 1000.0
FEET_PER_M = 1.0 / 0.3048
FATHOMS_PER_M = 1.0 / 1.8288


@dataclass(frozen=True, slots=True)
class NmeaDepth:
    """One ping: depth below the transducer (NaN: no bottom), DPT's offset (NaN in DBT)."""

    talker: str
    sentence: str          # "DPT" or "DBT"
    depth_m: float
    offset_m: float = math.nan


@dataclass
class DepthCounters:
    sentences: int = 0
    garbage_bytes: int = 0
    bad_checksums: int = 0
    overlong: int = 0
    bad_fields: int = 0
    other_sentences: int = 0   # valid NMEA of another kind (a sounder's MTW water temperature, ...)


def checksum(body: str) -> int:
    x = 0
    for ch in body.encode("ascii", "replace"):
        x ^= ch
    return x


def sentence(body: str) -> bytes:
    """`$body*hh\\r\\n`: an NMEA sentence with its checksum."""
    return f"${body}*{checksum(body):02X}\r\n".encode("ascii")


def _number(text: str) -> float:
    """A field's number; NaN for an empty field; ValueError for anything else odd."""
    if text == "":
        return math.nan
    v = float(text)
    if not math.isfinite(v):
        raise ValueError(text)
    return v


def parse_body(body: str) -> NmeaDepth | None:
    """A DPT or DBT body (without $ and checksum) as a ping; None for another sentence;
    ValueError for a DPT/DBT whose fields make no depth."""
    fields = body.split(",")
    head = fields[0]
    if len(head) != 5 or not head.isalnum():
        raise ValueError(f"address field {head[:10]!r}")
    talker, kind = head[:2], head[2:]
    if kind == "DPT":
        if len(fields) < 3:
            raise ValueError("DPT needs depth and offset")
        depth, offset = _number(fields[1]), _number(fields[2])
    elif kind == "DBT":
        if len(fields) < 7 or fields[2] not in ("f", "") or fields[4] not in ("M", "") or fields[6] not in ("F", ""):
            raise ValueError("DBT needs feet,f,metres,M,fathoms,F")
        metres, feet, fathoms = _number(fields[3]), _number(fields[1]), _number(fields[5])
        # the metres field; a sounder that fills only feet or fathoms still says the depth
        depth = metres if not math.isnan(metres) else feet / FEET_PER_M if not math.isnan(feet) else fathoms / FATHOMS_PER_M
        offset = math.nan
    else:
        return None
    if not math.isnan(depth) and not 0.0 <= depth <= MAX_DEPTH_M:
        raise ValueError(f"depth {depth:g} m")
    if not math.isnan(offset) and abs(offset) > 100.0:
        raise ValueError(f"offset {offset:g} m")
    return NmeaDepth(talker, kind, depth, offset)


class DepthParser:
    """Incremental parser of an echosounder's byte stream (see the module docstring)."""

    def __init__(self) -> None:
        self.counters = DepthCounters()
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[NmeaDepth]:
        self._buf += data
        out: list[NmeaDepth] = []
        buf = self._buf
        while True:
            start = buf.find(b"$")
            if start < 0:
                # keep nothing: no sentence can start in these bytes
                self.counters.garbage_bytes += len(buf)
                buf.clear()
                break
            if start:
                self.counters.garbage_bytes += start
                del buf[:start]
            end = buf.find(b"\n", 1)
            nxt = buf.find(b"$", 1)
            if 0 < nxt < (end if end >= 0 else len(buf)):
                # a new sentence starts before this one ended: the first was cut
                self.counters.garbage_bytes += nxt
                del buf[:nxt]
                continue
            if end < 0:
                if len(buf) > MAX_SENTENCE:
                    self.counters.overlong += 1
                    self.counters.garbage_bytes += len(buf)
                    buf.clear()
                break
            line = bytes(buf[:end + 1])
            del buf[:end + 1]
            if len(line) > MAX_SENTENCE + 1:
                self.counters.overlong += 1
                continue
            ping = self._line(line.rstrip(b"\r\n"))
            if ping is not None:
                out.append(ping)
        return out

    def _line(self, line: bytes) -> NmeaDepth | None:
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            self.counters.bad_checksums += 1
            return None
        star = text.rfind("*")
        if star < 0 or len(text) - star != 3:
            self.counters.bad_checksums += 1   # a sounder's sentence always carries its checksum
            return None
        body = text[1:star]
        try:
            given = int(text[star + 1:], 16)
        except ValueError:
            self.counters.bad_checksums += 1
            return None
        if checksum(body) != given:
            self.counters.bad_checksums += 1
            return None
        self.counters.sentences += 1
        try:
            ping = parse_body(body)
        except ValueError:
            self.counters.bad_fields += 1
            return None
        if ping is None:
            self.counters.other_sentences += 1
        return ping


def dpt(depth_m: float, offset_m: float, talker: str = "SD", max_range_m: float | None = None) -> bytes:
    """A DPT sentence (depth NaN: the empty field of a ping that found no bottom)."""
    d = "" if math.isnan(depth_m) else f"{depth_m:.2f}"
    body = f"{talker}DPT,{d},{offset_m:.2f}" + (f",{max_range_m:.1f}" if max_range_m is not None else "")
    return sentence(body)


def dbt(depth_m: float, talker: str = "SD") -> bytes:
    """A DBT sentence: feet, metres, fathoms (empty fields when no bottom was found)."""
    if math.isnan(depth_m):
        return sentence(f"{talker}DBT,,f,,M,,F")
    return sentence(f"{talker}DBT,{depth_m * FEET_PER_M:.1f},f,{depth_m:.2f},M,{depth_m * FATHOMS_PER_M:.2f},F")
