"""An identification experiment on the stack is a command source like the keys: the supervisor
forwards it in EXPERIMENT mode under its pre-arm checks and failsafes, and the experiment ends
(thrusters neutral, disarmed) when the supervisor refuses or leaves the mode."""

import numpy as np
import pytest

from lotsen.messages import OperatorCommand, ThrustCommand, Topic
from lotsen.runtime.config import LaunchConfig, NodesSection, WebSection
from lotsen.stack.experiment import ExperimentNode
from lotsen.stack.launch import build_stack
from lotsen.sysid.experiment import parse_experiment

STEPS = {"name": "bow_steps", "area": {"size_m": [40, 40]},
         "pieces": [{"type": "steps", "step_duration_s": 3,
                     "levels": [{"n_rps": 20, "nt_rps": 60}, {"n_rps": 20, "nt_rps": -60}]}]}


def run(until_s=14.0, before=None, at=None):
    """The experiment on the simulated stack (lake boat, EKF); `before(stack)` after building,
    `at = (t, action)`: an operator request at t."""
    cfg = LaunchConfig(nodes=NodesSection(fusion="ekf", controller="los"), web=WebSection(enabled=False))
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    if before is not None:
        before(stack)
    node = stack.add(ExperimentNode(parse_experiment(STEPS, "test")))
    commands, modes = [], []
    stack.bus.subscribe(Topic.SHIP_COMMAND, commands.append)
    stack.bus.subscribe(Topic.SUPERVISOR, lambda s: modes.append((s.stamp_s, s.mode)))
    if at is not None:
        stack.executor.run_until(at[0])
        stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=at[0], action=at[1], source="test"))
    stack.executor.run_until(until_s, stop=lambda: node.done and stack.executor.clock.now() > node.t_start + 1.0)
    stack.executor.run_for(0.5)
    return stack, node, commands, modes


def test_the_experiment_drives_through_the_supervisor_and_ends_disarmed():
    stack, node, commands, modes = run()
    sup = stack.nodes["supervisor"]
    assert node.done and node.aborted == "" and len(node.rows) > 100
    assert "EXPERIMENT" in {m for _, m in modes}
    driving = [c for c in commands if c.source == "experiment"]
    assert driving and max(abs(c.nt_rps) for c in driving) == 60.0  # the design reached the actuators
    assert all(c.source != "experiment" for c in commands if c.stamp_s > node.t0 + 6.1)  # ended
    assert not sup.armed and sup.mode.name == "MANUAL" and commands[-1].as_tuple() == (0.0,) * 5


def test_an_operator_estop_ends_the_experiment_and_the_thrusters_stay_neutral():
    stack, node, commands, modes = run(at=(4.0, "estop"))
    assert node.done and "left EXPERIMENT: ESTOP" in node.aborted
    after = [c for c in commands if c.stamp_s >= 4.0 - 1e-9]
    first_neutral = next(i for i, c in enumerate(after) if c.source == "estop")
    assert after[first_neutral].stamp_s < 4.0 + 1e-6  # at once, not on the next control tick
    assert all(c.as_tuple() == (0.0,) * 5 for c in after[first_neutral:])


def test_the_experiment_is_refused_with_the_pre_arm_reason():
    def uncalibrated(stack):
        stack.nodes["supervisor"].heading_calibration = ""

    stack, node, commands, modes = run(before=uncalibrated)
    assert node.done and node.t0 is None and "magnetometer not calibrated" in node.aborted
    assert all(c.source != "experiment" for c in commands)


def test_experiment_commands_move_nothing_outside_the_experiment_mode():
    cfg = LaunchConfig(nodes=NodesSection(fusion="ekf", controller="los"), web=WebSection(enabled=False))
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    commands = []
    stack.bus.subscribe(Topic.SHIP_COMMAND, commands.append)
    stack.executor.run_until(3.0)
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=3.0, action="arm", source="test"))
    stack.executor.add_timer(0.05, lambda: stack.bus.publish(Topic.EXPERIMENT_COMMAND, ThrustCommand(
        stamp_s=stack.executor.clock.now(), n1_rps=40.0, n2_rps=40.0, source="experiment")))
    stack.executor.run_until(5.0)
    assert stack.nodes["supervisor"].mode.name == "MANUAL"
    assert all(c.as_tuple() == (0.0,) * 5 for c in commands)
    # the pilot's page may ask for the mode while an experiment sends: then it is forwarded
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=5.0, action="experiment", source="test"))
    stack.executor.run_until(6.0)
    assert stack.nodes["supervisor"].mode.name == "EXPERIMENT" and commands[-1].n1_rps == 40.0


def test_a_boat_about_to_leave_the_area_turns_back_and_the_experiment_completes():
    """A straight 60-s run at ~0.6 m/s in a 20 x 20 m area on the stack (lake boat, EKF): the boat
    would leave after ~15 s; the node pauses the signal, steers back, resumes, and the experiment
    ends normally with every second of the signal and the returns' rows in the record."""
    from lotsen.messages import LogEvent

    straight = {"name": "straight", "area": {"size_m": [20, 20]},
                "pieces": [{"type": "constant", "duration_s": 60, "n_rps": 40}]}
    cfg = LaunchConfig(nodes=NodesSection(fusion="ekf", controller="los"), web=WebSection(enabled=False))
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    node = stack.add(ExperimentNode(parse_experiment(straight, "test")))
    logs: list[str] = []
    stack.bus.subscribe(Topic.LOG, lambda e: logs.append(e.text) if isinstance(e, LogEvent) else None)
    stack.executor.run_until(400.0, stop=lambda: node.done)
    assert node.done and node.aborted == "", node.aborted
    k = node.keeper
    assert k.returns >= 1 and k.paused_s > 5.0
    rec = node.record()
    assert rec.t[-1] == pytest.approx(60.0 + k.paused_s, abs=0.2)  # the signal whole, the returns on top
    north, east = rec.outputs[:, 0] - node.origin[0], rec.outputs[:, 1] - node.origin[1]
    assert np.all(np.abs(north) < 10.0) and np.all(np.abs(east) < 10.0)
    assert any("turns back to the area's centre" in text for text in logs)
    assert any("the signal resumes" in text for text in logs)
    assert stack.nodes["supervisor"].mode.name == "MANUAL"


def test_without_returns_the_area_edge_aborts_the_experiment():
    straight = {"name": "straight", "area": {"size_m": [20, 20]},
                "pieces": [{"type": "constant", "duration_s": 60, "n_rps": 40}]}
    cfg = LaunchConfig(nodes=NodesSection(fusion="ekf", controller="los"), web=WebSection(enabled=False))
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    node = stack.add(ExperimentNode(parse_experiment(straight, "test"), keep_inside=False))
    stack.executor.run_until(100.0, stop=lambda: node.done)
    assert node.done and "left the experiment area" in node.aborted and node.record().t[-1] < 30.0
