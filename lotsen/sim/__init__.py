"""The simulated vessel (digital twin): the plant (vessel, actuators, environment; an interface an
external physics implements too), lotsen's sensor models, faults."""

from lotsen.sim.actuators import ActuatorDynamics, ActuatorFaults
from lotsen.sim.boat import (
    DEFAULT_BOAT, LAKE_BOAT_PARAMETERS, SimulatedBoat, parameter_mismatch, random_boat, randomised_parameters,
)
from lotsen.sim.sensors import (
    GRAVITY_MPS2, GnssConfig, GnssModel, ImuConfig, ImuModel, MagnetometerModel, TachometerConfig,
    TachometerModel,
)
from lotsen.sim.plant import BoatPlant, Plant, PlantError, PlantSample, planar_state
from lotsen.sim.simulator import BatteryConfig, SimConfig, Simulator, propulsion_energy_j, simulate_inputs

__all__ = [
    "DEFAULT_BOAT", "LAKE_BOAT_PARAMETERS", "SimulatedBoat", "parameter_mismatch", "random_boat",
    "randomised_parameters",
    "ActuatorDynamics", "ActuatorFaults", "GRAVITY_MPS2", "GnssConfig", "GnssModel", "ImuConfig",
    "ImuModel", "MagnetometerModel", "TachometerConfig", "TachometerModel", "BatteryConfig",
    "SimConfig", "Simulator", "propulsion_energy_j", "simulate_inputs", "BoatPlant", "Plant", "PlantError", "PlantSample", "planar_state",
]
