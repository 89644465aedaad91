"""A small receiver capture: NAV-PVT solutions generated with pyubx2, mixed with NMEA, RTCM3,
an ACK, a corrupted NAV-PVT, a truncated one, and garbage bytes (tests/drivers/data/capture.ubx
is this function's output: `python tests/drivers/capture.py`)."""

from __future__ import annotations

import random
from pathlib import Path

from pyubx2 import GET, UBXMessage

from lotsen.drivers.ubx import crc24q, ubx_frame

# (iTOW ms, lat, lon, height mm, fixType, carrSoln, hAcc mm)
EXPECTED = [
    (379_200_000, 57.6905000, 11.9760000, 10_000, 3, 0, 1500),
    (379_200_125, 57.6905010, 11.9760020, 10_010, 3, 1, 180),
    (379_200_250, 57.6905020, 11.9760040, 10_020, 3, 2, 14),
    (379_200_375, 57.6905030, 11.9760060, 10_030, 3, 2, 12),
    (379_200_500, 0.0, 0.0, 0, 0, 0, 4_294_967_295),
]


def nav_pvt(itow: int, lat: float, lon: float, height: int, fix_type: int, carr: int, h_acc: int) -> bytes:
    return UBXMessage("NAV", "NAV-PVT", GET, iTOW=itow, year=2026, month=6, day=1, hour=9, min=20,
                      second=(itow // 1000) % 60, nano=(itow % 1000) * 1_000_000, validDate=1, validTime=1, fullyResolved=1,
                      fixType=fix_type, gnssFixOk=int(fix_type >= 2), carrSoln=carr, numSV=22 if fix_type else 2,
                      lat=lat, lon=lon, height=height, hMSL=height - 40_000, hAcc=h_acc, vAcc=2 * min(h_acc, 10**9),
                      velN=120, velE=-30, velD=0, gSpeed=124, sAcc=40, pDOP=1.1).serialize()


def rtcm_frame(payload: bytes) -> bytes:
    head = bytes((0xD3, (len(payload) >> 8) & 0x03, len(payload) & 0xFF)) + payload
    return head + crc24q(head).to_bytes(3, "big")


def make_capture() -> bytes:
    rng = random.Random(7)
    nmea = b"$GNGGA,092000.00,5741.43000,N,01158.56000,E,4,22,0.6,10.0,M,0.0,M,1.0,0000*"
    x = 0
    for ch in nmea[1:-1]:
        x ^= ch
    nmea += f"{x:02X}\r\n".encode()
    out = bytearray(b"\x00\xff\xb5garbage\xd3\x3f")
    for k, row in enumerate(EXPECTED):
        out += nmea
        out += bytes(rng.randrange(256) for _ in range(5 + k))  # line noise
        out += nav_pvt(*row)
        out += rtcm_frame(bytes([0x3E, 0xD0]) + bytes(17))  # message 1005-like
        if k == 1:
            bad = bytearray(nav_pvt(*row))
            bad[30] ^= 0x55  # corrupted: checksum fails, must be dropped
            out += bad
            out += ubx_frame(0x05, 0x01, b"\x06\x8a")  # ACK-ACK of a CFG-VALSET
    out += nav_pvt(*EXPECTED[0])[:50]  # truncated at the end of the capture
    return bytes(out)


if __name__ == "__main__":
    Path(__file__).with_name("data").joinpath("capture.ubx").write_bytes(make_capture())
