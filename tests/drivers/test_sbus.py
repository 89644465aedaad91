"""SBUS decoding (FrSky X8R), the channel map and the RC driver against the emulated receiver."""

import math

import numpy as np
import pytest

from lotsen.drivers.config import HardwareConfig, RcSection, RcStick, RcSwitch
from lotsen.drivers.emulated import EmulatedX8R
from lotsen.drivers.rc import RcInterpreter, RcReceiverNode, stick_raw, stick_value, switch_on, switch_raw
from lotsen.drivers.sbus import (
    FRAME_LEN, RAW_CENTER, RAW_HIGH, RAW_LOW, SbusDecoder, SbusError, SbusFrame, decode_frame, encode_frame,
)
from lotsen.messages import Topic

RNG = np.random.default_rng(27)


def random_frame(rng=RNG, flags=True):
    chans = tuple(int(v) for v in rng.integers(0, 2048, 16))
    f = rng.integers(0, 2, 4) if flags else (0, 0, 0, 0)
    return SbusFrame(chans, ch17=bool(f[0]), ch18=bool(f[1]), frame_lost=bool(f[2]), failsafe=bool(f[3]))


# ---------------------------------------------------------------------------- the wire format
def test_known_frame_bytes():
    """Channel 1 = 1 and channel 16 = 2047 land in the documented bits; flags byte 23."""
    chans = (1,) + (0,) * 14 + (2047,)
    data = encode_frame(SbusFrame(chans, ch17=True, failsafe=True))
    assert len(data) == 25 and data[0] == 0x0F and data[24] == 0x00
    assert data[1] == 0x01 and data[2] == 0x00  # channel 1 in bits 0-10
    assert data[21] == 0xE0 and data[22] == 0xFF  # channel 16 in bits 165-175: byte 21 bits 5-7, byte 22
    assert data[23] == 0x01 | 0x08
    # against a bit-by-bit packer: channel i bit b is bit 11 i + b of bytes 1..22, LSB first
    for _ in range(50):
        f = random_frame()
        ref = bytearray(25)
        ref[0] = 0x0F
        for i, v in enumerate(f.channels):
            for b in range(11):
                if v >> b & 1:
                    k = 11 * i + b
                    ref[1 + k // 8] |= 1 << (k % 8)
        ref[23] = f.ch17 | f.ch18 << 1 | f.frame_lost << 2 | f.failsafe << 3
        assert encode_frame(f) == bytes(ref)


def test_round_trip_of_random_frames():
    for _ in range(500):
        f = random_frame()
        assert decode_frame(encode_frame(f)) == f


def test_decode_frame_refuses_wrong_framing():
    good = encode_frame(random_frame())
    for bad in (good[:-1], good + b"\x00", b"\x0e" + good[1:], good[:-1] + b"\x04"):
        with pytest.raises(SbusError):
            decode_frame(bad)


def test_flags_are_decoded_each_on_its_own():
    for bit, name in ((0x01, "ch17"), (0x02, "ch18"), (0x04, "frame_lost"), (0x08, "failsafe")):
        data = bytearray(encode_frame(SbusFrame((RAW_CENTER,) * 16)))
        data[23] = bit
        f = decode_frame(bytes(data))
        assert [getattr(f, n) for n in ("ch17", "ch18", "frame_lost", "failsafe")].count(True) == 1
        assert getattr(f, name)
    assert SbusFrame((0,) * 16, ch17=True).raw(17) == RAW_HIGH and SbusFrame((0,) * 16).raw(18) == RAW_LOW


# ---------------------------------------------------------------------------- the stream decoder
def stream(frames):
    return b"".join(encode_frame(f) for f in frames)


def test_stream_cut_anywhere_gives_the_same_frames():
    frames = [random_frame() for _ in range(60)]
    data = stream(frames)
    assert SbusDecoder().feed(data) == frames
    # out of step, a frame is trusted only with its successor's header behind it
    dec = SbusDecoder()
    assert dec.feed(data[:25]) == [] and dec.feed(data[25:26]) == frames[:1]
    assert dec.in_step and dec.feed(data[26:75]) == frames[1:3]  # in step: at once
    for size in (1, 2, 3, 7, 24, 25, 26, 64):
        dec, got = SbusDecoder(), []
        for i in range(0, len(data), size):
            got += dec.feed(data[i:i + size])
        assert got == frames, size
        assert dec.counters.frames == 60 and dec.counters.bad_frames == 0 and dec.counters.garbage_bytes == 0


def test_resynchronises_after_garbage_and_drops_a_broken_frame():
    frames = [SbusFrame(tuple(int(v) for v in RNG.integers(172, 1812, 16))) for _ in range(30)]
    data = bytearray(stream(frames[:10]))
    # garbage full of false headers and footers (none 24 bytes behind a header: SBUS has no
    # checksum, so 25 bytes with both in place are a frame to any decoder)
    data += bytes([0x0F, 0x00, 0x0F, 0x33, 0x00, 0x0F] * 6)
    broken = bytearray(encode_frame(frames[10]))
    broken[24] = 0x5A  # footer corrupted: this frame cannot be trusted
    data += broken + stream(frames[11:])
    dec = SbusDecoder()
    got = dec.feed(bytes(data))
    assert got[:10] == frames[:10]
    assert frames[10] not in got
    assert got[-19:] == frames[11:30]  # every intact frame after the garbage found again
    assert len(got) == 29 and dec.counters.bad_frames >= 1 and dec.counters.garbage_bytes >= 35


@pytest.mark.parametrize("seed", range(5))
def test_fuzz_random_and_mutated_bytes_never_raise(seed):
    rng = np.random.default_rng(seed)
    dec = SbusDecoder()
    total = 0
    for _ in range(200):
        kind = rng.integers(3)
        if kind == 0:  # pure noise
            chunk = rng.integers(0, 256, int(rng.integers(0, 80))).astype(np.uint8).tobytes()
        elif kind == 1:  # frames with flipped, dropped and inserted bytes
            b = bytearray(stream([random_frame(rng) for _ in range(3)]))
            for _ in range(int(rng.integers(1, 4))):
                op, i = rng.integers(3), int(rng.integers(len(b)))
                if op == 0:
                    b[i] ^= 1 << int(rng.integers(8))
                elif op == 1:
                    del b[i]
                else:
                    b.insert(i, int(rng.integers(256)))
            chunk = bytes(b)
        else:  # the bytes that matter most: headers and footers
            chunk = rng.choice([0x0F, 0x00, 0xFF], int(rng.integers(1, 60))).astype(np.uint8).tobytes()
        for f in dec.feed(chunk):
            assert len(f.channels) == 16 and all(0 <= v <= 2047 for v in f.channels)
            total += 1
        assert len(dec._buf) <= 4 * FRAME_LEN
    c = dec.counters
    assert c.garbage_bytes > 1000 and total == c.frames
    # and after all that, a clean stream is followed again from its second frame on
    clean = [random_frame(rng) for _ in range(10)]
    assert dec.feed(stream(clean))[-8:] == clean[-8:]


# ---------------------------------------------------------------------------- the channel map
def test_stick_mapping_round_trips_and_has_a_deadband():
    s = RcStick(channel=2)
    assert stick_value(s, 992) == 0.0 and stick_value(s, 1811) == 1.0 and stick_value(s, 172) == -1.0
    assert stick_value(s, 992 + 30) == 0.0  # inside the 5 % deadband
    assert stick_value(s, 0) == -1.0 and stick_value(s, 2047) == 1.0  # clipped
    for v in (-1.0, -0.6, -0.1, 0.0, 0.25, 0.7, 1.0):
        assert stick_value(s, stick_raw(s, v)) == pytest.approx(v, abs=0.003)
    r = RcStick(channel=2, reverse=True)
    assert stick_value(r, 1811) == -1.0 and stick_value(r, stick_raw(r, 0.5)) == pytest.approx(0.5, abs=0.003)


def test_switch_mapping():
    sw = RcSwitch(channel=5)
    assert switch_on(sw, 1811) and not switch_on(sw, 172) and not switch_on(sw, 992)
    rev = RcSwitch(channel=6, reverse=True)
    assert switch_on(rev, 172) and not switch_on(rev, 1811)
    assert switch_on(rev, switch_raw(rev, True)) and not switch_on(sw, switch_raw(sw, False))


def frame_with(cfg, takeover=False, estop=False, throttle=0.0, steering=0.0, bow=0.0, **flags):
    ch = [RAW_CENTER] * 4 + [RAW_LOW] * 12
    for stick, v in ((cfg.throttle, throttle), (cfg.steering, steering), (cfg.bow, bow)):
        ch[stick.channel - 1] = stick_raw(stick, v)
    ch[cfg.takeover.channel - 1] = switch_raw(cfg.takeover, takeover)
    ch[cfg.estop.channel - 1] = switch_raw(cfg.estop, estop)
    return SbusFrame(tuple(ch), **flags)


def test_interpreter_sticks_to_thrust_and_the_centre_sticks_gate():
    cfg = RcSection()
    rc = RcInterpreter(cfg)
    rc.frame(frame_with(cfg, throttle=0.5), 0.0)
    assert rc.override(0.0).command is None and not rc.override(0.0).active  # no takeover: no command
    rc.frame(frame_with(cfg, takeover=True, throttle=0.5, steering=1.0), 0.01)
    cmd = rc.override(0.01).command
    assert cmd.n1_rps == 0.0 and cmd.alpha1_rad == pytest.approx(-math.radians(35.0))  # throttle not centred yet
    rc.frame(frame_with(cfg, takeover=True), 0.02)
    rc.frame(frame_with(cfg, takeover=True, throttle=0.5, steering=-0.5, bow=1.0), 0.03)
    cmd = rc.override(0.03).command
    assert cmd.source == "rc" and cmd.n1_rps == cmd.n2_rps == pytest.approx(30.0, abs=0.2)
    assert cmd.alpha1_rad == cmd.alpha2_rad == pytest.approx(math.radians(17.5), abs=0.005)
    assert cmd.nt_rps == pytest.approx(50.0, abs=0.2)
    msg = rc.override(0.03)
    assert msg.active and msg.link == "ok" and not msg.estop


def test_interpreter_link_lost_failsafe_and_switches_only_from_good_frames():
    cfg = RcSection()
    rc = RcInterpreter(cfg)
    assert rc.override(0.0).link == "lost"  # never heard
    rc.frame(frame_with(cfg, takeover=True), 0.0)
    # frames flagged lost carry stale channels: a single one changes nothing, a run of them is a loss
    rc.frame(frame_with(cfg, takeover=False, estop=True, frame_lost=True), 0.1)
    assert rc.override(0.1).link == "ok" and rc.takeover and not rc.estop
    rc.frame(frame_with(cfg, takeover=False, frame_lost=True), 0.21)
    m = rc.override(0.21)
    assert m.link == "lost" and m.active and m.command is None and not m.estop
    # the failsafe flag: the receiver's preset values (here: e-stop on) are ignored
    rc.frame(frame_with(cfg, takeover=False, estop=True, frame_lost=True, failsafe=True), 1.0)
    m = rc.override(1.0)
    assert m.link == "failsafe" and m.active and not m.estop and m.command is None
    rc.frame(frame_with(cfg, takeover=True, estop=True), 1.5)
    m = rc.override(1.5)
    assert m.link == "ok" and m.estop
    assert rc.override(1.5 + cfg.lost_after_s + 0.01).link == "lost"  # silence


# ---------------------------------------------------------------------------- the driver node
class Ctx:
    def __init__(self):
        self.t = 0.0

    def now(self):
        return self.t


def node_and_twin(cfg=RcSection()):
    x8r = EmulatedX8R()
    node = RcReceiverNode(cfg, x8r.port.reopen)
    return node, x8r


def run_node(node, x8r, t0, t1, dt=0.01):
    out = []
    t = t0
    while t < t1 - 1e-9:
        t += dt
        x8r.advance(t)
        out += [(t, topic, m) for topic, m in node.step(t)]
    return out


def test_node_publishes_at_its_rate_and_reports_the_link_within_its_time():
    cfg = RcSection()
    node, x8r = node_and_twin(cfg)
    out = run_node(node, x8r, 0.0, 2.0)
    rc = [(t, m) for t, topic, m in out if topic == Topic.RC]
    assert 38 <= len(rc) <= 42 and all(m.link == "ok" and not m.active for _, m in rc)  # no "lost" at start
    assert node.health.messages >= 200 and node.health.dropped == 0
    x8r.transmitter_on = False
    out = run_node(node, x8r, 2.0, 3.5)
    lost = [t for t, topic, m in out if topic == Topic.RC and m.link != "ok"]
    assert lost and lost[0] - 2.0 <= cfg.lost_after_s + 0.03
    fs = [t for t, topic, m in out if topic == Topic.RC and m.link == "failsafe"]
    assert fs and 2.9 <= fs[0] <= 3.1  # the twin's failsafe flag after 1 s
    assert any(topic == Topic.LOG and "RC link lost" in m.text for _, topic, m in out)
    x8r.transmitter_on = True
    out = run_node(node, x8r, 3.5, 3.6)
    assert [m for _, topic, m in out if topic == Topic.RC][-1].link == "ok"
    x8r.output_on = False  # a cut wire: no bytes at all
    out = run_node(node, x8r, 3.6, 4.0)
    lost = [t for t, topic, m in out if topic == Topic.RC and m.link == "lost"]
    assert lost and lost[0] - 3.6 <= cfg.lost_after_s + 0.03


def test_node_reports_a_receiver_that_never_speaks_as_lost():
    cfg = RcSection()
    node, x8r = node_and_twin(cfg)
    x8r.output_on = False
    out = run_node(node, x8r, 0.0, 1.0)
    rc = [(t, m) for t, topic, m in out if topic == Topic.RC]
    assert rc and all(m.link == "lost" for _, m in rc) and rc[0][0] <= cfg.lost_after_s + 0.02


def test_node_survives_a_corrupted_stream():
    node, x8r = node_and_twin()
    x8r.corrupt_probability = 0.01  # one bit in a hundred bytes: a quarter of the frames hit
    x8r.channels[4] = RAW_HIGH  # takeover on
    out = run_node(node, x8r, 0.0, 5.0)
    c = node.decoder.counters
    assert c.frames > 300 and c.bad_frames + c.garbage_bytes > 20 and node.health.dropped > 0
    rc = [m for _, topic, m in out if topic == Topic.RC]
    assert sum(m.link == "ok" for m in rc) >= 0.9 * len(rc)
    assert node.health.errors > 0 and not any(topic == Topic.LOG and m.level == "error" for _, topic, m in out)


def test_hardware_boat_has_the_rc_receiver_and_it_can_be_switched_off():
    from lotsen.model import VesselModel
    from lotsen.runtime.config import LaunchConfig
    from lotsen.runtime.executor import SimExecutor
    from lotsen.stack.hardware import add_hardware_boat
    from lotsen.stack.stack import Stack

    stack = Stack(config=LaunchConfig(), executor=SimExecutor(), model=VesselModel())
    boat = add_hardware_boat(stack, emulated=True)
    got = []
    stack.bus.subscribe(Topic.RC, got.append)
    stack.executor.run_until(1.0)
    assert "rc" in boat.drivers and boat.drivers["rc"].refresh_health().ok
    assert len(got) >= 18 and got[-1].link == "ok"
    stack.executor.shutdown()
    off = HardwareConfig(rc=RcSection(enabled=False))
    stack = Stack(config=LaunchConfig(), executor=SimExecutor(), model=VesselModel())
    assert "rc" not in add_hardware_boat(stack, emulated=True, config=off).drivers
    stack.executor.shutdown()
