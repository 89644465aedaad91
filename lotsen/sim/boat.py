"""The simulated boat as its own thing: a hull that is not the model the estimator, planner and
controllers use.

A real hull differs from any prior by 10-20 % on its coefficients and has effects no grey-box
model here carries: a propeller that makes no thrust below a few rev/s, astern thrust weaker than
ahead, ESCs and servos slower than their data sheets, set-points that reach the actuators late,
and a GNSS antenna that is not at the model's origin. `SimulatedBoat` holds all of them; the
`Simulator` is built from one. `DEFAULT_BOAT` is the lake boat every demo, test and benchmark
runs; `SimulatedBoat.ideal(model)` is a boat equal to a model (figures from it are labelled
"ideal model").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from lotsen.model.dynamics import VesselModel
from lotsen.model.parameters import (
    DEFAULT_GEOMETRY, DEFAULT_LIMITS, DEFAULT_PARAMETERS, ActuatorLimits, VesselGeometry, VesselParameters,
)
from lotsen.sim.waves import HullForm

#: The lake boat's coefficients: 9-20 % away from the model's defaults, in the directions a
#: heavier, fuller hull with smaller propellers would take (more added mass and damping, less thrust).
LAKE_BOAT_PARAMETERS = VesselParameters(
    m11=15.6, m22=27.5, m33=2.05, X_u=3.4, X_uu=-5.9, Y_v=13.8, Y_r=1.2, Y_uv=-7.0, Y_vv=-46.0, Y_rv=-2.3,
    N_v=0.58, N_r=3.5, N_vv=-1.15, N_rr=-1.3, kappa=0.023, C_N=0.85, mu_az=0.00097, mu_t=0.00034)


@dataclass(frozen=True)
class SimulatedBoat:
    """The simulated hull, its actuators and its sensor mounting (all SI; body frame x forward, y starboard)."""

    name: str = "lake boat"
    parameters: VesselParameters = LAKE_BOAT_PARAMETERS
    geometry: VesselGeometry = field(default_factory=lambda: replace(DEFAULT_GEOMETRY, reverse_thrust_ratio=0.8))
    limits: ActuatorLimits = field(default_factory=lambda: replace(
        DEFAULT_LIMITS, alpha_rate_max_radps=math.radians(150.0), motor_time_constant_s=0.10))
    # |n| below this makes no thrust (friction, a propeller that only bites above a few rev/s)
    thrust_dead_band_rps: float = 3.0
    # set-points reach the ESCs and servos this late (PWM frame, ESC firmware)
    command_latency_s: float = 0.03
    # the GNSS antenna's position on the hull relative to the model's origin (body x, y)
    gnss_antenna_m: tuple[float, float] = (0.05, 0.0)
    # what the waves see: waterline, draft, how the hull heaves, rolls and pitches, the antenna's height
    hull: HullForm = field(default_factory=HullForm)
    ideal: bool = False  # True: this boat is exactly a model (no unmodelled effects)

    @classmethod
    def ideal_for(cls, model: VesselModel, limits: ActuatorLimits = DEFAULT_LIMITS) -> "SimulatedBoat":
        """A boat equal to `model`: same coefficients, geometry and actuators, no unmodelled effects."""
        return cls(name="ideal model", parameters=model.params, geometry=model.geometry, limits=limits,
                   thrust_dead_band_rps=0.0, command_latency_s=0.0, gnss_antenna_m=(0.0, 0.0),
                   hull=HullForm(gnss_antenna_height_m=0.0), ideal=True)

    def model(self) -> VesselModel:
        """The boat's own equations (what the simulator integrates)."""
        return VesselModel(self.parameters, self.geometry)

    def with_parameters(self, parameters: VesselParameters, name: str | None = None) -> "SimulatedBoat":
        return replace(self, parameters=parameters, name=name or self.name)

    def describe(self, reference: VesselParameters = DEFAULT_PARAMETERS) -> str:
        """One line for reports: the boat and how far its coefficients are from `reference`."""
        if self.ideal:
            return f"{self.name} (the simulated boat equals the model)"
        d = parameter_mismatch(self.parameters, reference)
        worst = max(d, key=lambda k: abs(d[k]))
        return (f"{self.name}: coefficients {min(abs(v) for v in d.values()) * 100:.0f}-"
                f"{max(abs(v) for v in d.values()) * 100:.0f} % from the model's ({worst} {d[worst] * 100:+.0f} %), "
                f"reverse thrust x{self.geometry.reverse_thrust_ratio:g}, dead band {self.thrust_dead_band_rps:g} rev/s, "
                f"latency {self.command_latency_s * 1000:.0f} ms, motor lag {self.limits.motor_time_constant_s:g} s, "
                f"GNSS antenna at ({self.gnss_antenna_m[0]:g}, {self.gnss_antenna_m[1]:g}) m")


DEFAULT_BOAT = SimulatedBoat()


def randomised_parameters(rng: np.random.Generator, low: float, high: float,
                          reference: VesselParameters = DEFAULT_PARAMETERS) -> VesselParameters:
    """Coefficients each `low`..`high` (relative, random sign) away from `reference`: a hull as far
    from a prior as real ones are. Signs of the coefficients are kept (damping stays dissipative)."""
    ref = reference.to_dict()
    values = {}
    for name, v in ref.items():
        rel = rng.uniform(low, high) * rng.choice((-1.0, 1.0))
        values[name] = v * (1.0 + rel)
    return VesselParameters.from_dict(values, source="randomised boat")


def random_boat(seed: int, low: float = 0.10, high: float = 0.40) -> SimulatedBoat:
    """The lake boat's unmodelled effects with coefficients `low`..`high` off the defaults, drawn by
    `seed` (`randomised_parameters`): the randomised boats of the tests and the model-chain bench."""
    return DEFAULT_BOAT.with_parameters(randomised_parameters(np.random.default_rng(seed), low, high),
                                        name=f"random boat {seed} ({low * 100:.0f}-{high * 100:.0f} %)")


def parameter_mismatch(boat: VesselParameters, model: VesselParameters) -> dict[str, float]:
    """Relative difference (boat - model) / |model| per coefficient."""
    b, m = boat.to_dict(), model.to_dict()
    return {k: (b[k] - m[k]) / abs(m[k]) if m[k] else 0.0 for k in m}


def scaled_parameters(parameters: VesselParameters, error: float, rng: np.random.Generator) -> VesselParameters:
    """A model `error` (relative) away from `parameters` on every coefficient: each scaled by
    (1 + error * sign) with a random sign per coefficient (the model-quality sweep of the control bench)."""
    values = {k: v * (1.0 + error * rng.choice((-1.0, 1.0))) for k, v in parameters.to_dict().items()}
    return VesselParameters.from_dict(values, source=f"model {error * 100:.0f} % off")
