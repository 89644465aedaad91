"""Environmental forces beyond the seed's calm water: current (handled in `vessel_rhs`) and wind.

Wind follows Fossen (2021, sec. 10.1) with constant coefficients for a small hull:
    tau_wind = -1/2 rho_air V_rw^2 [C_X cos(g) A_F, C_Y sin(g) A_L, C_N sin(2 g) A_L L]
with g = gamma_rw the direction the relative wind comes from (0 = from ahead, +90 deg = from
starboard), so wind from starboard pushes the boat to port.

Gusts (made in the simulator, seeded): the wind speed is W + w(t), w a first-order Gauss-Markov
(Ornstein-Uhlenbeck) process with standard deviation `wind_gust_std_mps` and time constant
`wind_gust_time_constant_s`; the direction wanders the same way by `wind_direction_std_deg`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Environment:
    """Current and wind in the earth frame; direction is where they come FROM for wind (meteorological)
    and where the current flows TO (oceanographic), both in degrees clockwise from north."""

    current_speed_mps: float = 0.0
    current_to_deg: float = 0.0
    wind_speed_mps: float = 0.0
    wind_from_deg: float = 0.0
    wave_force_std_N: float = 0.0  # band-limited wave disturbance (made in the simulator)
    wave_period_s: float = 1.5
    wind_gust_std_mps: float = 0.0  # gusts on the wind speed (0: steady wind)
    wind_gust_time_constant_s: float = 8.0
    wind_direction_std_deg: float = 0.0  # slow wander of the wind direction (same time constant x 4)

    @property
    def gusty(self) -> bool:
        return bool(self.wind_gust_std_mps or self.wind_direction_std_deg)

    @property
    def current_ne(self) -> tuple[float, float]:
        a = math.radians(self.current_to_deg)
        return (self.current_speed_mps * math.cos(a), self.current_speed_mps * math.sin(a))


@dataclass(frozen=True)
class WindCoefficients:
    rho_air: float = 1.225
    frontal_area_m2: float = 0.05  # above-water frontal area A_F of the 0.3 m wide hull
    lateral_area_m2: float = 0.15  # above-water lateral area A_L
    length_m: float = 0.99
    C_X: float = 0.6
    C_Y: float = 0.8
    C_N: float = 0.1


def wind_force(psi: float, u: float, v: float, env: Environment,
               coeff: WindCoefficients = WindCoefficients(), speed_mps: float | None = None,
               from_deg: float | None = None) -> tuple[float, float, float]:
    """Body-frame wind force and moment for the vessel at heading psi and ground velocity (u, v).

    `speed_mps` / `from_deg` override the environment's mean wind (the simulator's gusts)."""
    W = env.wind_speed_mps if speed_mps is None else speed_mps
    if W == 0.0:
        return (0.0, 0.0, 0.0)
    beta = math.radians(env.wind_from_deg if from_deg is None else from_deg)
    # wind velocity (moving TO beta + pi) expressed in the body frame
    uw = -W * math.cos(beta - psi)
    vw = -W * math.sin(beta - psi)
    urw, vrw = u - uw, v - vw
    V2 = urw * urw + vrw * vrw
    gamma = math.atan2(vrw, urw)  # where the relative wind comes from; 0 = straight ahead
    q = 0.5 * coeff.rho_air * V2
    return (-coeff.C_X * math.cos(gamma) * coeff.frontal_area_m2 * q,
            -coeff.C_Y * math.sin(gamma) * coeff.lateral_area_m2 * q,
            -coeff.C_N * math.sin(2.0 * gamma) * coeff.lateral_area_m2 * coeff.length_m * q)
