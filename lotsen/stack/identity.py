"""What makes two runs the same boat (`lotsen run`'s one run per boat, `RunLock`).

Light on purpose: `lotsen run` takes its lock with this before it loads anything else, so a
second run is refused at once.
"""

from __future__ import annotations

from lotsen.runtime.config import LaunchConfig
from lotsen.stack.config import stack_config
from lotsen.sim.boat import DEFAULT_BOAT


def run_identities(config: LaunchConfig) -> list[str]:
    """What makes two runs the same boat (one run per boat, `RunLock`): in simulation the
    simulated boat's name (or the external physics's address); on the hardware every device the
    run would open (serial ports, I2C addresses, pigpiod's pins). Emulated devices live in the
    run's core: their runs are told apart by the same names under "emulated"."""
    if config.mode == "sim":
        physics = stack_config(config).extra.physics.address
        if physics:  # one run per physics server: two would step one boat
            return [f"physics {physics}"]
        b = config.sim.boat
        return [f"sim boat {b.name or ('ideal model' if b.ideal else DEFAULT_BOAT.name)}"]
    extra = stack_config(config).extra
    hw = extra.hardware
    kind = "emulated" if extra.emulated else "hardware"
    ids = []
    if hw.gnss.enabled:
        ids += [f"{kind} serial {port}" for port in (hw.gnss.port, hw.gnss.rtcm_port, hw.gnss.base_port) if port]
    if hw.imu.enabled:
        ids.append(f"{kind} i2c {hw.imu.bus} 0x{hw.imu.address:02x}")
    if hw.battery.enabled:
        ids.append(f"{kind} i2c {hw.battery.bus} 0x{hw.battery.address:02x}")
    if hw.actuators.enabled:
        ids.append(f"{kind} pigpio {hw.actuators.pigpio_host}:{hw.actuators.pigpio_port}")
    return ids or [f"{kind} boat"]
