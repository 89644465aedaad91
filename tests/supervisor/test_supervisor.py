"""Supervisor modes and transitions on the simulated boat (truth as the estimate, fast)."""

import math
from dataclasses import replace

import pytest

from lotsen.messages import (
    BatteryStatus, ManualCommand, OperatorCommand, RcOverride, ThrustCommand, Topic, VesselState,
)
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection
from lotsen.stack.launch import build_stack
from lotsen.stack.stack import example_route

ROUTE = example_route("figure_eight")


def make_stack(route=ROUTE, x0=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0), controller="los", failsafes=None):
    cfg = LaunchConfig(route=route, nodes=NodesSection(fusion="truth", controller=controller),
                       sim=SimSection(initial_state=x0),
                       extra={"failsafes": {"prearm_skip": ["pilot_link"], **(failsafes or {})}})  # no page here
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    logs, cmds = [], []
    stack.bus.subscribe(Topic.LOG, logs.append)
    stack.bus.subscribe(Topic.SHIP_COMMAND, cmds.append)
    stack.executor.run_until(1.2)  # the first state estimate arrives, the simulated ESCs arm
    op(stack, "arm")
    return stack, stack.nodes["supervisor"], logs, cmds


def op(stack, action):
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=stack.executor.clock.now(), action=action))


def run(stack, seconds):
    stack.executor.run_for(seconds)


def test_starts_in_manual_with_neutral_thrusters():
    stack, sup, logs, cmds = make_stack()
    run(stack, 2.0)
    assert sup.mode.name == "MANUAL"
    assert all(c.as_tuple() == (0.0,) * 5 for c in cmds)
    assert stack.bus.latest[Topic.SUPERVISOR].mode == "MANUAL"


def test_auto_follows_the_route_and_pause_resume():
    stack, sup, logs, cmds = make_stack()
    run(stack, 1.0)
    op(stack, "auto")
    run(stack, 20.0)
    assert sup.mode.name == "AUTO"
    truth = stack.simulator.truth()
    assert truth.north_m > 6.0  # left the harbour (north 4 m) along the path
    op(stack, "hold")
    run(stack, 10.0)
    assert sup.mode.name == "HOLD"
    held = stack.simulator.truth()
    assert math.hypot(held.north_m - sup.hold_target.north_m, held.east_m - sup.hold_target.east_m) < 0.5
    op(stack, "auto")  # resume from where it paused
    run(stack, 5.0)
    assert sup.mode.name == "AUTO"


def test_estop_latches_and_refuses_until_reset():
    stack, sup, logs, cmds = make_stack()
    op(stack, "auto")
    run(stack, 5.0)
    op(stack, "estop")
    run(stack, 1.0)
    assert sup.mode.name == "ESTOP" and cmds[-1].as_tuple() == (0.0,) * 5
    op(stack, "auto")
    run(stack, 0.5)
    assert sup.mode.name == "ESTOP"
    assert any("emergency stop is latched" in e.text for e in logs)
    op(stack, "reset_estop")
    run(stack, 0.5)
    assert sup.mode.name == "MANUAL" and cmds[-1].as_tuple() == (0.0,) * 5


def test_rc_override_wins_over_everything():
    stack, sup, logs, cmds = make_stack()
    op(stack, "estop")
    run(stack, 0.5)
    rc_cmd = ThrustCommand(stamp_s=0.5, n1_rps=30, n2_rps=30, source="rc")
    sticks = {"msg": RcOverride(stamp_s=0.5, active=True, command=rc_cmd)}
    stack.executor.add_timer(0.05, lambda: stack.bus.publish(Topic.RC, sticks["msg"]))  # a receiver: 20 Hz
    run(stack, 1.0)
    assert sup.mode.name == "RC" and cmds[-1].n1_rps == 30
    op(stack, "auto")
    run(stack, 0.5)
    assert sup.mode.name == "RC"
    sticks["msg"] = RcOverride(stamp_s=2.0, active=False)
    run(stack, 0.5)
    assert sup.mode.name == "MANUAL" and not sup.armed  # the e-stop disarmed the boat


def test_rc_release_holds_where_the_transmitter_left_the_boat():
    stack, sup, logs, cmds = make_stack()
    op(stack, "auto")
    run(stack, 3.0)
    stack.bus.publish(Topic.RC, RcOverride(stamp_s=3.0, active=True))
    run(stack, 1.0)
    assert sup.mode.name == "RC" and cmds[-1].as_tuple() == (0.0,) * 5  # no command: neutral
    stack.bus.publish(Topic.RC, RcOverride(stamp_s=4.0, active=False))
    run(stack, 0.5)
    assert sup.mode.name == "HOLD" and "RC override released" in sup.reason


def test_unknown_or_impossible_requests_are_refused_with_a_reason():
    stack, sup, logs, cmds = make_stack(route=None)
    run(stack, 0.5)
    op(stack, "fly")
    op(stack, "auto")
    run(stack, 0.5)
    texts = [e.text for e in logs]
    assert any("unknown action 'fly'" in t for t in texts)
    assert any("auto: no route loaded" in t for t in texts)
    assert sup.mode.name == "MANUAL" and sup.counters["refused_requests"] == 2


