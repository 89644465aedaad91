"""Wire nodes into a running stack from a validated launch config (`lotsen.stack.config`).

`build_stack` creates the executor (simulated time or wall clock), the boat (the simulated boat,
or the hardware drivers with real or emulated devices), and the parts the config asks for, in
order: the state estimate, the supervisor (which runs the controllers), then the recorder, the
Zenoh bridge and the web server, which only observe and relay. Every import is explicit: the
stack is the top of the package graph and nothing below imports it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig
from lotsen.runtime.executor import Executor, RealtimeExecutor, SimExecutor
from lotsen.model.actuators import advance_motors
from lotsen.stack.config import stack_config
from lotsen.stack.parts import add_recorder, add_state, add_supervisor, add_web, add_zenoh
from lotsen.stack.sim_boat import SimulatedBoatNode
from lotsen.model import VesselModel
from lotsen.sim import Simulator
from lotsen.stack.stack import Stack, resolve_origin, simulator_from_config, vessel_model

@dataclass(frozen=True)
class Harness:
    """What a harness may replace in a stack built on simulated time (None: from the config)."""

    simulator: Simulator | None = None  # e.g. another model than the controllers' (mismatch runs)
    model: VesselModel | None = None  # the controllers' and the estimator's model
    estimator: Any = None  # an estimator object (on_imu/on_mag/on_gnss/on_command, estimate(t))
    follower: Any = None  # a path follower for AUTO/RETURN
    station_keeper: Any = None
    truth_rate_hz: float = 20.0  # sim/truth (and the truth 'estimate'); harnesses on truth use the step rate


PARTS: dict[str, Callable[[Stack], object]] = {
    "state": add_state,
    "supervisor": add_supervisor,
    "logs": add_recorder,
    "zenoh": add_zenoh,
    "web": add_web,
}


def add_boat(stack: Stack, simulator: Simulator | None = None, truth_rate_hz: float = 20.0,
             realtime: bool = False) -> None:
    """The simulated boat node (on `simulator` if given; else lotsen's own boat or the external
    physics of `extra.physics`), or the hardware drivers (emulated devices with `extra.emulated`)."""
    config = stack.config
    if config.mode == "sim":
        own_boat = simulator is None and not stack_config(config).extra.physics.address
        stack.simulator = simulator or simulator_from_config(config, stack.model, realtime)
        stack.on_shutdown(stack.simulator.plant.close)  # an external physics's socket
        # on wall-clock time lotsen's own boat steps twice per wake-up (docs/runtime.md, "A lighter
        # idle run"); an external physics answers step by step, and simulated time costs no wake-ups
        stack.add(SimulatedBoatNode(stack.simulator, truth_rate_hz=truth_rate_hz,
                                    command_deadline_s=config.nodes.command_deadline_s,
                                    esc_arm_time_s=config.sim.esc_arm_time_s,
                                    steps_per_wakeup=2 if realtime and own_boat else 1))
    else:
        from lotsen.stack.hardware import add_hardware_boat  # pigpio/serial openers only on this path

        add_hardware_boat(stack, emulated=config.extra.emulated)


def build_stack(config: LaunchConfig, realtime: bool, parts: tuple[str, ...] | None = None, *,
                executor: Executor | None = None, harness: Harness | None = None,
                progress: Callable[[str], None] | None = None) -> Stack:
    """The whole stack for `config`. `parts` limits the optional parts (None = all). `harness`
    replaces pieces for the closed-loop harnesses (simulator, estimator, controllers, model).

    `realtime`: every compiled kernel the loop calls is compiled (or loaded from numba's cache)
    here, before the loop and its watchdog start; `progress` hears how far that is (the first
    start after install compiles for about a minute, a warm start loads in about a second)."""
    config = stack_config(config)  # the extra sections typed (as loaded: unchanged)
    h = harness or Harness()
    executor = executor or (RealtimeExecutor() if realtime else SimExecutor())
    stack = Stack(config=config, executor=executor, model=h.model or vessel_model(config),
                  origin=resolve_origin(config))
    warm = KernelWarmUp(progress if realtime else None, 3 + (config.mode == "sim"))
    if realtime:
        warm.step("vessel model", stack.model.warm_up)  # numba compiles now, not when the operator presses AUTO
        # the thruster monitor's and the EKF's motor model
        warm.step("motor model", lambda: advance_motors((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.1))
    add_boat(stack, h.simulator, h.truth_rate_hz, realtime)
    if realtime and stack.simulator is not None:
        # the simulated boat's plant step: compiled before the loop's first tick
        warm.step("simulated boat", stack.simulator.warm_up)
    for name, adder in PARTS.items():
        if parts is None or name in parts:
            if name == "state":
                add_state(stack, h.estimator)
            elif name == "supervisor":
                add_supervisor(stack, h.follower, h.station_keeper)
            else:
                adder(stack)
    supervisor = stack.nodes.get("supervisor")
    warm_up = getattr(getattr(supervisor, "follower", None), "warm_up", None)
    if realtime:
        # the path follower's jitted step too (the MPC's first step compiles ~0.3 s)
        warm.step("path follower", warm_up or (lambda: None))
    return stack


class KernelWarmUp:
    """Runs the warm-up steps and tells `progress` about them: one line before the first, then
    a line per step that took long enough to be compiling (the first start after install)."""

    def __init__(self, progress: Callable[[str], None] | None, steps: int, slow_s: float = 0.5) -> None:
        self.progress = progress
        self.steps = steps
        self.slow_s = slow_s
        self.done = 0

    def step(self, what: str, fn: Callable[[], object]) -> None:
        if self.progress is not None and self.done == 0:
            self.progress(f"preparing {self.steps} groups of compiled kernels (loaded from the cache; "
                          "the first start after install compiles them, about a minute)")
        t0 = time.perf_counter()
        fn()
        self.done += 1
        took_s = time.perf_counter() - t0
        if self.progress is not None and took_s >= self.slow_s:
            self.progress(f"compiled kernels {self.done}/{self.steps} ready: {what} ({took_s:.1f} s)")


def summary(stack: Stack) -> str:
    """One-line state of the boat for the console."""
    truth = stack.bus.latest.get(Topic.TRUTH) or stack.bus.latest.get(Topic.STATE)
    t = stack.executor.clock.now()
    errors = stack.executor.errors.total
    tail = f"  callback errors: {errors} (see the log)" if errors else ""
    if truth is None:
        return f"t={t:7.1f} s  (no state yet){tail}"
    return (f"t={t:7.1f} s  N={truth.north_m:8.2f} m  E={truth.east_m:8.2f} m  "
            f"heading={math.degrees(truth.heading_rad) % 360:6.1f} deg  speed={truth.speed_mps:5.2f} m/s{tail}")
