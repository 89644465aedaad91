"""The simulated boat as a node: it listens to ship_command (through the actuator guard) and
publishes what the real drivers would: imu/data_raw, imu/mag, gps_chatter, rpm_chatter, battery,
plus the ground truth (sim/truth) and achieved actuator values (sim/actuators)."""

from __future__ import annotations

from lotsen.messages import (
    BatteryStatus, GnssFix, GnssFixType, ImuSample, MagSample, OperatorCommand, RpmSample, ThrustCommand, Topic,
)
from lotsen.runtime.executor import Node, NodeContext
from lotsen.runtime.nodes.actuator_guard import ActuatorGuard
from lotsen.sim.simulator import Simulator

_TOPIC_OF = {ImuSample: Topic.IMU_RAW, MagSample: Topic.IMU_MAG, GnssFix: Topic.GNSS,
             RpmSample: Topic.RPM, BatteryStatus: Topic.BATTERY}


class SimulatedBoatNode(Node):
    name = "sim_boat"

    def __init__(self, simulator: Simulator, truth_rate_hz: float = 20.0, command_deadline_s: float = 0.5,
                 rtk_convergence_s: float = 8.0) -> None:
        self.sim = simulator
        self.guard = ActuatorGuard(simulator.limits, command_deadline_s)
        self._truth_every = max(1, round(1.0 / (truth_rate_hz * simulator.config.dt_s)))
        self._steps = 0
        # RTK on/off from the operator, as the real receiver does: corrections off -> 3D fix;
        # on -> float until the ambiguities are fixed after rtk_convergence_s
        self.rtk_convergence_s = rtk_convergence_s
        self._rtk_fixed_at: float | None = None

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.subscribe(Topic.SHIP_COMMAND, self._on_command)
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        ctx.add_timer(self.sim.config.dt_s, self._tick)

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
        if self._rtk_fixed_at is not None and self.ctx.now() >= self._rtk_fixed_at:
            self.sim.set_gnss_fix_type(GnssFixType.RTK_FIXED)
            self._rtk_fixed_at = None
        was_stale = self.guard.stale
        self.sim.command(self.guard.output(self.ctx.now()))
        if self.guard.stale and not was_stale:
            self.ctx.log("warning", "stale thrust command: actuators to neutral", deadline_s=self.guard.deadline_s)
        publish = self.ctx.publish
        for msg in self.sim.step():
            publish(_TOPIC_OF[type(msg)], msg)
        self._steps += 1
        if self._steps % self._truth_every == 0:
            publish(Topic.TRUTH, self.sim.truth())
            publish(Topic.ACTUATORS, self.sim.actuator_state())
