"""The simulated vessel (digital twin): integrator, actuator dynamics, sensors, environment, faults."""

from lotsen.sim.actuators import ActuatorDynamics, ActuatorFaults
from lotsen.sim.sensors import (
    GRAVITY_MPS2, GnssConfig, GnssModel, ImuConfig, ImuModel, MagnetometerModel, TachometerConfig,
    TachometerModel,
)
from lotsen.sim.simulator import BatteryConfig, SimConfig, Simulator, simulate_inputs

__all__ = [
    "ActuatorDynamics", "ActuatorFaults", "GRAVITY_MPS2", "GnssConfig", "GnssModel", "ImuConfig",
    "ImuModel", "MagnetometerModel", "TachometerConfig", "TachometerModel", "BatteryConfig",
    "SimConfig", "Simulator", "simulate_inputs",
]
