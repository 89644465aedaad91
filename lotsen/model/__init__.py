"""The 3-DOF grey-box vessel model (seed section 3.2): parameters, forces, dynamics, linearisation."""

from lotsen.model.angles import all_finite, wrap_angle
from lotsen.model.dynamics import (
    INPUT_NAMES, NU, NX, STATE_NAMES, VesselModel, jacobians, rk4_step, symbolic_rhs,
    thruster_forces, vessel_rhs,
)
from lotsen.model.environment import Environment, WindCoefficients, wind_force
from lotsen.model.linear import (
    LinearSwayYaw, StabilityReport, condition_16d, linearise, linearise_straight, stability_report,
    straight_trim,
)
from lotsen.model.quantities import ModelArrays, geometry_tuple
from lotsen.model.parameters import (
    DEFAULT_GEOMETRY, DEFAULT_LIMITS, DEFAULT_PARAMETERS, ActuatorLimits, ParameterFile, VesselGeometry,
    VesselParameters, load_parameter_file, parameter_table_markdown, parameters_from_file,
)

__all__ = [
    "INPUT_NAMES", "NU", "NX", "STATE_NAMES", "VesselModel", "jacobians",
    "thruster_forces", "vessel_rhs", "geometry_tuple", "rk4_step", "symbolic_rhs", "Environment", "WindCoefficients", "wind_force",
    "LinearSwayYaw", "StabilityReport", "condition_16d", "linearise", "linearise_straight",
    "stability_report", "straight_trim", "DEFAULT_GEOMETRY", "DEFAULT_LIMITS", "DEFAULT_PARAMETERS",
    "ActuatorLimits", "ModelArrays", "ParameterFile", "VesselGeometry", "VesselParameters", "load_parameter_file", "parameters_from_file", "parameter_table_markdown", "all_finite", "wrap_angle",
]
