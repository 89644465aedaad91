"""Failsafe monitors as pure objects: the thruster monitor against the modelled ESC response."""

import math

import numpy as np

from lotsen.messages import RpmSample, ThrustCommand
from lotsen.model import DEFAULT_LIMITS
from lotsen.sim.actuators import ActuatorDynamics
from lotsen.supervisor.failsafes import FailsafeConfig, PersistentCondition, ThrusterMonitor
from lotsen.supervisor.node import SupervisorInputs


def drive(commands, failed=(), noise_rps=1.5, armed=True, seed=0, delay_s=0.0, cfg=None):
    """Commands at 10 Hz through the simulator's actuator model (reaching it `delay_s` after the
    monitor saw them leave), tachometers at 20 Hz: returns the times at which the monitor's
    (persistent) condition was active."""
    rng = np.random.default_rng(seed)
    cfg = cfg or FailsafeConfig()
    mon = ThrusterMonitor(cfg, DEFAULT_LIMITS)
    delay = round(delay_s / 0.01)
    act = ActuatorDynamics(DEFAULT_LIMITS, dt_s=0.01)
    act.set_faults(failed_units=set(failed))
    inputs = SupervisorInputs()
    active = []
    for k in range(len(commands) * 10):
        t = k * 0.01
        if k % 10 == 0:
            n = commands[k // 10]
            cmd = ThrustCommand(stamp_s=t, n1_rps=n, n2_rps=n, nt_rps=0.0)
            mon.on_command(cmd, t, escs_armed=armed)
        if (k - delay) % 10 == 0 and k >= delay:
            n = commands[(k - delay) // 10]
            act.set_command(*((0.0, 0.0, n, n, 0.0) if armed else (0.0,) * 5))
        state = act.step()
        if k % 5 == 4:
            meas = [v + noise_rps * rng.standard_normal() for v in state[2:]]
            mon.on_rpm(RpmSample(stamp_s=t + 0.01, n1_rps=meas[0], n2_rps=meas[1], nt_rps=meas[2]), None)
        if k % 10 == 0 and mon.update(inputs, t):
            active.append(t)
    return active


def test_propeller_reversals_are_no_thruster_fault():
    # a full reversal at every 10 Hz command (the MPC chattering): the propellers lag, the model knows it
    commands = [60.0 if i % 2 == 0 else -60.0 for i in range(300)]
    assert drive(commands) == []
    # ... while comparing with the commands themselves (the old monitor) declares a fault
    act = ActuatorDynamics(DEFAULT_LIMITS, dt_s=0.01)
    cond = PersistentCondition(FailsafeConfig().thruster_persist_s, 2.0)
    fired = False
    for k in range(3000):
        n = commands[k // 10]
        act.set_command(0.0, 0.0, n, n, 0.0)
        meas = act.step()[2]
        fired |= cond.update(abs(meas - n) > max(0.5 * abs(n), 8.0), k * 0.01)
    assert fired


def test_commands_that_reach_the_escs_late_are_no_thruster_fault():
    """Reversals at every command, each reaching the ESCs 0.1 s after it left the supervisor (bus,
    driver, PWM): within the latency window no alarm; a monitor without it raises a false one."""
    commands = [60.0 if i % 2 == 0 else -60.0 for i in range(300)]
    assert drive(commands, delay_s=0.1) == []
    assert drive(commands, delay_s=0.1, cfg=FailsafeConfig(thruster_latency_s=0.0)) != []


def test_a_failed_motor_is_declared_within_the_persistence_time():
    commands = [50.0] * 100
    active = drive(commands, failed=(0,), delay_s=0.1)
    assert active, "a dead azimuth motor went unnoticed"
    assert active[0] <= FailsafeConfig().thruster_persist_s + 0.3  # model settles in ~0.2 s


def test_escs_not_armed_means_no_thrust_expected():
    assert drive([50.0] * 50, armed=False, noise_rps=0.0) == []


def test_persistent_condition_needs_persistence_and_clears_with_hysteresis():
    c = PersistentCondition(0.5, 1.0)
    assert not c.update(True, 0.0) and not c.update(True, 0.4) and c.update(True, 0.5)
    assert c.update(False, 0.6) and c.update(False, 1.5) and not c.update(False, 1.6)
    assert c.activations == 1 and math.isfinite(c.persist_s)


def test_a_dead_motor_driven_in_short_astern_pulses_is_declared():
    """In a turn the MPC drives a propeller in short astern pulses around zero (bench azimuth_failure,
    seed 2). Between the pulses a stopped motor reads like a running one, so the sample-by-sample
    persistence restarts at every pulse and never declares it; the mean speed over 2 x persist_s
    does, once the window is full, and the same pulses on a healthy motor raise nothing."""
    persist = FailsafeConfig().thruster_persist_s
    for pulse in ([-32.0, -18.0, 3.0, 3.0, 3.0], [-35.0, -26.0, -13.0, 3.0, 3.0]):
        commands = pulse * 40
        active = drive(commands, failed=(0,), delay_s=0.1)
        assert active and active[0] <= 2.0 * persist + 0.15, (pulse, active[:1])
        assert drive(commands, delay_s=0.1) == []
