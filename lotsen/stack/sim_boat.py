"""The simulated boat as a node: it listens to ship_command (through the actuator guard) and
publishes what the real drivers would: imu/data_raw, imu/mag, gps_chatter, rpm_chatter, battery,
the achieved actuator values (actuators/state, with the ESCs' arming state), plus the ground
truth (sim/truth).

Behind an external physics (`lotsen.physics`) the node is the same: while the physics gives no
fresh state, the simulator measures nothing and the node publishes no truth and no actuator state
either, so every consumer sees the boat's data go stale, as when a real sensor bus stops.

One time base: every message is stamped on the runtime's clock, as the drivers stamp theirs.
The simulator keeps its own time from 0; the node maps it onto the clock (offset fixed at the
first tick) and, at wall-clock pace, steps as many simulator steps as the clock has advanced, so
a late tick (a busy CPU) neither stretches simulated time nor lets the stamps fall behind.
"""

from __future__ import annotations

from lotsen.messages import (
    ActuatorState, BatteryStatus, DepthSample, GnssFix, GnssFixType, ImuSample, MagSample, OperatorCommand,
    RpmSample, ThrustCommand, Topic,
)
from lotsen.runtime.executor import Node, NodeContext
from lotsen.runtime.guard import ActuatorGuard
from lotsen.sim.simulator import Simulator

_TOPIC_OF = {ImuSample: Topic.IMU_RAW, MagSample: Topic.IMU_MAG, GnssFix: Topic.GNSS,
             RpmSample: Topic.RPM, BatteryStatus: Topic.BATTERY, DepthSample: Topic.DEPTH}

#: at most this much simulated time is caught up in one tick; a longer stall (a debugger, a suspended
#: laptop) is skipped and logged. Shorter ones are replayed: the water does not wait for a late
#: control loop, and skipping would make the measurements after it disagree with the motion
MAX_CATCH_UP_S = 5.0
#: an external physics silent for this many steps in a row is logged (a single late frame is not)
STALE_LOG_STEPS = 10


class SimulatedBoatNode(Node):
    name = "sim_boat"

    def __init__(self, simulator: Simulator, truth_rate_hz: float = 20.0, command_deadline_s: float = 0.5,
                 rtk_convergence_s: float = 8.0, esc_arm_time_s: float = 0.0, steps_per_wakeup: int = 1) -> None:
        self.sim = simulator
        # the boat steps at its dt (100 Hz) whatever this is; a real-time loop woken for every step
        # pays a cache-cold wake-up each time, so `lotsen run` wakes it every second step and steps
        # twice (the samples keep their own step's stamps; the thrust command is taken per wake-up)
        if not (isinstance(steps_per_wakeup, int) and steps_per_wakeup >= 1):
            raise ValueError(f"steps_per_wakeup must be an integer >= 1, got {steps_per_wakeup!r}")
        self.steps_per_wakeup = steps_per_wakeup
        self.guard = ActuatorGuard(simulator.limits, command_deadline_s)
        self._truth_every = max(1, round(1.0 / (truth_rate_hz * simulator.config.dt_s)))
        self._steps = 0
        # RTK on/off from the operator, as the real receiver does: corrections off -> 3D fix;
        # on -> float until the ambiguities are fixed after rtk_convergence_s
        self.rtk_convergence_s = rtk_convergence_s
        self._rtk_fixed_at: float | None = None
        # ESCs arm after seeing neutral for esc_arm_time_s (as the real ones at power-up);
        # esc_fault: they never arm (a fault scenario)
        self.esc_arm_time_s = esc_arm_time_s
        self.esc_fault = False
        self._escs_armed_at: float | None = None
        self.offset_s: float | None = None  # runtime clock - simulator time
        self._stale_steps = 0  # steps in a row without a fresh state (an external physics)
        self.skipped_s = 0.0

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.SHIP_COMMAND, self._on_command)
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        ctx.add_timer(self.sim.config.dt_s * self.steps_per_wakeup, self._tick)

    @property
    def escs_armed(self) -> bool:
        return self._armed_at(self.ctx.now())

    def _armed_at(self, t: float) -> bool:
        """The ESCs armed at `t` (a step's start: with two steps per wake-up the clock is ahead of it)."""
        return not self.esc_fault and self._escs_armed_at is not None and t >= self._escs_armed_at

    def _on_operator(self, msg: OperatorCommand) -> None:
        if msg.action == "rtk_stop":
            self.sim.set_gnss_fix_type(GnssFixType.FIX_3D)
            self._rtk_fixed_at = None
        elif msg.action == "rtk_start" and self.sim.gnss.fix_type < GnssFixType.RTK_FLOAT:
            self.sim.set_gnss_fix_type(GnssFixType.RTK_FLOAT)
            self._rtk_fixed_at = self.ctx.now() + self.rtk_convergence_s

    def _on_command(self, cmd: ThrustCommand) -> None:
        self.guard.accept(cmd, self.ctx.now())

    def _tick(self) -> None:
        now = self.ctx.now()
        if self.offset_s is None:
            self.offset_s = now - self.sim.t
            self._escs_armed_at = now + self.esc_arm_time_s
        dt = self.sim.config.dt_s
        behind = now - (self.sim.t + self.offset_s)
        if behind > MAX_CATCH_UP_S:  # a stall (debugger, suspended laptop): do not replay it in a burst
            skip = behind - dt
            self.offset_s += skip
            self.skipped_s += skip
            self.ctx.log("warning", f"simulated boat fell {behind:.2f} s behind the clock: skipped", skipped_s=skip)
        n = max(1, int((now - (self.sim.t + self.offset_s)) / dt + 1e-6))
        for _ in range(n):
            self._step()

    def _step(self) -> None:
        off = self.offset_s
        t = self.sim.t + off  # the step's start on the runtime clock
        if self._rtk_fixed_at is not None and t >= self._rtk_fixed_at:
            self.sim.set_gnss_fix_type(GnssFixType.RTK_FIXED)
            self._rtk_fixed_at = None
        was_stale = self.guard.stale
        u = self.guard.output(t)
        armed = self._armed_at(t)
        if not armed:
            u = (u[0], u[1], 0.0, 0.0, 0.0)  # ESCs not armed: propellers stay still, servos move
        self.sim.command(u)
        if self.guard.stale and not was_stale:
            self.ctx.log("warning", "stale thrust command: actuators to neutral", deadline_s=self.guard.deadline_s)
        publish = self.ctx.publish
        for msg in self.sim.step():
            msg.stamp_s += off
            publish(_TOPIC_OF[type(msg)], msg)
        self._steps += 1
        if not self.sim.fresh:  # an external physics without a fresh state: nothing is measured, not even the truth
            self._stale_steps += 1
            if self._stale_steps == STALE_LOG_STEPS:
                self.ctx.log("error", "the physics does not answer: the boat's sensors are stale",
                             **self.sim.plant.status())
            return
        if self._stale_steps >= STALE_LOG_STEPS:
            self.ctx.log("warning", f"the physics answers again after {self._stale_steps * self.sim.config.dt_s:.2f} s",
                         **self.sim.plant.status())
        self._stale_steps = 0
        if self._steps % self._truth_every == 0:
            truth = self.sim.truth()
            truth.stamp_s += off
            publish(Topic.TRUTH, truth)
            a = self.sim.actuators.state
            publish(Topic.ACTUATORS, ActuatorState(stamp_s=self.sim.t + off, alpha1_rad=a[0], alpha2_rad=a[1],
                                                   n1_rps=a[2], n2_rps=a[3], nt_rps=a[4],
                                                   escs_armed=armed))
