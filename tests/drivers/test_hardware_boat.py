"""The real driver code end to end against the emulated devices on a SimExecutor."""

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from lotsen.cli.main import main
from lotsen.drivers import HardwareConfig
from lotsen.stack.hardware import add_hardware_boat
from lotsen.errors import ConfigError
from lotsen.messages import ThrustCommand, Topic
from lotsen.model import VesselModel
from lotsen.runtime.config import LaunchConfig
from lotsen.runtime.executor import SimExecutor
from lotsen.stack.config import load_stack_config, stack_config
from lotsen.stack.stack import Stack

DEPLOY = Path(__file__).resolve().parents[2] / "deploy" / "hardware.yaml"
COMMAND = (0.15, 0.15, 40.0, 40.0, -20.0)


def emulated_stack(hw=HardwareConfig(), command=COMMAND, stop_commands_at=math.inf):
    stack = Stack(config=LaunchConfig(), executor=SimExecutor(), model=VesselModel())
    boat = add_hardware_boat(stack, emulated=True, config=hw)
    got = defaultdict(list)
    stack.bus.subscribe_all(lambda t, m: got[t].append(m))
    ex = stack.executor

    def send():
        if ex.clock.now() < stop_commands_at:
            stack.bus.publish(Topic.SHIP_COMMAND, ThrustCommand.from_tuple(ex.clock.now(), command))

    ex.add_timer(0.1, send)
    return stack, boat, got


@pytest.fixture(scope="module")
def run20():
    stack, boat, got = emulated_stack()
    twin = boat.twin
    emitted, imu_in = [], []
    emit = twin.zed.emit
    # the fixes the receiver outputs as NAV-PVT (before the driver's VALSET it sends NMEA only)
    twin.zed.emit = lambda fix, t: (twin.zed.nav_pvt_on and emitted.append(fix), emit(fix, t))
    set_sample = twin.i2c.mpu.set_sample
    twin.i2c.mpu.set_sample = lambda g, a: (imu_in.append((g, a)), set_sample(g, a))
    stack.executor.run_until(20.0)
    yield stack, boat, got, emitted, imu_in
    stack.executor.shutdown()


def test_gnss_fixes_are_the_simulators_through_ubx(run20):
    stack, boat, got, emitted, _ = run20
    fixes = got[Topic.GNSS]
    assert len(fixes) >= 158 and len(emitted) - len(fixes) <= 1  # 8 Hz, at most one in flight
    for f, e in zip(fixes, emitted):
        assert abs(f.lat_deg - e.lat_deg) <= 0.6e-7 and abs(f.lon_deg - e.lon_deg) <= 0.6e-7  # 1e-7 deg LSB
        assert f.fix_type == e.fix_type and abs(f.vel_n_mps - e.vel_n_mps) <= 0.0006
    # and the truth: the last fix within RTK noise + quantisation of the simulated position
    sim = stack.simulator
    g = sim.gnss
    n, e = g.frame.to_ne(fixes[-1].lat_deg, fixes[-1].lon_deg, fixes[-1].height_m)
    truth = [m for m in got[Topic.TRUTH] if abs(m.stamp_s - fixes[-1].stamp_s) < 0.06][0]
    assert math.hypot(n - truth.north_m, e - truth.east_m) < 0.06 + 0.05  # noise + <= 50 ms of motion


def test_imu_samples_are_the_simulators_through_registers(run20):
    _, _, got, _, imu_in = run20
    samples = got[Topic.IMU_RAW]
    assert len(samples) == len(imu_in) == 2001
    g_lsb, a_lsb = math.radians(500) / 32768, 4 * 9.80665 / 32768
    # sample 0 was written before the driver woke the chip up (the twin ignores writes while asleep)
    pairs = list(zip(samples, imu_in))[1:]
    gyro_err = max(abs(s.gyro_radps[i] - g[i]) for s, (g, a) in pairs for i in range(3))
    accel_err = max(abs(s.accel_mps2[i] - a[i]) for s, (g, a) in pairs for i in range(3))
    assert gyro_err <= 0.51 * g_lsb and accel_err <= 0.51 * a_lsb
    mags = got[Topic.IMU_MAG]
    assert 950 <= len(mags) <= 1001  # 50 Hz
    assert np.linalg.norm(mags[-1].field_uT) == pytest.approx(np.linalg.norm((15.5, 0, 47)), rel=0.25)


def test_propeller_speed_loop_reaches_the_commanded_speed(run20):
    stack, boat, got, _, _ = run20
    rpm = [m for m in got[Topic.RPM] if m.stamp_s > 10.0]
    n1 = np.mean([m.n1_rps for m in rpm])
    nt = np.mean([m.nt_rps for m in rpm])
    assert n1 == pytest.approx(40.0, abs=0.4) and nt == pytest.approx(-20.0, abs=0.4)
    true = stack.simulator.actuators.state
    assert true[2] == pytest.approx(40.0, abs=0.5) and true[4] == pytest.approx(-20.0, abs=0.5)
    # the true ESCs make only 85 % / 80 % of the calibrated speed: the loop had to add the rest
    act = boat.drivers["actuators"]
    assert act.motors[0].loop.integral > 4.0
    assert stack.simulator.actuators.state[0] == pytest.approx(0.15, abs=1e-3)  # servo angle via pulses
    assert not any(m.level == "error" for m in got[Topic.LOG])


