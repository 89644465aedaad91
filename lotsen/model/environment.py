"""Environmental forces beyond the seed's calm water: current (handled in `vessel_rhs`) and wind.

Wind follows Fossen (2021, sec. 10.1) with constant coefficients for a small hull:
    tau_wind = -1/2 rho_air V_rw^2 [C_X cos(g) A_F, C_Y sin(g) A_L, C_N sin(2 g) A_L L]
with g = gamma_rw the direction the relative wind comes from (0 = from ahead, +90 deg = from
starboard), so wind from starboard pushes the boat to port.

Gusts (made in the simulator, seeded): the wind speed is W + w(t), w a first-order Gauss-Markov
(Ornstein-Uhlenbeck) process with standard deviation `wind_gust_std_mps` and time constant
`wind_gust_time_constant_s`; the direction wanders the same way by `wind_direction_std_deg`.

Wind waves (`Waves`, made in the simulator: `lotsen.sim.waves`): a directional JONSWAP sea given by
its significant wave height, peak period, the direction it comes from and its spreading. A 1 m boat
on a lake meets Hs 3-10 cm at Tp 0.7-1.2 s (fetch-limited growth: 4 m/s over 300 m gives about
Hs 0.035 m, Tp 0.66 s; 5 m/s over 500 m about Hs 0.06 m, Tp 1.0 s). Growth ties height to period:
a wind sea of a long period is a high one (`wind_sea_hs_floor_m`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Waves:
    """A wind sea: JONSWAP spectrum (DNV-RP-C205 sec. 3.5.5; Fossen 2021 sec. 10.2.1) of significant
    wave height `hs_m` and peak period `tp_s`, peak enhancement `gamma`, coming FROM `from_deg`
    (meteorological, like the wind) with cos-2s directional spreading of exponent `spreading`
    (0: long-crested; 10 is a typical wind sea)."""

    hs_m: float
    tp_s: float
    from_deg: float = 0.0
    spreading: float = 10.0
    gamma: float = 3.3

    def __post_init__(self) -> None:
        if not (self.hs_m >= 0.0 and self.tp_s > 0.0 and self.spreading >= 0.0 and self.gamma >= 1.0):
            raise ValueError(f"waves: Hs >= 0, Tp > 0, spreading >= 0 and gamma >= 1, got {self}")

    @property
    def peak_frequency_radps(self) -> float:
        return 2.0 * math.pi / self.tp_s

    def describe(self) -> str:
        crest = "long-crested" if self.spreading == 0.0 else f"spreading s={self.spreading:g}"
        return f"Hs {self.hs_m * 100:.0f} cm, Tp {self.tp_s:.2g} s, from {self.from_deg:.0f} deg, {crest}"


GRAVITY_MPS2 = 9.81  # the one g of the package (sensors, tilt, waves)
#: JONSWAP's fetch-limited growth (Hasselmann et al. 1973; US Army Coastal Engineering Manual II-2):
#: g Hs / U^2 = 0.0016 (g F / U^2)^(1/2) and g Tp / U = 0.286 (g F / U^2)^(1/3), wind U, fetch F
JONSWAP_HS_GROWTH = 0.0016
JONSWAP_TP_GROWTH = 0.286
#: Pierson-Moskowitz's fully developed sea: its peak frequency w_p = 0.877 g / U
PM_PEAK = 0.877


def wind_sea_hs_floor_m(tp_s: float) -> float:
    """The lowest significant wave height a wind sea of peak period `tp_s` has. With the fetch eliminated
    from JONSWAP's growth laws, Hs = 0.0016 (g Tp / 0.286)^(3/2) U^(1/2) / g grows with the wind U, and a
    wind raises waves of period Tp only up to a fully developed sea (w_p = 0.877 g / U), so
    U >= 0.877 g Tp / (2 pi). Tp 0.66 s: 1.7 cm (the module docstring's 4 m/s over 300 m: 3.5 cm); 0.8 s:
    2.4 cm; 1.0 s: 3.8 cm; 1.2 s: 5.5 cm; 2.8 s: 30 cm. Motion a hull's IMU reads at a long period and a
    small height is not a wind sea: the hull's own trim and heel in manoeuvres, or a passing wake."""
    u_min = PM_PEAK * GRAVITY_MPS2 * tp_s / (2.0 * math.pi)
    return JONSWAP_HS_GROWTH * (GRAVITY_MPS2 * tp_s / JONSWAP_TP_GROWTH) ** 1.5 * math.sqrt(u_min) / GRAVITY_MPS2


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
    waves: Waves | None = None  # a wind sea (None or Hs 0: flat water)

    @property
    def wavy(self) -> bool:
        """A wind sea is set (Hs > 0)."""
        return self.waves is not None and self.waves.hs_m > 0.0

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
    # the air's velocity in the earth frame: it moves TO beta + pi
    return apparent_wind_force(psi, u, v, -W * math.cos(beta), -W * math.sin(beta), *wind_drag_coefficients(coeff))


def wind_drag_coefficients(coeff: WindCoefficients = WindCoefficients()) -> tuple[float, float, float]:
    """(k_X, k_Y, k_N) = 1/2 rho_air (C_X A_F, C_Y A_L, C_N A_L L) of `apparent_wind_force`."""
    q = 0.5 * coeff.rho_air
    return (q * coeff.C_X * coeff.frontal_area_m2, q * coeff.C_Y * coeff.lateral_area_m2,
            q * coeff.C_N * coeff.lateral_area_m2 * coeff.length_m)


def apparent_wind_force(psi, u, v, wind_n, wind_e, k_x, k_y, k_n, k_nv=0.0, cos=math.cos,  # type: ignore[no-untyped-def]
                        sin=math.sin, sqrt=math.sqrt):
    """The wind model above without angles: with the apparent wind (u_rw, v_rw) = (u, v) - R(psi)^T w,
    V cos(gamma) = u_rw, V sin(gamma) = v_rw, V^2 sin(2 gamma) = 2 u_rw v_rw, so

        tau = -[k_X V u_rw, k_Y V v_rw, 2 k_N u_rw v_rw + k_Nv V v_rw],   V = |(u_rw, v_rw)|

    (w = earth-frame velocity of the air, k = `wind_drag_coefficients`). `k_nv` (0 in the simulator's
    Fossen form) is a yaw moment that follows the side force, k_Nv = l k_Y with l the lateral centre of
    pressure ahead of the origin: the other shape real hulls show (beam wind turns them, where the
    sin(2 gamma) moment is zero); identification estimates both. Smooth, so that identification can
    differentiate it: `cos`, `sin`, `sqrt` may be CasADi's or numpy's."""
    c, s = cos(psi), sin(psi)
    urw = u - (wind_n * c + wind_e * s)
    vrw = v - (-wind_n * s + wind_e * c)
    V = sqrt(urw * urw + vrw * vrw + 1e-12)
    return (-k_x * V * urw, -k_y * V * vrw, -2.0 * k_n * urw * vrw - k_nv * V * vrw)
