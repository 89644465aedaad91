"""SBUS, the serial output of the FrSky X8R receiver: bytes -> frames, and frames -> bytes for
the emulated receiver.

Line: 100 000 baud, 8 data bits, even parity, 2 stop bits, inverted (an inverter between the
receiver and the Pi's RX pin; see docs/drivers.md). A frame is 25 bytes, one every 7-14 ms:

    byte 0      0x0F header
    bytes 1-22  16 channels of 11 bits, little-endian bit order: channel 1 is bits 0-10 of the
                22-byte block read as one little-endian integer, channel 2 bits 11-21, ...
    byte 23     flags: bit 0 channel 17, bit 1 channel 18 (digital), bit 2 frame lost (the
                receiver missed a frame from the transmitter and repeats the last values),
                bit 3 failsafe (the receiver lost the transmitter and outputs its failsafe values)
    byte 24     0x00 footer

Raw channel values are 0-2047; FrSky transmitters send 172 (-100 %, 988 us) .. 992 (0, 1500 us)
.. 1811 (+100 %, 2012 us).

SBUS has no checksum: header and footer are the only framing. The decoder therefore trusts a
frame only where the stream is in step: the first frame after a start or a loss of step is
taken only when the byte after its footer is the next frame's header (frames are sent back to
back), and every following frame must start exactly where the previous one ended. A frame whose
header or footer is wrong at that place is dropped and counted, and the search starts again one
byte later, so the decoder finds its way back into any stream, and never raises on garbage.
A corrupted channel byte inside a frame with intact framing cannot be detected (no checksum);
the channel map's plausibility checks (lotsen.drivers.rc) are the only defence there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

SBUS_BAUDRATE = 100_000
FRAME_LEN = 25
HEADER = 0x0F
FOOTER = 0x00
N_CHANNELS = 16
RAW_MAX = 2047
FLAG_CH17 = 0x01
FLAG_CH18 = 0x02
FLAG_FRAME_LOST = 0x04
FLAG_FAILSAFE = 0x08
# FrSky's raw values at -100 %, 0 and +100 % stick
RAW_LOW = 172
RAW_CENTER = 992
RAW_HIGH = 1811
_MAX_BUFFER = 4 * FRAME_LEN  # bytes kept while looking for a frame start


class SbusError(ValueError):
    """Bytes that are not one SBUS frame (wrong length, header or footer)."""


@dataclass(frozen=True, slots=True)
class SbusFrame:
    """One decoded frame: 16 raw 11-bit channels, the two digital channels and the link flags."""

    channels: tuple[int, ...]
    ch17: bool = False
    ch18: bool = False
    frame_lost: bool = False
    failsafe: bool = False

    def raw(self, channel: int) -> int:
        """Channel 1..16 as its raw value; 17 and 18 (digital) as RAW_HIGH (on) or RAW_LOW (off)."""
        if channel == 17:
            return RAW_HIGH if self.ch17 else RAW_LOW
        if channel == 18:
            return RAW_HIGH if self.ch18 else RAW_LOW
        return self.channels[channel - 1]


def encode_frame(frame: SbusFrame) -> bytes:
    """The 25 bytes a receiver sends for `frame` (channels clipped to 0..2047)."""
    if len(frame.channels) != N_CHANNELS:
        raise SbusError(f"an SBUS frame has {N_CHANNELS} channels, got {len(frame.channels)}")
    bits = 0
    for i, v in enumerate(frame.channels):
        bits |= (min(max(int(v), 0), RAW_MAX)) << (11 * i)
    flags = ((FLAG_CH17 if frame.ch17 else 0) | (FLAG_CH18 if frame.ch18 else 0)
             | (FLAG_FRAME_LOST if frame.frame_lost else 0) | (FLAG_FAILSAFE if frame.failsafe else 0))
    return bytes((HEADER,)) + bits.to_bytes(22, "little") + bytes((flags, FOOTER))


def decode_frame(data: bytes) -> SbusFrame:
    """Exactly one frame (25 bytes, header and footer checked) -> SbusFrame."""
    if len(data) != FRAME_LEN:
        raise SbusError(f"an SBUS frame is {FRAME_LEN} bytes, got {len(data)}")
    if data[0] != HEADER or data[24] != FOOTER:
        raise SbusError(f"not an SBUS frame: header 0x{data[0]:02x} (0x0f), footer 0x{data[24]:02x} (0x00)")
    bits = int.from_bytes(data[1:23], "little")
    channels = tuple((bits >> (11 * i)) & RAW_MAX for i in range(N_CHANNELS))
    f = data[23]
    return SbusFrame(channels, ch17=bool(f & FLAG_CH17), ch18=bool(f & FLAG_CH18),
                     frame_lost=bool(f & FLAG_FRAME_LOST), failsafe=bool(f & FLAG_FAILSAFE))


@dataclass
class SbusCounters:
    frames: int = 0
    bad_frames: int = 0  # in step, but the header or footer was wrong where a frame had to be
    garbage_bytes: int = 0  # skipped while out of step
    frame_lost_flags: int = 0
    failsafe_flags: int = 0


@dataclass
class SbusDecoder:
    """Incremental decoder: `feed(bytes) -> [SbusFrame]`; the result does not depend on how the
    stream is cut into reads. Never raises on any input."""

    counters: SbusCounters = field(default_factory=SbusCounters)
    in_step: bool = False
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[SbusFrame]:
        buf = self._buf
        buf += data
        frames: list[SbusFrame] = []
        c = self.counters
        i = 0
        n = len(buf)
        while n - i >= FRAME_LEN:
            if self.in_step:
                if buf[i] == HEADER and buf[i + 24] == FOOTER:
                    frames.append(self._take(buf, i))
                    i += FRAME_LEN
                    continue
                c.bad_frames += 1
                self.in_step = False
                i += 1  # the search for a new start begins one byte later
                continue
            j = buf.find(HEADER, i, n - FRAME_LEN + 1)
            if j < 0:
                c.garbage_bytes += max(0, n - FRAME_LEN + 1 - i)
                i = n - FRAME_LEN + 1
                break
            c.garbage_bytes += j - i
            i = j
            if buf[i + 24] != FOOTER:
                c.garbage_bytes += 1
                i += 1
                continue
            if n - i < FRAME_LEN + 1:
                break  # a candidate: wait for the byte after it (the next frame's header)
            if buf[i + FRAME_LEN] != HEADER:
                c.garbage_bytes += 1
                i += 1
                continue
            self.in_step = True
            frames.append(self._take(buf, i))
            i += FRAME_LEN
        del buf[:i]
        if len(buf) > _MAX_BUFFER:  # cannot happen with the loop above; a bound all the same
            c.garbage_bytes += len(buf) - _MAX_BUFFER
            del buf[:len(buf) - _MAX_BUFFER]
            self.in_step = False
        return frames

    def _take(self, buf: bytearray, i: int) -> SbusFrame:
        frame = decode_frame(bytes(buf[i:i + FRAME_LEN]))
        c = self.counters
        c.frames += 1
        c.frame_lost_flags += frame.frame_lost
        c.failsafe_flags += frame.failsafe
        return frame

    def reset(self) -> None:
        """Forget partial input (a reopened port)."""
        self._buf.clear()
        self.in_step = False
