import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from lotsen.drivers.config import ImuSection
from lotsen.drivers.emulated import Ak8963Twin, EmulatedI2CBus, Mpu9250Twin
from lotsen.drivers.imu import (
    ImuNode, Mpu9250, RegisterError, ak_to_chip, body_to_chip, chip_to_body, decode_accel_gyro, decode_mag,
    parse_axes,
)
from lotsen.messages import Topic


def make(axes=("+x", "-y", "-z"), **kw):
    cfg = ImuSection(axes=axes, **kw)
    bus = EmulatedI2CBus()
    bus.mpu, bus.ak = Mpu9250Twin(axes), Ak8963Twin(axes)
    m = Mpu9250(bus, cfg, sleep=lambda s: None)
    m.init()
    return m, bus


def test_at_rest_level_reads_minus_g_on_body_z_and_the_chip_sees_plus_g_up():
    m, bus = make()
    bus.mpu.set_sample((0.0, 0.0, 0.0), (0.0, 0.0, -9.81))
    raw_z = int.from_bytes(bytes(bus.mpu.regs[0x3F:0x41]), "big", signed=True)
    assert raw_z == round(9.81 / 9.80665 * 8192)  # +1 g on chip z (face up), 8192 LSB/g at +-4 g
    gyro, accel = m.read_imu()
    assert accel[2] == pytest.approx(-9.81, abs=2e-3) and abs(accel[0]) < 1e-9


@pytest.mark.parametrize("axes", [("+x", "-y", "-z"), ("-y", "-x", "-z"), ("+z", "+x", "+y")])
def test_body_values_survive_the_registers_for_any_mounting(axes):
    m, bus = make(axes, gyro_range_dps=1000, accel_range_g=8)
    g, a, f = (0.1, -0.2, 0.3), (1.0, -2.0, -9.81), (12.0, -5.0, 47.0)
    bus.mpu.set_sample(g, a)
    bus.ak.set_field(f)
    gyro, accel = m.read_imu()
    assert np.allclose(gyro, g, atol=math.radians(1000) / 32768) and np.allclose(accel, a, atol=8 * 9.81 / 32768)
    mag = m.read_mag()
    assert np.allclose(mag, f, atol=0.15 * 1.25)
    assert m.read_mag() is None  # ST2 read cleared DRDY: no new sample


def test_ak8963_axes_and_sensitivity_adjustment():
    assert ak_to_chip((1.0, 2.0, 3.0)) == (2.0, 1.0, -3.0)  # x_mag = y_acc, y_mag = x_acc, z_mag = -z_acc
    m, bus = make()
    assert m.scales.mag_uT_per_lsb[0] == pytest.approx(0.15 * ((176 - 128) / 256 + 1))


def test_axes_round_trip_and_validation():
    ax = parse_axes(("-y", "+z", "-x"))
    v = (1.0, 2.0, 3.0)
    assert chip_to_body(body_to_chip(v, ax), ax) == v
    with pytest.raises(ValueError):
        parse_axes(("+x", "+x", "-z"))


def test_wrong_who_am_i_and_missing_magnetometer():
    bus = EmulatedI2CBus()
    bus.mpu = Mpu9250Twin()
    bus.mpu.regs[0x75] = 0x68  # an MPU6050
    with pytest.raises(RegisterError, match="WHO_AM_I"):
        Mpu9250(bus, ImuSection(), sleep=lambda s: None).init()
    bus.mpu.regs[0x75] = 0x71
    with pytest.raises(OSError):  # AK8963 absent: NACK
        Mpu9250(bus, ImuSection(), sleep=lambda s: None).init()


def test_node_counts_i2c_errors_and_goes_on():
    bus = EmulatedI2CBus(rng=np.random.default_rng(3))
    bus.mpu, bus.ak = Mpu9250Twin(), Ak8963Twin()
    node = ImuNode(ImuSection(), lambda: bus, sleep=lambda s: None)
    node.step(0.0)  # opens
    bus.error_probability = 0.3
    out = [m for k in range(1, 201) for m in node.step(k * 0.01)]
    imu = [m for t, m in out if t == Topic.IMU_RAW]
    logs = [m for t, m in out if t == Topic.LOG]
    errs = node.health.counters["i2c_errors"]
    assert 100 < len(imu) < 180 and errs > 20 and len(imu) + errs == 200
    assert logs and logs[0].level == "warning" and len(logs) < 10  # reported, not flooded


def test_missing_device_is_reported_and_retried():
    bus = EmulatedI2CBus()  # nothing on it
    node = ImuNode(ImuSection(), lambda: bus, sleep=lambda s: None)
    out = node.step(0.0)
    assert not node.health.opened and out[0][1].level == "error" and "cannot open" in out[0][1].text
    bus.mpu, bus.ak = Mpu9250Twin(), Ak8963Twin()
    node.step(1.0)
    assert not node.health.opened  # retried only every reopen_s
    node.step(2.5)
    assert node.health.opened


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=20))
def test_register_decoders_fuzz(block):
    for decode in (decode_accel_gyro, decode_mag):
        try:
            decode(block)
        except RegisterError:
            pass
