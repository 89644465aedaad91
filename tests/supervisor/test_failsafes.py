"""Failsafe monitors as pure objects: the thruster monitor against the modelled ESC response; the
geofence, dead-reckoning, controller and estimator monitors asking the mode object what it is."""

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


# ------------------------------------------------------------------ monitors that ask the mode
def _state(north_m, east_m, std_m=0.05):
    from lotsen.messages import VesselState

    return VesselState(stamp_s=0.0, north_m=north_m, east_m=east_m, heading_rad=0.0, u_mps=0.0, v_mps=0.0,
                       r_radps=0.0, std=(std_m,) * 6)


def test_geofence_trips_after_its_persistence_and_holds_inside_only_in_fenced_modes():
    from lotsen.planning.route import HarbourNode, Route, RouteNode
    from lotsen.supervisor.failsafes import FailsafeAction, GeofenceMonitor
    from lotsen.supervisor.modes import all_modes

    modes = all_modes()
    cfg = FailsafeConfig(geofence_persist_s=0.3, geofence_inset_m=1.5)
    mon = GeofenceMonitor(cfg)
    inputs = SupervisorInputs(route=Route(HarbourNode(5.0, 5.0, 0.0), (RouteNode(8.0, 8.0, 0.0, 0.5),),
                                          area=((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0))))
    inputs.state = _state(5.0, 10.5)  # 0.5 m east of the east edge
    assert not mon.update(inputs, 0.0) and not mon.update(inputs, 0.2) and mon.update(inputs, 0.3)
    assert "outside the navigable area" in mon.reason
    assert {m: mon.action_for(modes[m]) for m in modes} == {
        "MANUAL": "continue", "AUTO": "hold_inside", "HOLD": "hold_inside", "RETURN": "hold_inside",
        "CALIBRATE": "continue", "ESTOP": "continue", "RC": "continue", "EXPERIMENT": "hold_inside"}
    north, east, heading = mon.hold_target(inputs)
    assert abs(north - 5.0) < 1e-6 and abs(east - 8.5) < 1e-6  # 1.5 m inside
    assert abs(heading - (-math.pi / 2)) < 1e-6  # bow toward the water it was pushed out of
    in_manual = GeofenceMonitor(FailsafeConfig(geofence_in_manual=True))
    assert in_manual.action_for(modes["MANUAL"]) is FailsafeAction.HOLD_INSIDE
    inputs.state = _state(5.0, 10.5, std_m=5.0)  # an estimate not trusted does not judge the fence
    assert mon.check(inputs, 1.0) == (False, "")


def test_dead_reckoning_stops_after_gnss_stop_after_s_of_its_sources():
    from lotsen.supervisor.failsafes import DeadReckoningMonitor, FailsafeAction, GnssLostMonitor
    from lotsen.supervisor.modes import all_modes

    cfg = FailsafeConfig(gnss_lost_s=1.5, gnss_stop_after_s=20.0)
    lost = GnssLostMonitor(cfg)
    dr = DeadReckoningMonitor(cfg, [lost])
    inputs = SupervisorInputs(last_usable_fix_s=0.0)
    tripped = None
    for k in range(300):
        t = k * 0.1
        lost.update(inputs, t)
        if dr.update(inputs, t) and tripped is None:
            tripped = t
    assert tripped is not None and abs(tripped - (1.6 + 20.0)) < 0.15
    modes = all_modes()
    assert {m for m in modes if dr.action_for(modes[m]) is FailsafeAction.STOP} == {"HOLD", "AUTO", "RETURN",
                                                                                "EXPERIMENT"}
    inputs.last_usable_fix_s = 30.0  # a fix again: released at once
    lost.update(inputs, 30.0), lost.update(inputs, 31.1)
    assert not dr.update(inputs, 31.1)


def test_controller_monitor_counts_consecutive_failures_and_overruns():
    from lotsen.supervisor.failsafes import ControllerMonitor

    mon = ControllerMonitor(FailsafeConfig(controller_failure_count=3, controller_overrun_count=5,
                                           controller_overrun_factor=0.8), period_s=0.1)
    assert [mon.observe(s, 5.0) for s in ("fallback_plan (x)", "ok", "safe_stop", "failed")] == ["", "", "", ""]
    assert "3 failed updates (fallback_plan (y))" == mon.observe("fallback_plan (y)", 5.0)
    assert mon.failures == 0  # counted afresh after it tripped
    assert [mon.observe("ok", 81.0) for _ in range(5)][-1] == "5 overruns (81.0 ms)"
    assert all(mon.observe("ok", 79.0) == "" for _ in range(20))


def test_estimator_heading_loss_stops_every_mode_that_needs_a_heading():
    from lotsen.messages import EstimatorHealth
    from lotsen.supervisor.failsafes import EstimatorMonitor, FailsafeAction
    from lotsen.supervisor.modes import all_modes

    mon = EstimatorMonitor(FailsafeConfig())
    mon.check(SupervisorInputs(health=EstimatorHealth(stamp_s=0.0, position_ok=True, heading_ok=False, velocity_ok=True)), 0.0)
    modes = all_modes()
    stops = {m for m in modes if mon.action_for(modes[m]) is FailsafeAction.STOP}
    assert stops == {m for m, mode in modes.items() if mode.requires_heading} == {"AUTO", "RETURN", "HOLD", "CALIBRATE",
                                                                                  "EXPERIMENT"}


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


def test_progress_monitor_warns_when_the_boat_does_not_get_along_its_route():
    """A start stalled in a strong beam current (docs/control.md "Limits": 95 s at the route's first
    point) is named to the operator; a boat at a third of its planned speed, a lap's restart and a
    HOLD in between are not a stall."""
    from lotsen.supervisor.failsafes import ProgressMonitor

    mon = ProgressMonitor(FailsafeConfig(no_progress_window_s=30.0, no_progress_fraction=0.25))
    dt, t, s = 0.1, 0.0, 0.0
    said = []
    for _ in range(600):  # 60 s at 0.02 m/s made good where 0.5 m/s is planned
        t, s = t + dt, s + 0.02 * dt
        said.append(mon.observe(t, s, 0.5))
    first = next(i for i, (on, _) in enumerate(said) if on)
    assert 29.0 <= (first + 1) * dt <= 31.0
    assert all(on for on, _ in said[first:])
    assert said[-1][1].startswith("0.6 m along the route in 30 s where the plan asks 15.0 m (0.02 m/s made good")
    for _ in range(100):  # under way again: cleared only once half the asked distance is made good
        t, s = t + dt, s + 0.5 * dt
        on, _ = mon.observe(t, s, 0.5)
    assert on
    for _ in range(300):
        t, s = t + dt, s + 0.5 * dt
        on, _ = mon.observe(t, s, 0.5)
    assert not on
    slow = ProgressMonitor(FailsafeConfig())
    assert not any(slow.observe(k * dt, 0.17 * k * dt, 0.5)[0] for k in range(1, 900))  # a third of the plan
    lap = ProgressMonitor(FailsafeConfig())
    for k in range(1, 900):  # a short route flown again and again: progress back to 0 every 10 s
        assert not lap.observe(k * dt, 0.5 * ((k * dt) % 10.0), 0.5)[0]
    held = ProgressMonitor(FailsafeConfig())
    for k in range(1, 200):  # 20 s stalled, a HOLD of 20 s without follower updates, 20 s stalled again
        assert not held.observe(k * dt, 0.0, 0.5)[0]
    assert held.idle(40.0)
    assert not any(held.observe(40.0 + k * dt, 0.0, 0.5)[0] for k in range(1, 200))
