import math

import pytest
from hypothesis import given, strategies as st

from lotsen.drivers.actuators import (
    TICK_WRAP, ActuatorNode, PropellerSpeedLoop, Tachometer, esc_rps, esc_us, servo_angle, servo_us,
)
from lotsen.drivers.config import ActuatorSection, EscCalibration, ServoCalibration, SpeedLoopGains
from lotsen.drivers.emulated import EmulatedPigpio
from lotsen.messages import ThrustCommand


@given(st.floats(-100, 100))
def test_esc_calibration_is_invertible_and_skips_the_deadband(n):
    cal = EscCalibration(deadband_us=25.0)
    us = esc_us(cal, n)
    assert 1000.0 <= us <= 2000.0
    if n != 0.0:
        assert abs(us - 1500.0) >= 25.0
    assert esc_rps(cal, us) == pytest.approx(n, abs=1e-9)


def test_esc_neutral_reverse_and_sign():
    cal = EscCalibration(n_max_reverse_rps=50.0, sign=-1.0)
    assert esc_us(cal, 0.0) == 1500.0 and esc_us(cal, math.nan) == 1500.0
    assert esc_us(cal, 25.0) == pytest.approx(1500 - 25 - 475 * 0.5)  # sign -1: forward is the reverse pulse
    assert esc_rps(EscCalibration(), 1510.0) == 0.0 and esc_rps(EscCalibration(), 0) == 0.0


@given(st.floats(-0.7, 0.7))  # within the pulse limits with the trim
def test_servo_calibration_round_trip(alpha):
    cal = ServoCalibration(center_us=1480.0, sign=-1.0)
    assert servo_angle(cal, servo_us(cal, alpha)) == pytest.approx(alpha, abs=1e-9)


def test_tachometer_uses_edge_times_and_handles_tick_wrap():
    tach = Tachometer(pulses_per_rev=6, timeout_s=0.5)
    t0 = TICK_WRAP - 30_000  # wraps during the run
    period = int(1e6 / (6 * 37.0))  # 37 rev/s
    tick = t0
    speeds = []
    for window in range(10):
        for _ in range(4):
            tick += period
            tach.on_edge(17, 1, tick % TICK_WRAP)
        speeds.append(tach.measure((tick + 1000) % TICK_WRAP))
    assert speeds[-1] == pytest.approx(37.0, rel=1e-3)
    assert tach.measure((tick + 600_000) % TICK_WRAP) == 0.0  # no pulses: 0 after the timeout


def test_speed_loop_removes_gain_error_without_windup():
    """First-order motor with 20 % less gain than the calibration assumes."""
    g = SpeedLoopGains()
    loop = PropellerSpeedLoop(g, 100.0, 100.0)
    n, dt, tau = 0.0, 0.02, 0.08
    for _ in range(150):
        u = loop.update(40.0, n, dt)
        n += (0.8 * u - n) * (1 - math.exp(-dt / tau))
    assert n == pytest.approx(40.0, abs=0.5)
    # impossible set-point: output saturates, the integral stays bounded
    for _ in range(500):
        u = loop.update(100.0, n, dt)
        n += (0.8 * u - n) * (1 - math.exp(-dt / tau))
    assert u == 100.0 and abs(loop.integral) <= g.integral_limit_rps
    assert loop.update(0.5, n, dt) == 0.0 and loop.integral == 0.0  # below min speed: neutral, reset


def run_node(cfg, commands, duration_s, edges_per_s=None, stop_commands_at=None):
    pi = EmulatedPigpio()
    node = ActuatorNode(cfg, lambda: pi, command_deadline_s=0.5)
    out = []
    k = 0
    t = 0.0
    node.step(0.0)
    while t < duration_s:
        k += 1
        t = k * node.period_s
        pi.tick_us = int(t * 1e6)
        if edges_per_s:
            for pin, rate in edges_per_s.items():
                for j in range(int(rate * t) - int(rate * (t - node.period_s))):
                    pi.edge(pin, int((t - node.period_s) * 1e6) + j * 100)
        if stop_commands_at is None or t < stop_commands_at:
            node.guard.accept(ThrustCommand.from_tuple(t, commands), t)
        out += node.step(t)
    return node, pi, out