def test_manual_driving_and_stale_keys():
    stack, sup, logs, cmds = make_stack()
    run(stack, 0.5)
    for i in range(20):
        stack.bus.publish(Topic.MANUAL, ManualCommand(stamp_s=stack.executor.clock.now(), surge=1.0))
        run(stack, 0.1)
    assert cmds[-1].n1_rps > 10 and cmds[-1].n2_rps > 10
    assert stack.simulator.truth().u_mps > 0.1
    run(stack, 1.0)  # keys no longer arrive: neutral after manual_timeout_s
    assert cmds[-1].as_tuple() == (0.0,) * 5


def test_manual_sideways_uses_the_bow_thruster():
    stack, sup, logs, cmds = make_stack()
    for _ in range(10):
        stack.bus.publish(Topic.MANUAL, ManualCommand(stamp_s=stack.executor.clock.now(), sway=1.0))
        run(stack, 0.1)
    assert cmds[-1].nt_rps > 5


def test_geofence_brings_the_boat_back_inside():
    # start outside the navigable area (field notes #7: do not freeze outside)
    stack, sup, logs, cmds = make_stack(x0=(-1.5, 20.0, math.pi, 0.0, 0.0, 0.0))
    run(stack, 0.3)
    op(stack, "hold")
    run(stack, 1.0)
    assert "geofence" in sup.failsafes.active
    assert sup.mode.name == "HOLD" and "geofence" in sup.reason
    t = sup.hold_target
    assert t.north_m > 0.0  # the target is inside
    run(stack, 30.0)
    truth = stack.simulator.truth()
    assert truth.north_m > 0.0, "the boat came back inside"


def test_low_battery_returns_and_critical_stops():
    stack, sup, logs, cmds = make_stack()
    op(stack, "auto")
    run(stack, 20.0)
    assert sup.mode.name == "AUTO"
    for _ in range(60):
        stack.bus.publish(Topic.BATTERY, BatteryStatus(stamp_s=stack.executor.clock.now(), voltage_v=10.6))
        run(stack, 0.1)
    assert sup.mode.name == "RETURN"
    for _ in range(60):
        stack.bus.publish(Topic.BATTERY, BatteryStatus(stamp_s=stack.executor.clock.now(), voltage_v=10.0))
        run(stack, 0.1)
    assert sup.mode.name == "MANUAL" and "battery_critical" in sup.reason and "10.00 V" in sup.reason
    assert cmds[-1].as_tuple() == (0.0,) * 5


def test_return_to_harbour_ends_holding_at_the_harbour():
    stack, sup, logs, cmds = make_stack()
    op(stack, "auto")
    run(stack, 40.0)
    op(stack, "return")
    run(stack, 0.2)
    assert sup.mode.name == "RETURN"
    run(stack, 150.0)
    assert sup.mode.name == "HOLD"
    truth = stack.simulator.truth()
    assert math.hypot(truth.north_m - 4.0, truth.east_m - 20.0) < 1.0


def test_magnetometer_calibration_manoeuvre():
    stack, sup, logs, cmds = make_stack()
    results = []
    stack.bus.subscribe(Topic.MAG_CALIBRATION, results.append)
    op(stack, "calibrate_mag")
    run(stack, 1.0)
    assert sup.mode.name == "CALIBRATE" and cmds[-1].nt_rps > 0
    run(stack, 80.0)
    assert results and results[0].ok, results[0].text if results else "no result"
    imu = stack.simulator.config.imu
    H = imu.earth_field_horizontal_uT
    assert results[0].center == pytest.approx(imu.hard_iron_uT, abs=0.5)
    assert results[0].matrix[0][0] == pytest.approx(imu.soft_iron[0][0] * H, rel=0.05)
    assert sup.mode.name == "HOLD"


def test_non_finite_state_stops_the_boat():
    stack, sup, logs, cmds = make_stack()
    op(stack, "auto")
    run(stack, 5.0)
    stack.nodes.pop("state_truth")  # the estimate source goes bad
    stack.executor.nodes = [n for n in stack.executor.nodes if n.name != "state_truth"]
    stack.bus._subs[Topic.TRUTH].clear()
    stack.bus.publish(Topic.STATE, VesselState(stamp_s=5.0, north_m=float("nan"), east_m=0, heading_rad=0,
                                               u_mps=0, v_mps=0, r_radps=0))
    run(stack, 0.5)
    assert sup.mode.name == "MANUAL" and "no finite state" in sup.reason
    assert cmds[-1].as_tuple() == (0.0,) * 5


def test_no_progress_along_the_route_is_a_warning_that_clears_when_no_route_is_followed():
    """The progress monitor's warning reaches the status, the log and the failsafe history, changes no
    mode, and is gone once the follower stops updating (a HOLD, MANUAL)."""
    from lotsen.messages import ControllerStatus

    stack, sup, logs, cmds = make_stack()
    t0 = stack.executor.clock.now()
    for k in range(1, 320):  # 32 s at the route's first metre, 0.5 m/s planned
        t = t0 + 0.1 * k
        sup.watch_controller(t, ControllerStatus(stamp_s=t, controller="mpc", progress_m=0.3 + 0.001 * k,
                                                 speed_ref_mps=0.5), 1.0)
    assert sup.failsafes.active["no_progress"].startswith("0.3 m along the route in 30 s where the plan asks 15.0 m")
    assert any(h.startswith("no_progress: ") for h in sup.failsafe_history)
    assert any("failsafe no_progress" in getattr(e, "text", "") for e in logs)
    assert sup.mode.name == "MANUAL"  # a warning: no mode change
    sup._check_failsafes(t + 2.0)
    assert "no_progress" not in sup.failsafes.active
