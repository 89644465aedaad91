"""Fewer, warmer wake-ups on the real-time loop (issue 49 item 3), with the same outputs: the
fusion node feeds its samples to the estimator at its publication, the simulated boat of
`lotsen run` steps twice per wake-up. Both on simulated time, where every step is reproducible."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lotsen.messages import Topic, ThrustCommand
from lotsen.runtime.config import load_config
from lotsen.runtime.executor import SimExecutor
from lotsen.stack.launch import build_stack
from lotsen.stack.sim_boat import SimulatedBoatNode
from lotsen.stack.stack import simulator_from_config

ROOT = Path(__file__).resolve().parents[2]


def _command_every_100ms(executor) -> None:
    """A constant command, fresh for the actuator guard: the boat moves and turns."""
    def send() -> None:
        executor.bus.publish(Topic.SHIP_COMMAND, ThrustCommand(
            stamp_s=executor.clock.now(), alpha1_rad=0.2, alpha2_rad=0.2, n1_rps=30.0, n2_rps=30.0))
    executor.add_timer(0.1, send, "test-command")


def _estimates(max_pending: int | None, seconds: float = 12.0) -> list[tuple[float, ...]]:
    stack = build_stack(load_config(ROOT / "config" / "sim.yaml"), realtime=False, parts=("state",))
    if max_pending is not None:
        stack.nodes["fusion"].MAX_PENDING = max_pending
    _command_every_100ms(stack.executor)
    out: list[tuple[float, ...]] = []
    stack.executor.bus.subscribe(Topic.STATE, lambda est: out.append((est.stamp_s,) + est.as_array_tuple()))
    stack.executor.run_until(seconds)
    stack.executor.shutdown()
    return out


def test_batched_samples_give_the_estimates_of_samples_fed_on_arrival():
    fed_on_arrival = _estimates(max_pending=0)  # every sample goes to the estimator as it comes
    batched = _estimates(max_pending=None)
    assert len(batched) == len(fed_on_arrival) >= 12 * 20 - 1
    assert batched == fed_on_arrival  # to the last bit: the same samples in the same order


def test_samples_wait_for_the_publication_and_none_is_left_at_it():
    stack = build_stack(load_config(ROOT / "config" / "sim.yaml"), realtime=False, parts=("state",))
    fusion = stack.nodes["fusion"]
    left_at_publication: list[int] = []
    stack.executor.bus.subscribe(Topic.STATE, lambda est: left_at_publication.append(len(fusion._pending)))
    stack.executor.run_until(1.0 + 0.035)  # between two publications (every 50 ms)
    assert len(fusion._pending) >= 3  # IMU and magnetometer samples since the last one
    assert len(left_at_publication) >= 20 and not any(left_at_publication)
    stack.executor.shutdown()


class _CountingBoat(SimulatedBoatNode):
    """The simulated boat, counting its wake-ups."""

    wakeups = 0

    def _tick(self) -> None:
        self.wakeups += 1
        super()._tick()


def _imu_and_ticks(steps_per_wakeup: int, seconds: float = 3.0) -> tuple[dict[float, tuple], int, float]:
    """The IMU samples by stamp, the boat's wake-ups and the most its stamps ran ahead of the clock
    after its first wake-up: the config's boat, as `lotsen run` makes it, at `steps_per_wakeup`."""
    config = load_config(ROOT / "config" / "sim.yaml")
    executor = SimExecutor()
    boat = executor.add_node(_CountingBoat(simulator_from_config(config),
                                           command_deadline_s=config.nodes.command_deadline_s,
                                           esc_arm_time_s=config.sim.esc_arm_time_s,
                                           steps_per_wakeup=steps_per_wakeup))
    _command_every_100ms(executor)
    samples: dict[float, tuple] = {}
    ahead = [0.0]

    def on_imu(msg) -> None:
        samples[round(msg.stamp_s, 6)] = tuple(msg.accel_mps2) + tuple(msg.gyro_radps)
        if boat.wakeups > 1:
            ahead[0] = max(ahead[0], msg.stamp_s - executor.clock.now())
    executor.bus.subscribe(Topic.IMU_RAW, on_imu)
    executor.run_until(seconds)
    executor.shutdown()
    return samples, boat.wakeups, ahead[0]


def test_simulated_time_steps_the_boat_once_per_wakeup():
    stack = build_stack(load_config(ROOT / "config" / "sim.yaml"), realtime=False, parts=())
    assert stack.nodes["sim_boat"].steps_per_wakeup == 1


def test_two_steps_per_wakeup_give_the_same_boat_with_half_the_wakeups():
    one, ticks_one, ahead_one = _imu_and_ticks(1)
    two, ticks_two, ahead_two = _imu_and_ticks(2)
    assert ticks_two <= ticks_one / 2 + 1
    common = sorted(set(one) & set(two))
    assert len(common) >= 0.99 * 3.0 * 100  # the boat still steps at 100 Hz
    # the same physics and sensor noise, sample for sample, under the same constant command
    np.testing.assert_allclose([one[t] for t in common], [two[t] for t in common], rtol=0, atol=1e-12)
    assert ahead_one <= 1e-9 and ahead_two <= 1e-9  # no sample from the clock's future


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2"])
def test_steps_per_wakeup_must_be_a_positive_integer(bad):
    stack = build_stack(load_config(ROOT / "config" / "sim.yaml"), realtime=False, parts=())
    with pytest.raises(ValueError, match="steps_per_wakeup"):
        SimulatedBoatNode(stack.simulator, steps_per_wakeup=bad)