def test_arming_holds_neutral_then_stale_command_goes_neutral():
    cfg = ActuatorSection(arm_time_s=1.0, speed_loop=SpeedLoopGains(enabled=False))
    node, pi, out = run_node(cfg, (0.2, -0.2, 30.0, 30.0, -20.0), 0.9)
    assert [pi.pulse_us[p] for p in cfg.esc_pins] == [1500, 1500, 1500]  # not armed yet
    assert pi.pulse_us[19] == round(servo_us(cfg.servo[0], 0.2))  # servos move at once
    node, pi, out = run_node(cfg, (0.2, -0.2, 30.0, 30.0, -20.0), 2.0)
    assert pi.pulse_us[16] == round(esc_us(cfg.esc[0], 30.0)) and pi.pulse_us[21] < 1475
    node, pi, out = run_node(cfg, (0.2, -0.2, 30.0, 30.0, -20.0), 3.0, stop_commands_at=2.0)
    assert [pi.pulse_us[p] for p in cfg.esc_pins] == [1500, 1500, 1500]
    assert any("stale" in m.text for _, m in out if hasattr(m, "text"))
    node.stop()
    assert all(v == 0 for v in pi.pulse_us.values()) and pi.stopped  # shutdown: neutral then pulses off


def test_nan_command_is_neutral_at_once():
    cfg = ActuatorSection(arm_time_s=0.0)
    node, pi, _ = run_node(cfg, (0.0, 0.0, math.nan, 30.0, 0.0), 0.5)
    assert [pi.pulse_us[p] for p in cfg.esc_pins] == [1500, 1500, 1500]


def test_silent_tachometer_is_reported_and_the_loop_falls_back_to_feedforward():
    cfg = ActuatorSection(arm_time_s=0.0)
    # thruster 2 has pulses (so it is measured), thruster 1's tachometer is silent
    node, pi, out = run_node(cfg, (0.0, 0.0, 40.0, 40.0, 0.0), 3.0, edges_per_s={27: 240})
    texts = [m.text for _, m in out if hasattr(m, "text")]
    assert any("GPIO 17: no pulses" in t for t in texts)
    assert node.motors[0].tacho_fault and not node.motors[1].tacho_fault
    assert pi.pulse_us[16] == round(esc_us(cfg.esc[0], 40.0))  # feedforward only, no windup
    assert node.motors[1].n_meas == pytest.approx(40.0, rel=0.05)


def test_escs_armed_is_reported_truthfully_through_arming_and_a_lost_pigpio_link():
    """AUTO needs armed ESCs (the supervisor refuses it otherwise): the driver's ActuatorState
    says False during the arming time, True after it, False at once when the pigpio link is lost,
    and True again only after reopening and a new arming time of neutral pulses."""
    from lotsen.messages import ActuatorState, Topic

    cfg = ActuatorSection(arm_time_s=1.0, speed_loop=SpeedLoopGains(enabled=False))
    pi = EmulatedPigpio()
    node = ActuatorNode(cfg, lambda: pi, command_deadline_s=0.5)
    node.reopen_s = 0.1
    link_down = (2.0, 2.5)
    real_tick = pi.get_current_tick

    def tick():
        if link_down[0] <= t < link_down[1]:
            raise OSError("pigpio: connection reset")
        return real_tick()

    pi.get_current_tick = tick
    states: list[tuple[float, bool]] = []
    for k in range(451):
        t = k * node.period_s
        pi.tick_us = int(t * 1e6)
        node.guard.accept(ThrustCommand.from_tuple(t, (0.0, 0.0, 30.0, 30.0, 0.0)), t)
        states += [(t, m.escs_armed) for topic, m in node.step(t) if topic == Topic.ACTUATORS
                   and isinstance(m, ActuatorState)]
    armed = lambda a, b: {v for s, v in states if a <= s < b}  # noqa: E731
    assert armed(0.0, 0.99) == {False} and armed(1.05, 2.0) == {True}
    assert (2.0, False) in states  # said at the moment the link broke
    # reopened at ~2.5 s: neutral again for arm_time_s before "armed"
    assert armed(2.0, 3.49) == {False} and armed(3.6, 4.5) == {True}