def test_battery_and_health(run20):
    _, boat, got, _, _ = run20
    b = got[Topic.BATTERY]
    assert len(b) == 41 and 12.0 < b[-1].voltage_v < 12.7 and b[-1].current_a > 0.6
    for h in boat.health():
        assert h.ok and h.errors == 0, h


def test_stale_command_goes_neutral_and_shutdown_stops_the_pulses():
    stack, boat, got = emulated_stack(stop_commands_at=8.0)
    stack.executor.run_until(11.0)
    sim = stack.simulator
    assert all(abs(v) < 1.0 for v in sim.actuators.state[2:])
    assert any("stale" in m.text for m in got[Topic.LOG])
    stack.executor.shutdown()
    assert all(v == 0 for v in boat.twin.pi.pulse_us.values())


def test_bad_bytes_and_i2c_errors_end_to_end_are_counted_and_survived():
    stack, boat, got = emulated_stack()
    boat.twin.zed.corrupt_probability = 0.3
    boat.twin.tacho_failed = {2}
    stack.executor.run_until(0.5)  # devices opened (an init that meets an I2C error is retried after 2 s)
    boat.twin.i2c.error_probability = 0.05
    stack.executor.run_until(8.0)
    d = boat.drivers
    assert d["gnss"].health.counters["bad_checksums"] > 5 and len(got[Topic.GNSS]) > 25
    assert d["imu"].health.counters["i2c_errors"] > 10 and len(got[Topic.IMU_RAW]) > 650
    assert d["actuators"].motors[2].tacho_fault and d["actuators"].motors[0].n_meas == pytest.approx(40, abs=1.5)
    assert stack.executor.timer_errors == 0 and stack.bus.stats.callback_errors == 0
    stack.executor.shutdown()


def test_rtk_needs_corrections_forwarded_from_the_bus():
    from lotsen.drivers.config import EmulationSection
    from lotsen.messages import GnssFixType, RtcmData

    from .capture import rtcm_frame

    hw = HardwareConfig(emulation=EmulationSection(rtk_requires_corrections=True))
    stack, boat, got = emulated_stack(hw)
    frame = rtcm_frame(b"\x3e\xd0" + bytes(17))
    base_station = stack.executor.add_timer(1.0, lambda: stack.bus.publish(Topic.RTCM, RtcmData(stamp_s=0.0, data=frame)), phase_s=3.0)
    stack.executor.run_until(6.0)
    fixes = got[Topic.GNSS]
    early = [f for f in fixes if f.stamp_s < 2.9]
    late = [f for f in fixes if f.stamp_s > 3.5]
    assert all(f.fix_type == GnssFixType.FIX_3D for f in early)
    assert all(f.fix_type == GnssFixType.RTK_FIXED for f in late)
    assert all(f.correction_age_s <= 1.05 for f in late) and boat.twin.zed.rtcm_frames == 4  # t = 3, 4, 5, 6 s
    # the base station goes quiet: warned after correction_timeout_s, RTK lost after the twin's 5 s
    base_station.cancel()
    stack.executor.run_until(20.0)
    texts = [m.text for m in got[Topic.LOG]]
    assert any("no RTCM corrections for" in t for t in texts)
    assert got[Topic.GNSS][-1].fix_type == GnssFixType.FIX_3D
    stack.executor.shutdown()


def test_deploy_config_loads_and_typos_are_named():
    config = load_stack_config(DEPLOY)
    hw = config.extra.hardware
    assert hw.actuators.esc_pins == (16, 20, 21) and hw.actuators.servo_pins == (19, 26)
    assert hw.actuators.tacho_pins == (17, 27, 22) and hw.imu.address == 0x68 and hw.battery.address == 0x40
    assert config.mode == "hardware"
    with pytest.raises(ConfigError, match=r"extra.hardware.gnss.baudrat: unknown key \(did you mean 'baudrate'"):
        stack_config(LaunchConfig(extra={"hardware": {"gnss": {"baudrat": 9600}}}))


@pytest.mark.live  # the twins run at wall-clock pace: their rates in a 0.6 s window are the check
def test_check_command_against_the_twins(capsys):
    assert main(["check", "--emulated", "--duration", "0.6"]) == 0
    out = capsys.readouterr().out
    assert "all devices OK" in out and "configured=yes" in out
    assert "imu: emulated MPU9250" in out
    assert "rc: emulated X8R SBUS" in out and "link ok, takeover off, e-stop off" in out


def test_rate_meter_leaves_the_opening_bursts_out():
    """`lotsen check` measures after the devices settle: what queued while the GNSS was being
    configured arrives in bursts that, in a short window, are most of the intervals."""
    from lotsen.drivers.base import RateMeter

    m = RateMeter(window_s=10.0)
    t = 0.0
    for _ in range(30):  # the backlog read at opening: 30 messages 2 ms apart
        m.tick(t)
        t += 0.002
    t = 1.0
    for _ in range(9):  # then an 8-Hz receiver: 9 messages, 8 intervals
        m.tick(t)
        t += 0.125
    assert m.rate() > 100.0  # the bursts' intervals are the median: a 4 Hz device would pass as 500 Hz
    assert m.rate(since_s=1.0) == pytest.approx(8.0)
    assert m.rate(since_s=1.1) == pytest.approx(8.0)  # the interval ending at 1.125 s counts whole
    assert m.rate(since_s=99.0) == 0.0
    single = RateMeter()
    single.tick(0.0)
    assert single.rate() == 0.0
