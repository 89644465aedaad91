"""An independent 6-DOF hull: a plant for tests and benches that is *not* lotsen's grey box.

Written from Fossen's *Handbook of Marine Craft Hydrodynamics and Motion Control* (2nd ed., 2021)
in the style of his Python Vehicle Simulator, with numpy only; it imports nothing of lotsen's model
or simulator, so a test that identifies or flies it checks lotsen against a hull of another
structure. The craft: a 0.99 m, 13 kg monohull with two azimuth thrusters aft at (-0.39, +-0.07) m
(1 starboard, 2 port) and a bow tunnel thruster at +0.37 m.

Frames and signs (lotsen's, docs/model.md): earth frame NED, body frame x forward, y starboard, z
down; heading psi from north, positive clockwise. Inputs (alpha1, alpha2, n1, n2, nt): azimuth
angles in rad (alpha > 0 turns a unit's thrust to starboard) and propeller speeds in rev/s, signed.

Equations (Fossen 2021, ch. 6-10), state eta = [x, y, z, phi, theta, psi], nu = [u, v, w, p, q, r]:

    eta_dot = J(eta) nu                                          (ZYX Euler angles)
    M nu_r_dot + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau_thr + tau_wind + tau_wave
    nu_dot = nu_r_dot + nu_c_dot,  nu_r = nu - [R^T v_c; 0]      (current, sec. 10.3)

- M = M_RB + M_A: rigid body with the centre of gravity r_g off the origin (the origin on the
  waterline amidships), added mass diagonal; C_RB in its linear-velocity-independent form
  (Fossen's Property 8.1, so the relative-velocity form holds in an irrotational current), C_A from
  M_A (Fossen's m2c) with the Munk yaw moment kept at `munk_fraction` (the hull's own lift cancels
  part of it on real hulls, as the Otter model in the Python Vehicle Simulator drops it entirely).
- Resistance: a frictional part (ITTC-57 line with a form factor) and a residuary (wave) part that
  grows with the Froude number, plus a small linear term at creeping speed: not the model's
  X_u u + X_uu |u| u.
- Sway and yaw: slender-body hull lift (proportional to U v), cross-flow drag by strip theory
  (2-D drag coefficient on 20 strips, Fossen's crossFlowDrag), small linear damping.
- Roll, pitch and heave: hydrostatic restoring (metacentric heights, waterplane area), linear plus
  quadratic roll damping; the thrusters sit below the waterline, the wind acts above it, so both
  heel the boat.
- Propellers: thrust rho D^4 K_T(J) n|n| with K_T falling linearly with the advance ratio
  J = V_a / (|n| D) (wake fraction w), astern thrust weaker; a dead band at low speed. The pods make
  lift when the water meets them at an angle (a low-aspect foil in the local flow plus the
  propeller's slipstream from momentum theory). The bow thruster's thrust fades with forward
  speed (the tunnel's jet is bent away).
- Actuators: servos slew at a limited rate to within +-45 deg; ESC + motor first-order with a ramp
  limit; set-points reach them after a small latency.
- Environment (its own forms, not lotsen's): an earth-frame current (constant plus an optional
  slow sinusoidal variation of speed and direction), wind as quadratic drag of the apparent wind
  on each body axis with its own moment arms (yaw and heel), gusts as an Ornstein-Uhlenbeck wind
  speed and a wandering (Ornstein-Uhlenbeck) wind direction; waves (below). All seeded.

Waves (`WaveField`, `HullEnvironment.wave_*`, `--waves HS,TP,FROM_DEG`); sources: Fossen 2021 sec. 10.2
(wave spectra, the JONSWAP spectrum and directional spreading), DNV-RP-C205 (2010) sec. 3.5.5
(JONSWAP in Hs and Tp), Faltinsen 1990 (*Sea Loads on Ships and Offshore Structures*) ch. 2 (linear
waves, Table 2.1), ch. 3 (Froude-Krylov and diffraction loads, the long-wave approximation) and ch. 5
(mean drift), Newman 1977 (*Marine Hydrodynamics*) ch. 6 (waves; G. I. Taylor's long-wave force).
- The sea: linear, deep water (k = w^2 / g), a JONSWAP spectrum (gamma 3.3 by default) spread as
  cos^(2s) about the mean direction (s = 0: long-crested), 50 components, one random direction per
  frequency, random phases and frequencies inside their bands, scaled to m0 = Hs^2 / 16; its own
  seed stream, so waves leave the gusts as they were. Elevation, orbital velocity and acceleration
  with e^{-kz} decay at any earth point (`WaveField.elevation`, `.kinematics`,
  `Hull6DOF.wave_elevation`); `realised_hs_m` and `realised_tp_s` are the truth a sea-state
  estimator should find.
- First-order loads, linear in the wave, on the 20 strips where they are now (the hull's position
  and heading at the step's midpoint, so the encounter frequency w - k U cos(beta) follows from
  the motion itself), with the water's acceleration averaged over a strip's breadth (sin x / x of
  the linear wave, exact for a rectangular section) and the hull's mean depth ((1 - e^{-kT}) / kT):
  surge and sway the long-wave force (displaced mass + added mass) x acceleration, its
  Froude-Krylov share (displaced mass) in earth axes at the centre of buoyancy, the diffraction
  share (added mass) in the hull's axes; heave, roll and pitch the restoring relative to the wave
  surface: the waterplane's mean elevation, its least-squares pitch and its roll (the elevation's
  transverse moment over each strip's breadth, exact for the linear wave) times the heave stiffness,
  rho g I_L and rho g I_T, plus (displaced + heave added mass) x the water's vertical acceleration
  (Froude-Krylov's pressure gradient, the Smith effect, and diffraction); yaw the moment of the
  sway strip forces. The added mass and the damping act on the velocity relative to the water
  (the orbital velocity over the hull, the wave surface's heave, roll and pitch rates: Morison's
  relative-velocity form, as nu_r treats the current); in waves the heave restoring and damping act
  along the vertical. The loads are evaluated once per internal step and held over it, as the
  current and the wind are. A hull much shorter than the waves follows the surface (heave RAO -> 1,
  specific force normal to it); waves shorter than the hull average out along it.
- Second-order mean drift (Faltinsen 1990 ch. 5, the drift force in short waves with the finite
  draft's correction): per component 1/2 rho g a^2 R^2 times the integral of (n . k)^2 (-n) over
  the waterline's lit side (and its yaw moment), R^2 Ursell's (1947) reflection by a wall of the
  hull's draft, pi^2 I1(kT)^2 / (pi^2 I1(kT)^2 + K1(kT)^2): it goes with Hs^2 and is small when
  kT << 1. Slowly varying: the mean times the wave groups' normalised squared envelope at the hull
  (Newman's 1974 approximation). `Hull6DOF.mean_wave_drift()`.
- Not modelled: nonlinear and breaking waves, finite depth, the current's effect on the waves,
  frequency-dependent added mass and damping (constants here: no radiation memory), the drift's
  growth with speed (added resistance), the hull's own radiated waves in the drift (the reflection
  is a fixed wall's), wave loads on the thruster pods (their inflow does see the orbital velocity),
  slamming and green water. The nonlinear 6-DOF kinematics turn the first-order loads and motions
  into second-order means of their own (loads at displaced positions, rotated by roll and pitch,
  coning of roll and pitch into heading) on top of the drift formula: measured, not removed.

Integration: classical RK4 at a fixed internal step (`step_s`, default 5 ms = 200 Hz), actuators
advanced between the RK4 steps and acting through their mean over each step; deterministic.

`record(...)` makes an identification record (lotsen.sysid.data.IdRecord, the format only) the way
lotsen's lake records are written (docs/sysid.md "Data"): achieved actuators at 50 Hz as interval
means stamped at the interval start (`# inputs: mean`), GNSS north/east at 8 Hz with 1 cm noise,
psi (0.01 rad noise) and r (0.003 rad/s noise, optional gyro offset) on the fix rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Sequence

import numpy as np

RHO_WATER = 1000.0
RHO_AIR = 1.225
GRAVITY = 9.81
NU_WATER = 1.0e-6  # kinematic viscosity, m^2/s


@dataclass(frozen=True)
class HullParameters:
    """The hull, its propulsion and its actuators. SI units, rev/s, rad."""

    # main dimensions
    length_m: float = 0.99
    beam_m: float = 0.22
    draft_m: float = 0.085
    mass_kg: float = 13.0
    r_g_m: tuple[float, float, float] = (-0.01, 0.0, 0.02)  # centre of gravity from the origin (z down)
    gyration_radii_m: tuple[float, float, float] = (0.085, 0.25, 0.265)  # roll, pitch, yaw about the CG
    waterplane_coefficient: float = 0.80
    gm_transverse_m: float = 0.035  # metacentric heights
    gm_longitudinal_m: float = 0.90
    # added mass (kg, kg m^2), positive numbers: -X_udot, -Y_vdot, -Z_wdot, -K_pdot, -M_qdot, -N_rdot
    added_mass: tuple[float, float, float, float, float, float] = (1.2, 11.5, 13.0, 0.02, 0.6, 0.72)
    munk_fraction: float = 0.65  # share of the Munk yaw moment the hull keeps
    # resistance
    wetted_area_m2: float = 0.30
    form_factor: float = 0.25  # k: friction x (1 + k)
    residuary_coefficient: float = 0.052  # C_R at and above the hump
    froude_hump: float = 0.42  # C_R = C_Rmax Fn^4 / (Fn^4 + Fn_hump^4)
    surge_linear_kg_s: float = 1.0  # creeping speed (laminar, appendages)
    # sway / yaw
    sway_linear_kg_s: float = 2.5
    yaw_linear_kgm2_s: float = 1.1
    lift_slope: float = 0.30  # hull lift coefficient per rad of drift (slender wing, ~ pi T / L)
    lift_centre_m: float = 0.06  # ahead of the origin
    crossflow_cd: float = 0.78  # 2-D drag coefficient of a section (Hoerner, B / 2T = 1.3)
    strips: int = 20
    # roll / pitch / heave damping (relative damping of the free oscillation) and quadratic roll
    roll_damping_ratio: float = 0.12
    roll_quadratic: float = 0.05  # kg m^2 (K_|p|p)
    pitch_damping_ratio: float = 0.45
    heave_damping_ratio: float = 0.45
    # azimuth units: position (x, y, z) of unit 1 (starboard); unit 2 mirrored
    unit_position_m: tuple[float, float, float] = (-0.39, 0.07, 0.07)
    propeller_diameter_m: float = 0.045
    kt0: float = 0.27  # K_T at J = 0 (bollard)
    j_zero_thrust: float = 1.35  # K_T falls linearly to 0 at this J
    wake_fraction: float = 0.10
    astern_ratio: float = 0.75
    dead_band_rps: float = 2.5
    pod_area_m2: float = 0.0012  # lateral area of the pod and strut
    pod_lift_slope: float = 1.8  # per rad (low aspect ratio)
    # bow tunnel thruster
    bow_position_m: tuple[float, float, float] = (0.37, 0.0, 0.04)
    bow_thrust_coefficient: float = 0.00036  # N per (rev/s)^2 at rest
    bow_fade_speed_mps: float = 0.45  # thrust x 1 / (1 + (u / this)^2)
    # actuators
    alpha_max_rad: float = math.radians(45.0)
    alpha_rate_radps: float = math.radians(120.0)
    n_max_rps: float = 100.0
    n_bow_max_rps: float = 80.0
    motor_time_constant_s: float = 0.09
    bow_motor_time_constant_s: float = 0.07
    motor_ramp_rps2: float = 500.0
    latency_s: float = 0.02


@dataclass(frozen=True)
class HullEnvironment:
    """Water and air. Directions in degrees clockwise from north: the current flows TO, the wind
    comes FROM. Gusts: an OU process on the wind speed (std `gust_fraction` x mean, time constant
    `gust_time_constant_s`); the direction wanders as another OU process (std `wind_wander_deg`,
    time constant `wander_time_constant_s`). The current's speed and direction vary slowly as
    sinusoids (`current_variation` of the speed, `current_wander_deg`, period `current_period_s`).
    Waves (`WaveField`): a JONSWAP sea of significant height `wave_hs_m` (0: none) and peak period
    `wave_tp_s`, coming FROM `wave_from_deg`, long-crested for `wave_spreading` 0 or None, else
    spread as cos^(2s) about the mean direction; `wave_components` regular components."""

    current_mps: float = 0.0
    current_to_deg: float = 0.0
    current_variation: float = 0.0
    current_wander_deg: float = 0.0
    current_period_s: float = 180.0
    wind_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_fraction: float = 0.0
    gust_time_constant_s: float = 5.0
    wind_wander_deg: float = 0.0
    wander_time_constant_s: float = 40.0
    # the hull above water: frontal and lateral areas, drag coefficients, moment arms
    frontal_area_m2: float = 0.022
    lateral_area_m2: float = 0.085
    cx: float = 0.7
    cy: float = 0.95
    wind_arm_x_m: float = 0.07  # centre of lateral pressure ahead of the origin
    wind_arm_z_m: float = -0.06  # above the waterline (z down)
    wave_hs_m: float = 0.0
    wave_tp_s: float = 1.0
    wave_from_deg: float = 0.0
    wave_spreading: float | None = 0.0  # s of cos^(2s); 0 or None: long-crested
    wave_gamma: float = 3.3  # JONSWAP peak enhancement (1: Pierson-Moskowitz)
    wave_components: int = 50
    seed: int = 0


# ----------------------------------------------------------------------------------------------
# waves: a linear, deep-water, irregular sea (its own code, written from the literature)

def jonswap_spectrum(omega_radps: Any, hs_m: float, tp_s: float, gamma: float = 3.3) -> np.ndarray:
    """One-sided JONSWAP wave spectrum S(w) in m^2 s/rad: the Pierson-Moskowitz form in Hs and the
    peak frequency w_p = 2 pi / Tp times the peak enhancement gamma^r, r = exp(-(w - w_p)^2 /
    (2 sigma^2 w_p^2)), sigma 0.07 below the peak and 0.09 above, normalised by 1 - 0.287 ln(gamma)
    (DNV-RP-C205 (2010) sec. 3.5.5; Fossen 2021 sec. 10.2.2, the JONSWAP spectrum)."""
    w = np.asarray(omega_radps, dtype=float)
    wp = 2.0 * math.pi / tp_s
    pm = 5.0 / 16.0 * hs_m ** 2 * wp ** 4 * w ** -5.0 * np.exp(-1.25 * (wp / w) ** 4)
    sigma = np.where(w <= wp, 0.07, 0.09)
    r = np.exp(-((w - wp) ** 2) / (2.0 * sigma ** 2 * wp ** 2))
    return (1.0 - 0.287 * math.log(gamma)) * pm * gamma ** r


def spreading_function(mu_rad: Any, s: float) -> np.ndarray:
    """Directional spreading D(mu) = Gamma(s + 1) / (sqrt(pi) Gamma(s + 1/2)) cos^(2s)(mu) for
    |mu| < pi/2 about the mean direction, 0 beyond; integrates to 1 (Fossen 2021 sec. 10.2.2, the
    directional spectrum, there with integer s; s = 1 is 2/pi cos^2)."""
    mu = np.asarray(mu_rad, dtype=float)
    c = math.exp(math.lgamma(s + 1.0) - math.lgamma(s + 0.5)) / math.sqrt(math.pi)
    return np.where(np.abs(mu) < 0.5 * math.pi, c * np.abs(np.cos(mu)) ** (2.0 * s), 0.0)


class WaveField:
    """A linear irregular sea in deep water, earth-fixed: the sum of `components` regular waves

        zeta(t, N, E) = sum_i a_i cos(w_i t - k_i (N cos chi_i + E sin chi_i) + eps_i),  k_i = w_i^2 / g

    (Faltinsen 1990 sec. 2.2, Table 2.1; Fossen 2021 sec. 10.2.1), chi_i the direction a component
    travels TO (the waves come FROM `from_deg`, clockwise from north). Frequencies: one per equal
    band over 0.5-3 w_p, drawn at random inside its band (no repetition period); amplitudes
    a_i = sqrt(2 S(w_i) dw), scaled so that sum a_i^2 / 2 = Hs^2 / 16 exactly (the spectrum's tail
    beyond the bands, ~1 % of its energy, is put back into them); random phases; directions: one
    random direction per frequency, drawn from the spreading function (the single-summation method:
    no two components share a frequency, so the sea is ergodic, not phase-locked, and it costs one
    component per frequency). All from the seed's own stream."""

    def __init__(self, hs_m: float, tp_s: float, from_deg: float = 0.0, spreading: float | None = None,
                 gamma: float = 3.3, seed: int = 0, components: int = 50) -> None:
        if hs_m <= 0.0 or tp_s <= 0.0 or components < 1:
            raise ValueError("waves need Hs > 0, Tp > 0 and at least one component")
        self.hs_m, self.tp_s, self.from_deg, self.gamma = float(hs_m), float(tp_s), float(from_deg), float(gamma)
        self.spreading = float(spreading or 0.0)
        rng = np.random.default_rng(np.random.SeedSequence([seed, 6008]))  # not the gusts' stream (6006)
        # draw every stream whatever the options, so spreading or gamma leave the phases as they are
        in_band, phases, u_dir = rng.uniform(0.0, 1.0, (3, components))
        wp = 2.0 * math.pi / tp_s
        edges = np.linspace(0.5 * wp, 3.0 * wp, components + 1)
        dw = np.diff(edges)
        w = edges[:-1] + in_band * dw
        s_w = jonswap_spectrum(w, hs_m, tp_s, gamma)
        a = np.sqrt(2.0 * s_w * dw)
        scale = (hs_m / 4.0) / math.sqrt(0.5 * float(np.sum(a * a)))
        a *= scale
        mean_to = math.radians(from_deg) + math.pi
        if self.spreading > 0.0:  # inverse transform of the spreading function's distribution
            mu = np.linspace(-0.5 * math.pi, 0.5 * math.pi, 2001)
            d = spreading_function(mu, self.spreading)
            cdf = np.concatenate([[0.0], np.cumsum(0.5 * (d[1:] + d[:-1]) * np.diff(mu))])
            cdf /= cdf[-1]
            to = mean_to + np.interp(u_dir, cdf, mu)
        else:
            to = np.full(components, mean_to)
        self.omega_radps = w
        self.wavenumber_radpm = w * w / GRAVITY
        self.amplitude_m = a
        self.phase_rad = 2.0 * math.pi * phases
        self.to_rad = to
        self.cos_to, self.sin_to = np.cos(to), np.sin(to)
        self.spectral_density = s_w * scale * scale  # m^2 s/rad at omega_radps, as realised

    @property
    def realised_hs_m(self) -> float:
        """4 sqrt(m0) of the components: the significant wave height this sea has."""
        return 4.0 * math.sqrt(0.5 * float(np.sum(self.amplitude_m ** 2)))

    @property
    def realised_tp_s(self) -> float:
        """The period of the component where the realised spectral density peaks."""
        return 2.0 * math.pi / float(self.omega_radps[int(np.argmax(self.spectral_density))])

    def _phase(self, t: Any, north: Any, east: Any) -> np.ndarray:
        t, n, e = (np.asarray(v, dtype=float)[..., None] for v in (t, north, east))
        return self.omega_radps * t - self.wavenumber_radpm * (self.cos_to * n + self.sin_to * e) + self.phase_rad

    def elevation(self, t: Any, north: Any, east: Any) -> Any:
        """Surface elevation (m, up) at time(s) t and earth-fixed point(s) (north, east); broadcasts."""
        z = np.sum(self.amplitude_m * np.cos(self._phase(t, north, east)), axis=-1)
        return float(z) if z.ndim == 0 else z

    def kinematics(self, t: Any, north: Any, east: Any, depth_m: Any = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(velocity, acceleration) of the water, NED components on the first axis, at `depth_m`
        below the mean surface, from the potential phi = -(g a / w) e^{-kz} sin(theta) (Faltinsen's
        Table 2.1 with zeta = a cos(theta), z down): u = w a e^{-kz} cos(theta) along the travel
        direction, w_down = w a e^{-kz} sin(theta); the accelerations their time derivatives."""
        th = self._phase(t, north, east)
        decay = np.exp(-self.wavenumber_radpm * np.asarray(depth_m, dtype=float)[..., None])
        wa = self.omega_radps * self.amplitude_m * decay
        c, s = np.cos(th), np.sin(th)
        horiz_v, down_v = wa * c, wa * s
        horiz_a, down_a = -self.omega_radps * wa * s, self.omega_radps * wa * c
        vel = np.stack([np.sum(horiz_v * self.cos_to, -1), np.sum(horiz_v * self.sin_to, -1), np.sum(down_v, -1)])
        acc = np.stack([np.sum(horiz_a * self.cos_to, -1), np.sum(horiz_a * self.sin_to, -1), np.sum(down_a, -1)])
        return vel, acc


def _bessel_i1(x: float) -> float:
    """Modified Bessel function I_1 (its integral representation, trapezoidal over a period)."""
    t = np.linspace(0.0, math.pi, 2001)
    f = np.exp(x * np.cos(t)) * np.cos(t)
    return float(np.sum(0.5 * (f[1:] + f[:-1])) * (t[1] - t[0]) / math.pi)


def _bessel_k1(x: float) -> float:
    """Modified Bessel function K_1 = int_0^inf exp(-x cosh t) cosh t dt (x > 0)."""
    t = np.linspace(0.0, math.acosh(60.0 / x + 1.0), 4001)
    f = np.exp(-x * np.cosh(t)) * np.cosh(t)
    return float(np.sum(0.5 * (f[1:] + f[:-1])) * (t[1] - t[0]))


def reflection_coefficient_squared(k_radpm: float, draft_m: float) -> float:
    """R^2 of a wall of draft d in deep water: Ursell's (1947) vertical barrier,
    pi^2 I1(kd)^2 / (pi^2 I1(kd)^2 + K1(kd)^2), the finite-draft correction Faltinsen (1990, ch. 5)
    applies to the short-wave drift force; ~ pi^2 (kd)^4 / 4 in long waves, 1 in short ones."""
    kd = k_radpm * draft_m
    i1, k1 = _bessel_i1(kd), _bessel_k1(kd)
    return math.pi ** 2 * i1 * i1 / (math.pi ** 2 * i1 * i1 + k1 * k1)


def _waterline_drift_table(length_m: float, beam_m: float, cwp: float, points: int = 201, angles: int = 361
                           ) -> tuple[np.ndarray, np.ndarray]:
    """The short-wave drift integrals of the waterline, per unit 1/2 rho g a^2 R^2: over its
    lit side (where the wave meets it, n . k < 0), the force -(n . k)^2 n dl and its yaw moment
    (Faltinsen 1990 ch. 5, the drift force on a ship in short waves: the local wall reflects the
    wave's momentum flux normal to it). `angles` travel directions relative to the bow over 0-2 pi;
    rows: surge (m), sway (m), yaw (m^2). The waterline: half-breadth B/2 (1 - |2x/L|^n)."""
    n_exp = cwp / (1.0 - cwp)
    x = np.linspace(-0.5 * length_m, 0.5 * length_m, points)
    y = 0.5 * beam_m * (1.0 - np.abs(2.0 * x / length_m) ** n_exp)
    dx, dy = np.diff(x), np.diff(y)
    dl = np.hypot(dx, dy)
    xm, ym = 0.5 * (x[1:] + x[:-1]), 0.5 * (y[1:] + y[:-1])
    nx, ny = -dy / dl, dx / dl  # starboard side's outward normal (stern to bow)
    # both sides: the port side mirrors the starboard one
    xm, ym, nx, ny, dl = (np.concatenate([xm, xm]), np.concatenate([ym, -ym]), np.concatenate([nx, nx]),
                          np.concatenate([ny, -ny]), np.concatenate([dl, dl]))
    beta = np.linspace(0.0, 2.0 * math.pi, angles)
    kn = np.outer(np.cos(beta), nx) + np.outer(np.sin(beta), ny)
    lit = np.where(kn < 0.0, kn * kn * dl, 0.0)
    fx, fy = -lit @ nx, -lit @ ny
    fn = -lit @ (xm * ny - ym * nx)
    return beta, np.vstack([fx, fy, fn])


def _strip_positions(L: float, n: int) -> tuple[list[float], float]:
    dx = L / n
    return [-L / 2 + (i + 0.5) * dx for i in range(n)], dx


class Hull6DOF:
    """The hull in its water: `command(...)`, then `advance(seconds)`; `x3` is lotsen's 3-DOF state
    [N, E, psi, u, v, r]; `eta`, `nu` the 6-DOF ones; `actuators` the achieved (alpha1, alpha2, n1,
    n2, nt); `measure()` the NED velocity and what an accelerometer at the origin measures. In waves:
    `waves` (the WaveField), `wave_elevation(t, north, east)`, `wave_first_order` and `wave_drift`
    (the loads held over the last step, body axes), `mean_wave_drift(heading)`."""

    def __init__(self, params: HullParameters = HullParameters(), environment: HullEnvironment = HullEnvironment(),
                 step_s: float = 0.005, pose: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        self.p = params
        self.env = environment
        self.h = step_s
        self._setup()
        self.reset(pose)

    # -- set-up --------------------------------------------------------------------------------
    def _setup(self) -> None:
        p = self.p
        m = p.mass_kg
        xg, yg, zg = p.r_g_m
        kx, ky, kz = p.gyration_radii_m
        Ig = np.diag([m * kx * kx, m * ky * ky, m * kz * kz])
        S = np.array([[0.0, -zg, yg], [zg, 0.0, -xg], [-yg, xg, 0.0]])
        Ib = Ig - m * S @ S  # inertia about the origin (parallel axes)
        MRB = np.zeros((6, 6))
        MRB[:3, :3] = m * np.eye(3)
        MRB[:3, 3:] = -m * S
        MRB[3:, :3] = m * S
        MRB[3:, 3:] = Ib
        MA = np.diag(p.added_mass)
        self.M = MRB + MA
        self.Minv = np.linalg.inv(self.M)
        self._Minv_rows = [list(map(float, row)) for row in self.Minv]
        self._Ib = [list(map(float, row)) for row in Ib]
        self._A = tuple(float(a) for a in p.added_mass)
        nabla = m / RHO_WATER
        awp = p.waterplane_coefficient * p.length_m * p.beam_m
        self._k_heave = RHO_WATER * GRAVITY * awp
        self._k_roll = RHO_WATER * GRAVITY * nabla * p.gm_transverse_m
        self._k_pitch = RHO_WATER * GRAVITY * nabla * p.gm_longitudinal_m
        M = self.M
        self._d_heave = 2.0 * p.heave_damping_ratio * math.sqrt(self._k_heave * M[2, 2])
        self._d_roll = 2.0 * p.roll_damping_ratio * math.sqrt(self._k_roll * M[3, 3])
        self._d_pitch = 2.0 * p.pitch_damping_ratio * math.sqrt(self._k_pitch * M[4, 4])
        self._strips, self._dx = _strip_positions(p.length_m, p.strips)
        self._k_cf = 0.5 * RHO_WATER * p.draft_m * p.crossflow_cd * self._dx
        self._k_lift = 0.5 * RHO_WATER * p.length_m * p.draft_m * p.lift_slope
        self._k_res = 0.5 * RHO_WATER * p.wetted_area_m2
        self._k_thrust = RHO_WATER * p.propeller_diameter_m ** 4 * p.kt0
        self._disc = math.pi * p.propeller_diameter_m ** 2 / 4.0
        x, y, z = p.unit_position_m
        self._units = ((x, y, z), (x, -y, z))
        e = self.env
        self._k_wx = 0.5 * RHO_AIR * e.cx * e.frontal_area_m2
        self._k_wy = 0.5 * RHO_AIR * e.cy * e.lateral_area_m2
        self.waves: WaveField | None = None
        self._tau_wave: list[float] | None = None  # wave loads (first order + drift), held over a step
        self._nu_wave = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # the water's motion the hull's damping sees
        self.wave_first_order = (0.0,) * 6
        self.wave_drift = (0.0, 0.0, 0.0)
        if e.wave_hs_m > 0.0:
            self.waves = WaveField(e.wave_hs_m, e.wave_tp_s, e.wave_from_deg, e.wave_spreading, e.wave_gamma,
                                   e.seed, e.wave_components)
            self._setup_wave_loads()

    def _setup_wave_loads(self) -> None:
        """What the wave loads need of the hull, once (module docstring, "Waves"). The waterplane's
        breadth b(x) = B (1 - |2x/L|^n), n = C_wp / (1 - C_wp), so its area is C_wp L B; the
        displaced mass, surge and sway added mass spread over the strips as b(x), heave added mass
        as b(x)^2 (2-D heave added mass goes with the breadth squared); the waterplane's own
        restoring in roll and pitch, rho g I_T and rho g I_L, is the metacentric restoring plus
        rho g V BG (B a box of the same waterplane and volume: its depth T_m = V / A_wp, B at T_m / 2)."""
        p, wf = self.p, self.waves
        assert wf is not None
        x = np.array(self._strips)
        dx = self._dx
        cwp = p.waterplane_coefficient
        b = p.beam_m * (1.0 - np.abs(2.0 * x / p.length_m) ** (cwp / (1.0 - cwp)))
        m = p.mass_kg
        a11, a22, a33 = p.added_mass[:3]
        nabla = m / RHO_WATER
        depth = nabla / (cwp * p.length_m * p.beam_m)  # mean depth of the displaced volume
        self._wave_z_b = 0.5 * depth  # centre of buoyancy below the waterline
        bg = self._wave_z_b - p.r_g_m[2]
        self._wave_c44 = self._k_roll + RHO_WATER * GRAVITY * nabla * bg
        self._wave_c55 = self._k_pitch + RHO_WATER * GRAVITY * nabla * bg
        m_s = m * b / b.sum()
        mean = b / b.sum()  # the hull's mean (of the orbital velocity, of the water's acceleration)
        mean33 = b * b / np.sum(b * b)  # the same with heave added mass's weights
        m33 = m_s + a33 * mean33
        m22 = m_s + a22 * mean
        area = b * dx / np.sum(b * dx)  # waterplane weights: the mean elevation over it
        slope = x * b * dx / np.sum(x * x * b * dx)  # the plane's pitch by least squares
        turn = x * m_s / np.sum(x * x * m_s)  # the sway flow's turn along the hull by least squares
        # columns against sinc * cos(theta) and sinc * sin(theta) (components x strips)
        self._wave_wq = np.column_stack([area, slope, m_s, mean33, x * m33, mean, turn])
        self._wave_wp = np.column_stack([area, slope, m_s, mean, x * m22])
        self._wave_wr = b ** 3 * dx / np.sum(b ** 3 * dx)  # transverse waterplane inertia's weights
        self._wave_x = x
        self._wave_half_b = 0.5 * b
        k = wf.wavenumber_radpm
        k_t = k * depth
        self._wave_depth_factor = (1.0 - np.exp(-k_t)) / k_t  # e^{-kz} averaged over the depth
        self._wave_aw = wf.amplitude_m * wf.omega_radps
        self._wave_awd = self._wave_aw * self._wave_depth_factor
        self._wave_aw2 = self._wave_awd * wf.omega_radps
        # second order: reflection of each component by the draft, and the waterline's drift integrals
        r2 = np.array([reflection_coefficient_squared(float(kk), p.draft_m) for kk in k])
        self._wave_drift_a2 = 0.5 * RHO_WATER * GRAVITY * wf.amplitude_m ** 2 * r2  # N/m per component
        self._wave_group = wf.amplitude_m * np.sqrt(r2)  # Newman's weights for the slow drift
        self._wave_group_norm = float(np.sum(self._wave_group ** 2))
        self._drift_beta, self._drift_table = _waterline_drift_table(p.length_m, p.beam_m, cwp)

    def _wave_loads(self) -> list[float]:
        """The wave loads for the coming internal step, evaluated at its midpoint (time and the
        hull's position extrapolated by half a step): first order (Froude-Krylov + diffraction in the
        long-wave approximation, on the strips where they are now) and the drift, in body axes.
        Froude-Krylov's force is the level frame's, turned into the hull's axes by its roll and
        pitch; diffraction's is the added mass times the water's acceleration in the hull's axes; the
        moments are linear in the wave. Also sets the water's motion the damping sees (_nu_wave)."""
        wf = self.waves
        assert wf is not None
        st = self.state
        hh = 0.5 * self.h
        psi = st[5] + hh * st[11]
        cps, sps = math.cos(psi), math.sin(psi)
        n0 = st[0] + hh * (cps * st[6] - sps * st[7])
        e0 = st[1] + hh * (sps * st[6] + cps * st[7])
        t = self.t + hh
        cb = wf.cos_to * cps + wf.sin_to * sps  # travel direction relative to the bow: cos, sin
        sb = wf.sin_to * cps - wf.cos_to * sps
        k = wf.wavenumber_radpm
        th0 = wf.omega_radps * t - k * (wf.cos_to * n0 + wf.sin_to * e0) + wf.phase_rad  # at the origin
        th = th0[:, None] - np.outer(k * cb, self._wave_x)  # at the strips
        c, s = np.cos(th), np.sin(th)
        ky = k * sb
        xb = np.outer(ky, self._wave_half_b)  # half the phase change across a strip's breadth
        small = np.abs(xb) < 1e-3
        xs = np.where(small, 1.0, xb)
        sx, cx = np.sin(xs), np.cos(xs)
        x2 = xb * xb
        sinc = np.where(small, 1.0 - x2 / 6.0, sx / xs)  # elevation's mean across the breadth
        j = np.where(small, 1.0 - x2 / 10.0, 3.0 * (sx - xs * cx) / (xs * xs * xs))  # its transverse slope's
        q = (sinc * c) @ self._wave_wq
        pp = (sinc * s) @ self._wave_wp
        a = wf.amplitude_m
        aw = self._wave_aw
        aw2 = self._wave_aw2
        zeta = float(a @ q[:, 0])  # the waterplane's mean elevation, its pitch and roll
        zeta_dot = -float(aw @ pp[:, 0])
        theta_w = float(a @ q[:, 1])
        theta_dot = -float(aw @ pp[:, 1])
        aky = a * ky
        phi_w = -float(aky @ ((j * s) @ self._wave_wr))
        phi_dot = -float((aky * wf.omega_radps) @ ((j * c) @ self._wave_wr))
        awd = self._wave_awd
        v_mean = awd * sb
        self._nu_wave = (float((awd * cb) @ q[:, 5]), float(v_mean @ q[:, 5]), -zeta_dot, phi_dot, theta_dot,
                         float(v_mean @ q[:, 6]))
        hx, hy = -aw2 * cb, -aw2 * sb  # horizontal acceleration per sinc * sin(theta)
        # Froude-Krylov: the waterplane's hydrostatics of the elevation and the displaced mass times
        # the water's acceleration (the pressure gradient over the volume), in the level frame
        fk_x = float(hx @ pp[:, 2])
        fk_y = float(hy @ pp[:, 2])
        fk_z = float(aw2 @ q[:, 2]) - self._k_heave * zeta
        # diffraction: the added mass times the water's acceleration as the hull's axes see it
        ax, ay, az = float(hx @ pp[:, 3]), float(hy @ pp[:, 3]), float(aw2 @ q[:, 3])
        cph, sph, cth, sth = math.cos(st[3]), math.sin(st[3]), math.cos(st[4]), math.sin(st[4])
        A11, A22, A33 = self._A[:3]
        X = cth * (fk_x + A11 * ax) - sth * (fk_z + A11 * az)
        Y = sth * sph * (fk_x + A22 * ax) + cph * (fk_y + A22 * ay) + cth * sph * (fk_z + A22 * az)
        Z = sth * cph * (fk_x + A33 * ax) - sph * (fk_y + A33 * ay) + cth * cph * (fk_z + A33 * az)
        K = -self._wave_z_b * fk_y + self._wave_c44 * phi_w
        M = self._wave_z_b * fk_x - float(aw2 @ q[:, 4]) + self._wave_c55 * theta_w
        N = float(hy @ pp[:, 4])
        self.wave_first_order = (X, Y, Z, K, M, N)
        # drift: the components' mean, times the wave groups' envelope at the hull (Newman 1974)
        beta = np.arctan2(sb, cb) % (2.0 * math.pi)
        tb = self._drift_table
        fa = self._wave_drift_a2
        mean = [float(fa @ np.interp(beta, self._drift_beta, tb[i])) for i in range(3)]
        g = self._wave_group
        envelope = (float(g @ np.cos(th0)) ** 2 + float(g @ np.sin(th0)) ** 2) / self._wave_group_norm
        self.wave_drift = (mean[0] * envelope, mean[1] * envelope, mean[2] * envelope)
        d = self.wave_drift
        return [X + d[0], Y + d[1], Z, K, M, N + d[2]]

    def mean_wave_drift(self, heading_rad: float | None = None) -> tuple[float, float, float]:
        """The mean drift (surge N, sway N, yaw N m; body axes) at `heading_rad` (default: now) at
        rest: sum over the components of 1/2 rho g a_i^2 R_i^2 times the waterline integral."""
        if self.waves is None:
            return (0.0, 0.0, 0.0)
        wf = self.waves
        psi = self.state[5] if heading_rad is None else heading_rad
        beta = (wf.to_rad - psi) % (2.0 * math.pi)
        return tuple(float(self._wave_drift_a2 @ np.interp(beta, self._drift_beta, self._drift_table[i]))
                     for i in range(3))  # type: ignore[return-value]

    def wave_elevation(self, t: Any, north: Any, east: Any) -> Any:
        """The sea's elevation (m, up) at time t and earth point (north, east); 0 without waves."""
        if self.waves is None:
            return 0.0 * np.asarray(t, dtype=float) if np.ndim(t) else 0.0
        return self.waves.elevation(t, north, east)

    def reset(self, pose: Sequence[float] = (0.0, 0.0, 0.0), t_s: float = 0.0) -> None:
        """At rest at (north, east, heading) with level attitude; actuators neutral; seeded streams restart."""
        self.t = float(t_s)
        self.state = [float(pose[0]), float(pose[1]), 0.0, 0.0, 0.0, float(pose[2])] + [0.0] * 6
        self.actuators = (0.0, 0.0, 0.0, 0.0, 0.0)
        self.step_mean = self.actuators  # actuators' mean over the last internal step
        self.cmd = (0.0, 0.0, 0.0, 0.0, 0.0)
        self._pending: list[tuple[float, tuple[float, ...]]] = []
        rng = np.random.default_rng(np.random.SeedSequence([self.env.seed, 6006]))
        self._rng = rng
        self._noise = iter(())
        self._gust = 0.0
        self._wander = 0.0
        ph = rng.uniform(0.0, 2.0 * math.pi, 2)
        self._current_phase = (float(ph[0]), float(ph[1]))
        self._nu_dot = [0.0] * 6
        self._update_forcing()

    def set_velocity(self, u: float, v: float, r: float) -> None:
        """Surge, sway and yaw rate (body axes) of a placed hull; as hull_b.CatamaranHull's, so a server or
        adapter places either hull alike."""
        self.state[6], self.state[7], self.state[11] = u, v, r

    # -- inputs --------------------------------------------------------------------------------
    def command(self, alpha1: float, alpha2: float, n1: float, n2: float, nt: float) -> None:
        """Set-points; non-finite values mean neutral; applied after the latency."""
        c = (alpha1, alpha2, n1, n2, nt)
        if not all(math.isfinite(v) for v in c):
            c = (0.0, 0.0, 0.0, 0.0, 0.0)
        p = self.p
        am, nm, nb = p.alpha_max_rad, p.n_max_rps, p.n_bow_max_rps
        c = (min(max(c[0], -am), am), min(max(c[1], -am), am), min(max(c[2], -nm), nm),
             min(max(c[3], -nm), nm), min(max(c[4], -nb), nb))
        if p.latency_s > 0.0:
            self._pending.append((self.t + p.latency_s, c))
        else:
            self.cmd = c

    # -- environment ---------------------------------------------------------------------------
    def _normal(self) -> float:
        try:
            return next(self._noise)
        except StopIteration:
            self._noise = iter(self._rng.standard_normal(4096).tolist())
            return next(self._noise)

    def _update_forcing(self) -> None:
        """Current (earth frame) and wind at the present time: held over one internal step."""
        e = self.env
        t = self.t
        if e.current_mps:
            w = 2.0 * math.pi / e.current_period_s
            s = e.current_mps * (1.0 + e.current_variation * math.sin(w * t + self._current_phase[0]))
            d = math.radians(e.current_to_deg + e.current_wander_deg * math.sin(w * t + self._current_phase[1]))
            self._vc = (s * math.cos(d), s * math.sin(d))
            # its rate of change (the sinusoids' derivative), for nu_c_dot
            ds = e.current_mps * e.current_variation * w * math.cos(w * t + self._current_phase[0])
            dd = math.radians(e.current_wander_deg) * w * math.cos(w * t + self._current_phase[1])
            self._vc_dot = (ds * math.cos(d) - s * math.sin(d) * dd, ds * math.sin(d) + s * math.cos(d) * dd)
        else:
            self._vc = (0.0, 0.0)
            self._vc_dot = (0.0, 0.0)
        if e.wind_mps:
            W = max(0.0, e.wind_mps + self._gust)
            b = math.radians(e.wind_from_deg + self._wander)
            self._vw = (-W * math.cos(b), -W * math.sin(b))  # the air moves TO from + 180 deg
        else:
            self._vw = (0.0, 0.0)
        if self.waves is not None:
            self._tau_wave = self._wave_loads()

    def _advance_gusts(self, h: float) -> None:
        e = self.env
        if not e.wind_mps:
            return
        if e.gust_fraction:
            a = math.exp(-h / e.gust_time_constant_s)
            self._gust = a * self._gust + math.sqrt(1 - a * a) * e.gust_fraction * e.wind_mps * self._normal()
        if e.wind_wander_deg:
            a = math.exp(-h / e.wander_time_constant_s)
            self._wander = a * self._wander + math.sqrt(1 - a * a) * e.wind_wander_deg * self._normal()

    @property
    def current_ne(self) -> tuple[float, float]:
        return self._vc

    @property
    def wind_now(self) -> tuple[float, float]:
        """(speed m/s, from deg) acting now, gusts included."""
        return math.hypot(*self._vw), (math.degrees(math.atan2(-self._vw[1], -self._vw[0])) % 360.0)

    # -- the equations -------------------------------------------------------------------------
    def forces(self, s: Sequence[float], act: Sequence[float]) -> tuple[list[float], list[float]]:
        """(tau, nu_c_dot): every force and moment on the body except inertia, and the body-frame
        rate of the current's velocity, at state s = eta + nu under the actuators `act`."""
        p = self.p
        _, _, z, phi, th, psi = s[0], s[1], s[2], s[3], s[4], s[5]
        u, v, w, pr, q, r = s[6], s[7], s[8], s[9], s[10], s[11]
        cph, sph, cth, sth, cps, sps = math.cos(phi), math.sin(phi), math.cos(th), math.sin(th), math.cos(psi), math.sin(psi)
        # R(Theta) (body -> NED), rows
        R = ((cps * cth, -sps * cph + cps * sth * sph, sps * sph + cps * cph * sth),
             (sps * cth, cps * cph + sph * sth * sps, -cps * sph + sth * sps * cph),
             (-sth, cth * sph, cth * cph))
        vcn, vce = self._vc
        # current in the body frame, R^T v_c
        uc = R[0][0] * vcn + R[1][0] * vce
        vc = R[0][1] * vcn + R[1][1] * vce
        wc = R[0][2] * vcn + R[1][2] * vce
        dvn, dve = self._vc_dot
        # d/dt (R^T v_c) = -omega x nu_c + R^T v_c_dot
        nu_c_dot = [-(q * wc - r * vc) + R[0][0] * dvn + R[1][0] * dve,
                    -(r * uc - pr * wc) + R[0][1] * dvn + R[1][1] * dve,
                    -(pr * vc - q * uc) + R[0][2] * dvn + R[1][2] * dve, 0.0, 0.0, 0.0]
        ur, vr, wr = u - uc, v - vc, w - wc
        m = p.mass_kg
        xg, yg, zg = p.r_g_m
        # C_RB(nu_r) nu_r, linear-velocity-independent form:
        #   [m w x v_r + m w x (w x r_g);  m r_g x (w x v_r) + w x (I_b w)]
        wxv = (q * wr - r * vr, r * ur - pr * wr, pr * vr - q * ur)
        wxg = (q * zg - r * yg, r * xg - pr * zg, pr * yg - q * xg)
        wxwxg = (q * wxg[2] - r * wxg[1], r * wxg[0] - pr * wxg[2], pr * wxg[1] - q * wxg[0])
        Ib = self._Ib
        Iw = (Ib[0][0] * pr + Ib[0][1] * q + Ib[0][2] * r, Ib[1][0] * pr + Ib[1][1] * q + Ib[1][2] * r,
              Ib[2][0] * pr + Ib[2][1] * q + Ib[2][2] * r)
        crb = (m * (wxv[0] + wxwxg[0]), m * (wxv[1] + wxwxg[1]), m * (wxv[2] + wxwxg[2]),
               m * (yg * wxv[2] - zg * wxv[1]) + (q * Iw[2] - r * Iw[1]),
               m * (zg * wxv[0] - xg * wxv[2]) + (r * Iw[0] - pr * Iw[2]),
               m * (xg * wxv[1] - yg * wxv[0]) + (pr * Iw[1] - q * Iw[0]))
        # the added mass and the damping see the water's own motion too: the waves' orbital velocity
        # over the hull, the wave surface's heave, roll and pitch rates, and the sway flow's turn
        # along the hull (all zero without waves)
        uw, vw, ww, pw, qw, rw = self._nu_wave
        ur, vr, wr = ur - uw, vr - vw, wr - ww
        pd, qd, rd = pr - pw, q - qw, r - rw
        # C_A(nu_r) nu_r (m2c of the diagonal M_A): [w x a; v x a + w x b], a = A_lin v_r, b = A_rot w
        A = self._A
        a = (A[0] * ur, A[1] * vr, A[2] * wr)
        b = (A[3] * pr, A[4] * q, A[5] * r)
        munk = p.munk_fraction
        ca = (q * a[2] - r * a[1], r * a[0] - pr * a[2], pr * a[1] - q * a[0],
              (vr * a[2] - wr * a[1]) + (q * b[2] - r * b[1]),
              (wr * a[0] - ur * a[2]) + (r * b[0] - pr * b[2]),
              munk * (ur * a[1] - vr * a[0]) + (pr * b[1] - q * b[0]))
        # resistance: friction (ITTC-57 with form factor) + residuary growing with the Froude number
        au = abs(ur)
        Re = max(au * p.length_m / NU_WATER, 1.0e4)
        cf = 0.075 / (math.log10(Re) - 2.0) ** 2
        fn = au / math.sqrt(GRAVITY * p.length_m)
        fn4 = fn ** 4
        cr = p.residuary_coefficient * fn4 / (fn4 + p.froude_hump ** 4)
        X = -p.surge_linear_kg_s * ur - self._k_res * (cf * (1.0 + p.form_factor) + cr) * au * ur
        # sway / yaw: hull lift (slender wing), cross-flow drag (strip theory), linear damping
        U = math.sqrt(ur * ur + vr * vr)
        Y_lift = -self._k_lift * U * vr
        Y = Y_lift - p.sway_linear_kg_s * vr
        N = p.lift_centre_m * Y_lift - p.yaw_linear_kgm2_s * rd
        ycf = ncf = 0.0
        for xs in self._strips:
            vl = vr + xs * rd
            f = vl * abs(vl)
            ycf += f
            ncf += xs * f
        Y -= self._k_cf * ycf
        N -= self._k_cf * ncf
        # heave, roll, pitch: hydrostatics (sines for larger angles) and damping
        if self.waves is None:
            Z = -self._k_heave * z - self._d_heave * wr
        else:
            # in waves the heave restoring and damping act along the vertical, as the wave's loads do
            # (relative to the surface's heave velocity; the rolled hull's body axis would lean them)
            zdot = -sth * u + cth * sph * v + cth * cph * w
            fz = -self._k_heave * z - self._d_heave * (zdot - ww)
            X -= sth * fz
            Y += cth * sph * fz
            Z = cth * cph * fz
            # the added mass's momentum A (nu - nu_w) turns with the hull: its rate in body axes has the
            # water's velocity seen from the turning hull, -A (omega x nu_w), besides A R^T a_w
            X -= A[0] * (q * ww - r * vw)
            Y -= A[1] * (r * uw - pr * ww)
            Z -= A[2] * (pr * vw - q * uw)
        K = -self._k_roll * sph * cth - self._d_roll * pd - p.roll_quadratic * abs(pd) * pd
        Mm = -self._k_pitch * sth - self._d_pitch * qd
        # azimuth thrusters: propeller thrust falling with the advance ratio, pod lift
        dband = p.dead_band_rps
        D = p.propeller_diameter_m
        for (lx, ly, lz), al, n in zip(self._units, act[:2], act[2:4]):
            ca_, sa_ = math.cos(al), math.sin(al)
            # the water's velocity at the unit (relative to the water), in body axes
            ux = ur - r * ly + q * lz
            uy = vr + r * lx - pr * lz
            va = (1.0 - p.wake_fraction) * (ux * ca_ + uy * sa_)  # inflow along the unit's axis
            T = 0.0
            if abs(n) >= dband:
                J = va / (abs(n) * D)
                if n > 0.0:
                    kt = max(0.0, 1.0 - J / p.j_zero_thrust)
                    T = self._k_thrust * kt * n * n
                else:
                    kt = max(0.0, 1.0 + J / p.j_zero_thrust)
                    T = -p.astern_ratio * self._k_thrust * kt * n * n
            # pod lift: the flow across the pod (the hull's motion and the slipstream, momentum theory)
            jet = math.copysign(math.sqrt(max(va * va + 2.0 * abs(T) / (RHO_WATER * self._disc), 0.0)) - abs(va), T)
            fa = -(ux * ca_ + uy * sa_) - 0.5 * jet  # water along the axis (towards -axis when ahead)
            fp = -(-ux * sa_ + uy * ca_)  # water across the axis
            # normal force of a low-aspect foil: C_L(a) = C_La sin(a) cos(a) (it stalls), pushing the
            # pod the way the cross-flow goes: 1/2 rho A C_La fp |fa|
            Lf = 0.5 * RHO_WATER * p.pod_area_m2 * p.pod_lift_slope * fp * abs(fa)
            Fx = T * ca_ - Lf * sa_
            Fy = T * sa_ + Lf * ca_
            X += Fx
            Y += Fy
            K += -lz * Fy
            Mm += lz * Fx
            N += lx * Fy - ly * Fx
        # bow tunnel thruster, fading with forward speed
        nt = act[4]
        if abs(nt) >= dband:
            bx, by, bz = p.bow_position_m
            Tt = p.bow_thrust_coefficient * nt * abs(nt) / (1.0 + (ur / p.bow_fade_speed_mps) ** 2)
            Y += Tt
            K += -bz * Tt
            N += bx * Tt
        # wind: quadratic drag of the apparent wind per body axis, own moment arms
        vwn, vwe = self._vw
        if vwn or vwe:
            e = self.env
            urw = u - (cps * vwn + sps * vwe)
            vrw = v - (-sps * vwn + cps * vwe)
            Xw = -self._k_wx * abs(urw) * urw
            Yw = -self._k_wy * abs(vrw) * vrw
            X += Xw
            Y += Yw
            N += e.wind_arm_x_m * Yw
            K += -e.wind_arm_z_m * Yw
        tw = self._tau_wave
        if tw is not None:  # waves: their loads for this step, held like the current and the wind
            X += tw[0]
            Y += tw[1]
            Z += tw[2]
            K += tw[3]
            Mm += tw[4]
            N += tw[5]
        tau = [X - crb[0] - ca[0], Y - crb[1] - ca[1], Z - crb[2] - ca[2],
               K - crb[3] - ca[3], Mm - crb[4] - ca[4], N - crb[5] - ca[5]]
        return tau, nu_c_dot

    def rhs(self, s: Sequence[float], act: Sequence[float]) -> list[float]:
        """d/dt [eta, nu]."""
        tau, ncd = self.forces(s, act)
        Mi = self._Minv_rows
        nu_dot = [Mi[i][0] * tau[0] + Mi[i][1] * tau[1] + Mi[i][2] * tau[2] + Mi[i][3] * tau[3]
                  + Mi[i][4] * tau[4] + Mi[i][5] * tau[5] + ncd[i] for i in range(6)]
        phi, th, psi = s[3], s[4], s[5]
        u, v, w, p, q, r = s[6], s[7], s[8], s[9], s[10], s[11]
        cph, sph, cth, sth, cps, sps = math.cos(phi), math.sin(phi), math.cos(th), math.sin(th), math.cos(psi), math.sin(psi)
        xd = cps * cth * u + (-sps * cph + cps * sth * sph) * v + (sps * sph + cps * cph * sth) * w
        yd = sps * cth * u + (cps * cph + sph * sth * sps) * v + (-cps * sph + sth * sps * cph) * w
        zd = -sth * u + cth * sph * v + cth * cph * w
        tth = sth / cth
        phd = p + sph * tth * q + cph * tth * r
        thd = cph * q - sph * r
        psd = sph / cth * q + cph / cth * r
        return [xd, yd, zd, phd, thd, psd] + nu_dot

    # -- stepping ------------------------------------------------------------------------------
    def _actuator_step(self, h: float) -> tuple[float, ...]:
        p = self.p
        a = self.actuators
        c = self.cmd
        da = p.alpha_rate_radps * h
        a1 = a[0] + min(max(c[0] - a[0], -da), da)
        a2 = a[1] + min(max(c[1] - a[1], -da), da)
        dn = p.motor_ramp_rps2 * h
        g = 1.0 - math.exp(-h / p.motor_time_constant_s)
        gb = 1.0 - math.exp(-h / p.bow_motor_time_constant_s)
        n1 = a[2] + min(max(g * (c[2] - a[2]), -dn), dn)
        n2 = a[3] + min(max(g * (c[3] - a[3]), -dn), dn)
        nt = a[4] + min(max(gb * (c[4] - a[4]), -dn), dn)
        return (a1, a2, n1, n2, nt)

    def step(self) -> None:
        """One internal step of `step_s`."""
        h = self.h
        while self._pending and self._pending[0][0] <= self.t + 1e-9:
            self.cmd = self._pending.pop(0)[1]
        a0 = self.actuators
        a1 = self._actuator_step(h)
        am = tuple(0.5 * (x + y) for x, y in zip(a0, a1))
        s = self.state
        k1 = self.rhs(s, am)
        k2 = self.rhs([s[i] + 0.5 * h * k1[i] for i in range(12)], am)
        k3 = self.rhs([s[i] + 0.5 * h * k2[i] for i in range(12)], am)
        k4 = self.rhs([s[i] + h * k3[i] for i in range(12)], am)
        self.state = [s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(12)]
        self.actuators = a1
        self.step_mean = am
        self.t += h
        self._advance_gusts(h)
        self._update_forcing()
        if not all(math.isfinite(v) for v in self.state):
            raise FloatingPointError(f"hull6dof diverged at t = {self.t:.3f} s")

    def advance(self, duration_s: float) -> tuple[float, ...]:
        """Step for `duration_s` (a whole number of internal steps); returns the actuators' mean over it."""
        n = max(1, int(round(duration_s / self.h)))
        acc = [0.0] * 5
        for _ in range(n):
            self.step()
            for i in range(5):
                acc[i] += self.step_mean[i]
        return tuple(v / n for v in acc)

    # -- outputs -------------------------------------------------------------------------------
    @property
    def eta(self) -> tuple[float, ...]:
        return tuple(self.state[:6])

    @property
    def nu(self) -> tuple[float, ...]:
        return tuple(self.state[6:])

    @property
    def x3(self) -> tuple[float, float, float, float, float, float]:
        """lotsen's planar state [N, E, psi (wrapped), u, v, r]."""
        s = self.state
        return (s[0], s[1], math.remainder(s[5], 2.0 * math.pi), s[6], s[7], s[11])

    def measure(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(velocity NED in m/s, specific force at the origin in body axes in m/s^2) now: what a GNSS
        receiver and an accelerometer see. Specific force = v_dot + omega x v - R^T [0, 0, g]."""
        d = self.rhs(self.state, self.actuators)
        s = self.state
        phi, th = s[3], s[4]
        u, v, w, p, q, r = s[6:12]
        g_b = (-math.sin(th) * GRAVITY, math.cos(th) * math.sin(phi) * GRAVITY, math.cos(th) * math.cos(phi) * GRAVITY)
        f = (d[6] + q * w - r * v - g_b[0], d[7] + r * u - p * w - g_b[1], d[8] + p * v - q * u - g_b[2])
        return (d[0], d[1], d[2]), f

    def kinetic_energy(self) -> float:
        """1/2 nu^T M nu (rigid body plus added mass)."""
        nu = np.array(self.state[6:])
        return 0.5 * float(nu @ self.M @ nu)


# ----------------------------------------------------------------------------------------------
# identification records

@dataclass(frozen=True)
class RecordOptions:
    duration_s: float = 600.0
    seed: int = 0
    command_rate_hz: float = 20.0
    input_rate_hz: float = 50.0
    gnss_rate_hz: float = 8.0
    position_noise_m: float = 0.01
    psi_noise_rad: float = 0.01
    r_noise_radps: float = 0.003
    gyro_offset_radps: float = 0.0
    start_heading_deg: float = 0.0
    current_mps: float = 0.0
    current_to_deg: float = 0.0
    current_variation: float = 0.0
    current_wander_deg: float = 0.0
    wind_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_fraction: float = 0.0
    wind_wander_deg: float = 0.0
    wave_hs_m: float = 0.0
    wave_tp_s: float = 1.0
    wave_from_deg: float = 0.0
    wave_spreading: float | None = 0.0
    wave_gamma: float = 3.3


def prbs_multisine(seed: int = 0, duration_s: float = 600.0) -> Callable[[float, Any], tuple[float, ...]]:
    """An input on all five channels: random levels held 0.6-2.4 s (PRBS-like) plus a small
    multisine, around 55 rev/s ahead: alpha +-25 deg (the two units differ a little), n1/n2 +-25,
    bow +-60 rev/s. Seeded; a function of time only."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4401]))
    n = int(duration_s / 0.6) + 2
    t_sw = np.concatenate([[0.0], np.cumsum(rng.uniform(0.6, 2.4, n))])
    alpha = rng.choice([-25.0, -12.0, 0.0, 12.0, 25.0], n + 1) + rng.uniform(-4, 4, n + 1)
    diff = rng.uniform(-6, 6, n + 1)
    base = 55.0 + rng.uniform(-25, 25, n + 1)
    dn = rng.uniform(-20, 20, n + 1)
    bow = rng.choice([-60.0, -30.0, 0.0, 30.0, 60.0], n + 1)
    levels = np.column_stack([np.radians(alpha + diff), np.radians(alpha - diff), base + dn, base - dn, bow])
    f = rng.uniform(0.1, 1.5, (5, 3))
    ph = rng.uniform(0, 2 * np.pi, (5, 3))
    amp = np.array([math.radians(2.0), math.radians(2.0), 4.0, 4.0, 5.0])

    def command(t: float, state: Any = None) -> tuple[float, ...]:
        k = int(np.searchsorted(t_sw, t, side="right")) - 1
        u = levels[min(k, len(levels) - 1)] + amp * np.sin(2 * np.pi * f * t + ph).sum(axis=1) / 3.0
        return tuple(float(v) for v in u)

    return command


def environment_of(opts: RecordOptions) -> HullEnvironment:
    return HullEnvironment(current_mps=opts.current_mps, current_to_deg=opts.current_to_deg,
                           current_variation=opts.current_variation, current_wander_deg=opts.current_wander_deg,
                           wind_mps=opts.wind_mps, wind_from_deg=opts.wind_from_deg,
                           gust_fraction=opts.gust_fraction, wind_wander_deg=opts.wind_wander_deg,
                           wave_hs_m=opts.wave_hs_m, wave_tp_s=opts.wave_tp_s, wave_from_deg=opts.wave_from_deg,
                           wave_spreading=opts.wave_spreading, wave_gamma=opts.wave_gamma, seed=opts.seed)


@dataclass
class HullRecord:
    record: Any  # lotsen.sysid.data.IdRecord
    truth_t: np.ndarray  # the true 3-DOF state at every fix (t, [N, E, psi, u, v, r])
    truth_x: np.ndarray
    params: HullParameters
    environment: HullEnvironment

    def save_csv(self, path: Any) -> None:
        from lotsen.sysid.data import save_csv

        save_csv(self.record, path)


def record(inputs: Any = None, options: RecordOptions = RecordOptions(), params: HullParameters = HullParameters(),
           **overrides: Any) -> HullRecord:
    """Run `inputs` on the hull and write what lotsen's lake records write (module docstring).

    `inputs`: a lotsen `Experiment` (its InputGenerator, command rate and start heading), a callable
    command(t, measured_state) -> (alpha1, alpha2, n1, n2, nt), or None for `prbs_multisine(seed)`.
    `overrides`: any RecordOptions field (duration_s=60, wind_mps=4, ...)."""
    from lotsen.sysid.data import IdRecord

    opts = replace(options, **overrides)
    rate = opts.command_rate_hz
    heading = math.radians(opts.start_heading_deg)
    if inputs is None:
        command = prbs_multisine(opts.seed, opts.duration_s)
    elif callable(inputs):
        command = inputs
    else:  # an Experiment
        from lotsen.sysid.experiment import InputGenerator

        gen = InputGenerator(inputs)
        command = gen.command
        rate = inputs.command_rate_hz
        heading = inputs.start_heading_rad
    env = environment_of(opts)
    hull = Hull6DOF(params, env, pose=(0.0, 0.0, heading))
    h = hull.h
    rng = np.random.default_rng(np.random.SeedSequence([opts.seed, 6007]))
    n_steps = int(round(opts.duration_s / h))
    in_every = int(round(1.0 / (opts.input_rate_hz * h)))
    cmd_every = int(round(1.0 / (rate * h)))
    fix_period = 1.0 / (opts.gnss_rate_hz * h)  # in steps (25 at 8 Hz, 200 Hz)
    rows: dict[int, list[float]] = {}
    acc = [0.0] * 5
    truth_t, truth_x = [], []
    next_fix = 0.0
    k_in = 0
    for k in range(n_steps + 1):
        t = k * h
        if k >= next_fix - 1e-9:
            next_fix += fix_period
            x = hull.x3
            y = [x[0] + opts.position_noise_m * rng.standard_normal(), x[1] + opts.position_noise_m * rng.standard_normal(),
                 math.remainder(x[2] + opts.psi_noise_rad * rng.standard_normal(), 2 * math.pi),
                 x[5] + opts.gyro_offset_radps + opts.r_noise_radps * rng.standard_normal()]
            rows.setdefault(k, [math.nan] * 9)[5:] = y
            truth_t.append(t)
            truth_x.append(x)
        if k == n_steps:
            break
        if k % cmd_every == 0:
            hull.command(*command(t, (math.nan, math.nan, hull.x3[2])))
        if k % in_every == 0:
            k_in = k
            acc = [0.0] * 5
        hull.step()
        for i in range(5):
            acc[i] += hull.step_mean[i]
        if (k + 1) % in_every == 0:
            rows.setdefault(k_in, [math.nan] * 9)[:5] = [v / in_every for v in acc]
    keys = sorted(rows)
    data = np.array([rows[k] for k in keys])
    rec = IdRecord(np.array(keys) * h, data[:, :5], data[:, 5:], source=f"hull6dof:seed {opts.seed}",
                   input_kind="mean")
    return HullRecord(rec, np.array(truth_t), np.array(truth_x), params, env)


# ----------------------------------------------------------------------------------------------
# manoeuvres (the property tests and the docs' figures)

def steady_speed(n_rps: float = 100.0, duration_s: float = 40.0, params: HullParameters = HullParameters()) -> float:
    """Forward speed after `duration_s` straight ahead with both propellers at `n_rps`."""
    hull = Hull6DOF(params, step_s=0.01)
    hull.command(0.0, 0.0, n_rps, n_rps, 0.0)
    hull.advance(duration_s)
    return hull.nu[0]


def turning_circle(n_rps: float = 50.0, alpha_deg: float = 20.0, duration_s: float = 60.0,
                   params: HullParameters = HullParameters(), environment: HullEnvironment = HullEnvironment()
                   ) -> dict[str, float]:
    """Both azimuths at `alpha_deg` and `n_rps` from rest: the steady turn's diameter (from the
    track's extent over the last full circle), speed and yaw rate."""
    hull = Hull6DOF(params, environment, step_s=0.01)
    a = math.radians(alpha_deg)
    hull.command(a, a, n_rps, n_rps, 0.0)
    hull.advance(duration_s - 20.0)
    pts = []
    for _ in range(200):
        hull.advance(0.1)
        pts.append(hull.x3)
    P = np.array(pts)
    u, r = hull.nu[0], hull.nu[5]
    U = math.hypot(hull.nu[0], hull.nu[1])
    return {"diameter_m": float(max(np.ptp(P[:, 0]), np.ptp(P[:, 1]))), "speed_mps": U, "u_mps": u,
            "yaw_rate_radps": r, "kinematic_diameter_m": 2.0 * U / abs(r) if r else math.inf}


def add_environment_arguments(ap: Any) -> None:
    """The water and air flags of this module's and hull_server.py's command lines."""
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--current", default="0,0", help="SPEED,TO_DEG")
    ap.add_argument("--current-variation", type=float, default=0.0, help="fraction of the speed, slow sinusoid")
    ap.add_argument("--wind", default="0,0", help="MEAN,FROM_DEG")
    ap.add_argument("--gusts", type=float, default=0.0, help="gust std as a fraction of the mean wind")
    ap.add_argument("--wander", type=float, default=0.0, help="wind direction wander std, deg")
    ap.add_argument("--waves", default=None, help="HS,TP,FROM_DEG: a JONSWAP sea (significant height m, peak period s)")
    ap.add_argument("--wave-spreading", type=float, default=0.0, help="s of the cos^2s spreading; 0: long-crested")
    ap.add_argument("--wave-gamma", type=float, default=3.3, help="JONSWAP peak enhancement (1: Pierson-Moskowitz)")


def environment_arguments(a: Any) -> dict[str, Any]:
    """The parsed flags of `add_environment_arguments` as HullEnvironment (and RecordOptions) fields."""
    cs, cd = (float(v) for v in a.current.split(","))
    ws, wd = (float(v) for v in a.wind.split(","))
    hs, tp, wfrom = (float(v) for v in a.waves.split(",")) if a.waves else (0.0, 1.0, 0.0)
    return dict(current_mps=cs, current_to_deg=cd, current_variation=a.current_variation, wind_mps=ws,
                wind_from_deg=wd, gust_fraction=a.gusts, wind_wander_deg=a.wander, wave_hs_m=hs, wave_tp_s=tp,
                wave_from_deg=wfrom, wave_spreading=a.wave_spreading, wave_gamma=a.wave_gamma, seed=a.seed)


def main(argv: Sequence[str] | None = None) -> int:
    """`python tests/physics/hull6dof.py --out REC.csv [--duration 600] [--seed 0] [--current 0.08,30]
    [--wind 4,250] [--gusts 0.2] [--wander 15] [--waves 0.03,0.8,250 [--wave-spreading 2]]`: a record for
    `lotsen identify REC.csv [--lake]`."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--out", required=True)
    ap.add_argument("--duration", type=float, default=600.0)
    add_environment_arguments(ap)
    a = ap.parse_args(argv)
    rec = record(duration_s=a.duration, **environment_arguments(a))
    rec.save_csv(a.out)
    print(f"{a.out}: {len(rec.record.t)} rows, {a.duration:g} s on the 6-DOF hull (seed {a.seed})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
