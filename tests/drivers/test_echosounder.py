"""The echosounder: NMEA 0183 DPT/DBT parsed from any talker, corrupt bytes counted and dropped
(never a crash, whatever the stream and however it is cut into reads), and the real driver end to
end against its emulated twin over the simulated lake bed."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lotsen.drivers import HardwareConfig
from lotsen.drivers.config import EchosounderSection
from lotsen.drivers.nmea_depth import DepthParser, dbt, dpt, sentence
from lotsen.messages import DepthSample, Topic
from lotsen.model import VesselModel
from lotsen.runtime.config import LakeBedSection, LaunchConfig, SimSection
from lotsen.runtime.executor import SimExecutor
from lotsen.stack.hardware import add_hardware_boat
from lotsen.stack.stack import Stack


def test_dpt_and_dbt_from_any_talker_and_a_missing_bottom():
    p = DepthParser()
    pings = p.feed(b"$SDDPT,3.42,0.10,50.0*" + b"%02X" % 0 + b"\r\n")   # wrong checksum: dropped
    assert pings == [] and p.counters.bad_checksums == 1
    pings = p.feed(dpt(3.42, 0.1) + dbt(12.5, talker="II") + sentence("SDDPT,,0.10") + sentence("SDMTW,12.1,C"))
    assert [(x.talker, x.sentence) for x in pings] == [("SD", "DPT"), ("II", "DBT"), ("SD", "DPT")]
    assert pings[0].depth_m == 3.42 and pings[0].offset_m == 0.1
    assert pings[1].depth_m == 12.5 and math.isnan(pings[1].offset_m)
    assert math.isnan(pings[2].depth_m)                      # no bottom: the empty field
    assert p.counters.other_sentences == 1 and p.counters.sentences == 4


def test_dbt_with_feet_only_is_converted():
    assert DepthParser().feed(sentence("SDDBT,32.8,f,,M,,F"))[0].depth_m == pytest.approx(32.8 * 0.3048)


@pytest.mark.parametrize("line,counter", [
    (b"$SDDPT,-1.0,0.1", "bad_fields"),            # a negative depth
    (b"$SDDPT,deep,0.1", "bad_fields"),
    (b"$SDDBT,1,x,2,M,1,F", "bad_fields"),
    (b"$SD DPT,1,0.1", "bad_fields"),
])
def test_sentences_that_make_no_depth_are_counted(line, counter):
    body = line[1:].decode()
    p = DepthParser()
    assert p.feed(sentence(body)) == []
    assert getattr(p.counters, counter) == 1


def test_garbage_overlong_lines_and_cut_sentences_are_counted_and_the_next_ping_is_found():
    p = DepthParser()
    stream = b"\x00\xff noise" + b"$SDDPT," + b"9" * 120 + b"\r\n" + b"$SDDPT,1.0" + dpt(2.0, 0.1)
    pings = p.feed(stream)
    assert [x.depth_m for x in pings] == [2.0]
    assert p.counters.garbage_bytes > 0 and p.counters.overlong == 1


STREAM = (dpt(1.5, 0.1) + b"junk\r\n" + dbt(2.25) + b"$SDDPT,3.0,0.1*00\r\n" + sentence("SDDPT,,0.1")
          + b"\x00" * 5 + dpt(4.75, -0.3, max_range_m=80.0))


@settings(max_examples=60, deadline=None)
@given(cuts=st.lists(st.integers(1, 40), min_size=1, max_size=30))
def test_what_the_parser_returns_does_not_depend_on_the_reads(cuts):
    whole = DepthParser().feed(STREAM)
    p, got, i = DepthParser(), [], 0
    for n in cuts * 20:
        if i >= len(STREAM):
            break
        got += p.feed(STREAM[i:i + n])
        i += n
    got += p.feed(STREAM[i:])
    assert [(x.sentence, x.depth_m if not math.isnan(x.depth_m) else None) for x in got] == \
        [(x.sentence, x.depth_m if not math.isnan(x.depth_m) else None) for x in whole]
    assert len(whole) == 4


@settings(max_examples=100, deadline=None)
@given(data=st.binary(max_size=400), flips=st.lists(st.integers(0, 10_000), max_size=20))
def test_random_bytes_and_bit_flips_never_crash_the_parser(data, flips):
    good = bytearray(STREAM * 3)
    for f in flips:
        good[f % len(good)] ^= 1 << (f % 8)
    p = DepthParser()
    for x in p.feed(data) + p.feed(bytes(good)):
        assert math.isnan(x.depth_m) or 0.0 <= x.depth_m <= 1000.0


BED = LakeBedSection(depths_m=((2.0, 3.0, 4.0), (2.5, 3.5, 6.0), (3.0, 4.0, 5.0)), origin_m=(-20.0, -20.0), cell_m=20.0,
                     sounder_dropout=0.1)


def test_the_driver_reads_the_twins_nmea_as_the_simulator_pinged():
    cfg = LaunchConfig(sim=SimSection(lakebed=BED))
    stack = Stack(config=cfg, executor=SimExecutor(), model=VesselModel())
    hw = HardwareConfig(echosounder=EchosounderSection(enabled=True))
    boat = add_hardware_boat(stack, emulated=True, config=hw)
    sent: list[DepthSample] = []
    twin = boat.twin.sounder
    emit = twin.emit
    twin.emit = lambda m: (sent.append(m), emit(m))
    got = defaultdict(list)
    stack.bus.subscribe_all(lambda t, m: got[t].append(m))
    stack.executor.run_until(10.0)
    stack.executor.shutdown()
    depths = got[Topic.DEPTH]
    assert len(sent) == 51 and len(depths) >= 49          # 5 Hz over 0-10 s; the first before the port opened
    first = next(k for k, s in enumerate(sent) if abs(s.depth_m - depths[0].depth_m) < 0.005
                 or (math.isnan(s.depth_m) and math.isnan(depths[0].depth_m)))
    assert first <= 1
    for d, s in zip(depths, sent[first:]):                             # DPT wins over the DBT of the same ping
        assert d.sentence == "SDDPT"
        if math.isnan(s.depth_m):
            assert math.isnan(d.depth_m)
        else:
            assert d.depth_m == pytest.approx(s.depth_m, abs=0.005)     # two decimals on the wire
    assert 1 <= sum(math.isnan(d.depth_m) for d in depths) <= 12        # the 10 % dropouts arrive as no bottom
    assert boat.drivers["echosounder"].health.dropped == 0


def test_corrupt_bytes_from_the_twin_are_counted_not_published():
    cfg = LaunchConfig(sim=SimSection(lakebed=BED))
    stack = Stack(config=cfg, executor=SimExecutor(), model=VesselModel())
    boat = add_hardware_boat(stack, emulated=True, config=HardwareConfig(echosounder=EchosounderSection(enabled=True)))
    boat.twin.sounder.corrupt_probability = 0.01
    got = defaultdict(list)
    stack.bus.subscribe_all(lambda t, m: got[t].append(m))
    stack.executor.run_until(10.0)
    stack.executor.shutdown()
    node = boat.drivers["echosounder"]
    assert node.health.dropped > 0
    bed = np.asarray(BED.depths_m)
    for d in got[Topic.DEPTH]:
        assert math.isnan(d.depth_m) or bed.min() - 1 < d.depth_m < bed.max() + 1
