"""Hardware drivers of the boat (GNSS, IMU, actuators, battery) and their emulated twins.

    from lotsen.drivers import HardwareConfig, add_hardware_boat
    add_hardware_boat(stack, emulated=False, config=HardwareConfig())

See docs/drivers.md.
"""

from lotsen.drivers.config import HardwareConfig, hardware_config_from_launch
from lotsen.drivers.launch import HardwareBoat, add_hardware_boat

__all__ = ["HardwareConfig", "hardware_config_from_launch", "HardwareBoat", "add_hardware_boat"]
