"""Put the hardware boat into a `Stack`: driver nodes publishing what the simulated boat
publishes (imu/data_raw, imu/mag, gps_chatter, rpm_chatter, battery, sim/actuators), the RC
receiver (rc/override), and obeying ship_command through the `ActuatorGuard`.

`emulated=True` puts the device twins (lotsen.drivers.emulated) behind the same driver code and
adds the node that steps the simulator (stack.simulator, created from the launch config when
absent; it also publishes sim/truth). With a `RealtimeExecutor` the serial and I2C drivers read
in their own threads; with a `SimExecutor` they poll in timers (deterministic tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from lotsen.drivers.actuators import ActuatorNode, pigpio_opener
from lotsen.drivers.base import DriverNode
from lotsen.drivers.battery import BatteryNode
from lotsen.drivers.config import HardwareConfig
from lotsen.drivers.gnss import GnssNode, serial_opener
from lotsen.drivers.imu import ImuNode
from lotsen.drivers.echosounder import EchosounderNode
from lotsen.drivers.rc import RcReceiverNode, sbus_opener
from lotsen.model.parameters import DEFAULT_LIMITS
from lotsen.runtime.executor import RealtimeExecutor
from lotsen.stack.stack import simulator_from_config


@dataclass
class HardwareBoat:
    """What add_hardware_boat added (also in stack.services["hardware"])."""

    config: HardwareConfig
    emulated: bool
    drivers: dict[str, DriverNode] = field(default_factory=dict)
    twin: Any = None  # EmulatedBoatNode when emulated

    def health(self, since_s: float = -math.inf) -> list:
        """Each driver's health, its rate from the intervals ending at or after `since_s`."""
        return [d.refresh_health(since_s) for d in self.drivers.values()]


def _smbus_opener(bus: int) -> Any:
    def open_bus() -> Any:
        from smbus2 import SMBus

        return SMBus(bus)  # FileNotFoundError (an OSError) when I2C is not enabled

    return open_bus


def add_hardware_boat(stack: Any, emulated: bool, config: HardwareConfig | None = None) -> HardwareBoat:
    """Add the driver nodes (and, if `emulated`, the twins and the simulator stepping them)."""
    hw = config or stack.config.extra.hardware
    threaded = isinstance(stack.executor, RealtimeExecutor)
    deadline = stack.config.nodes.command_deadline_s
    boat = HardwareBoat(hw, emulated)
    if emulated:
        from lotsen.drivers.emulated import EmulatedBoatNode

        if stack.simulator is None:
            stack.simulator = simulator_from_config(stack.config, stack.model)
        stack.simulator.warm_up()  # the plant step compiled now, not in the twins' first tick
        twin = EmulatedBoatNode(stack.simulator, hw)
        stack.add(twin)  # first: its timer runs before the drivers' at equal times
        boat.twin = twin
        no_sleep = lambda s: None  # noqa: E731 - the twins need no settling time

        open_gnss = twin.zed.uart1.reopen
        open_rtcm = lambda: twin.zed.uart2  # noqa: E731
        open_base = None
        open_imu_bus = lambda: twin.i2c  # noqa: E731
        open_batt_bus = lambda: twin.i2c  # noqa: E731
        open_pi = lambda: twin.pi  # noqa: E731
        open_rc = twin.x8r.port.reopen if twin.x8r is not None else None
        open_sounder = twin.sounder.port.reopen if twin.sounder is not None else None
        sleep = no_sleep
    else:
        import time

        g = hw.gnss
        open_gnss = serial_opener(g.port, g.baudrate)
        open_rtcm = serial_opener(g.rtcm_port, g.rtcm_baudrate)
        open_base = serial_opener(g.base_port, g.base_baudrate) if g.rtcm_source == "serial" and g.base_port else None
        open_imu_bus = _smbus_opener(hw.imu.bus)
        open_batt_bus = _smbus_opener(hw.battery.bus)
        open_pi = pigpio_opener(hw.actuators.pigpio_host, hw.actuators.pigpio_port)
        open_rc = sbus_opener(hw.rc.port)
        open_sounder = serial_opener(hw.echosounder.port, hw.echosounder.baudrate)
        sleep = time.sleep
    limits = DEFAULT_LIMITS  # the boat's configured limits, also with emulated devices (the twin has its own)
    if hw.actuators.enabled:
        boat.drivers["actuators"] = ActuatorNode(hw.actuators, open_pi, limits, command_deadline_s=deadline)
    if hw.imu.enabled:
        boat.drivers["imu"] = ImuNode(hw.imu, open_imu_bus, threaded=threaded, sleep=sleep)
    if hw.gnss.enabled:
        boat.drivers["gnss"] = GnssNode(hw.gnss, open_gnss, open_rtcm, open_base, threaded=threaded)
    if hw.battery.enabled:
        boat.drivers["battery"] = BatteryNode(hw.battery, open_batt_bus, threaded=threaded)
    if hw.rc.enabled and open_rc is not None:
        boat.drivers["rc"] = RcReceiverNode(hw.rc, open_rc, threaded=threaded)
    if hw.echosounder.enabled and open_sounder is not None:
        boat.drivers["echosounder"] = EchosounderNode(hw.echosounder, open_sounder, threaded=threaded)
    for node in boat.drivers.values():
        if emulated:
            node.device = node.health.device = f"emulated {node.device}"
        stack.add(node)
    stack.services["hardware"] = boat
    return boat
