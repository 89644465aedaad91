"""Hardware drivers of the boat (GNSS, IMU, actuators, battery) and their emulated twins.

    from lotsen.drivers import HardwareConfig, hardware_config_from_launch
    # the stack puts the driver nodes together: lotsen.stack.hardware.add_hardware_boat

See docs/drivers.md.
"""

from lotsen.drivers.config import HardwareConfig, hardware_config_from_launch

__all__ = ["HardwareConfig", "hardware_config_from_launch"]
