"""Hardware drivers of the boat (GNSS, IMU, actuators, battery) and their emulated twins.

    from lotsen.drivers import HardwareConfig
    # the launch config's extra.hardware, typed: lotsen.stack.config (config.extra.hardware);
    # the stack puts the driver nodes together: lotsen.stack.hardware.add_hardware_boat

See docs/drivers.md.
"""

from lotsen.drivers.config import HardwareConfig

__all__ = ["HardwareConfig"]
