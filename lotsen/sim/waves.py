"""Wind waves on lotsen's simulated boat: a directional JONSWAP sea, the first-order (wave-frequency)
loads it puts on the hull in surge, sway and yaw, the heave, roll and pitch an IMU on the hull
feels, and the second-order mean drift.

The sea (`WaveField`): the spectrum of `lotsen.model.environment.Waves` (JONSWAP, DNV-RP-C205 sec.
3.5.5, Fossen 2021 sec. 10.2.1) discretised into `n_components` components of random frequency
within equal bins between 0.6 and 3 peak frequencies, each with its own direction drawn from the
cos-2s spreading function (one direction per frequency: the sea never repeats and costs one
component per frequency), amplitude a_i = sqrt(2 S(w_i) dw_i) and a random phase; deep water
(k = w^2 / g). Elevation at an earth-fixed point: zeta = sum a_i cos(w_i t - k_i (N cos b_i +
E sin b_i) + phi_i), b_i the direction the component travels TO. The loads are evaluated at the
boat's position at every step, so a boat under way meets the waves at the encounter frequency
w_e = w - k U cos(b - psi) without being told.

First-order loads in the horizontal plane: strip theory in the long-wave (G. I. Taylor) limit, where
the Froude-Krylov and diffraction forces on a section are its displaced plus added mass times the
fluid's acceleration (Faltinsen 1990, sec. 3.3-3.4; Newman 1977, sec. 4.17). The fluid's
acceleration along the travel direction at the section, averaged over the draft T, is
-w^2 a d(k) sin(theta), d(k) = (1 - e^{-kT}) / (kT); integrated over the waterline length L of a
prismatic hull (x from -L/2 to L/2, phase theta(x) = theta_0 - kappa x, kappa = k cos chi, chi the
travel direction relative to the bow):

    X = m11 sum -w^2 a d cos(chi) sinc(kappa L / 2) sin(theta_0)           (m11 = m + A11)
    Y = m22 sum -w^2 a d sin(chi) sinc(kappa L / 2) sin(theta_0)           (m22 = m + A22)
    N = (m22 / L) sum  w^2 a d sin(chi) cos(theta_0) G(kappa),   G(kappa) = int x sin(kappa x) dx

so a boat short against the wave moves with the water in surge and sway, and one long against it
averages the wave out (sinc) and turns in it (G). The water's orbital velocity, averaged the same way
(w a d(k) cos(theta_0) sinc(kappa L / 2) along the travel), is the velocity the hull moves through:
the plant adds it to the current, so the hull's damping, lift and Munk moment act on its velocity
through the water (Morison's form: inertia on the fluid's acceleration above, drag on the relative
velocity). Without it a hull carried by the orbit was damped against the water's own motion and felt
a mean Munk moment (m11 - m22) <u v> in oblique seas that no real hull feels.

Heave, roll and pitch (what the IMU and the GNSS antenna feel; they do not feed back into the
3-DOF plane): each a linear oscillator of the boat's natural period and damping driven towards
the wave surface it floats on, with the Smith factor e^{-kT/2} for the pressure's decay over the
draft: heave towards the elevation averaged over the waterplane, pitch towards the surface's
least-squares slope along the hull, roll towards the slope across it (the effective wave slope of
Froude's roll theory; Bhattacharyya 1978, ch. 8; a small boat in long waves aligns with the
surface normal). Roll has quadratic damping besides the linear (bilge keels, the hull's corners).

Mean drift: Faltinsen's short-wave asymptote for a wall-sided hull (1990, eq. 5.47), each component
pushing on the lit part of the waterline with (rho g / 2) a^2 (n . k)^2 per unit length against the
outward normal n, reduced for a finite draft by the energy that passes under the keel
(1 - e^{-2kT}) and for waves long against the beam, which a freely floating hull follows instead of
reflecting ((kB)^2 / (1 + (kB)^2)). The waterline is a box with a wedge bow of half-angle
`bow_half_angle_deg`. Slowly varying (difference-frequency) drift is not modelled.

Not modelled: radiation damping in the plane (the model's own damping acts on the velocity through
the water, which the wave's orbital velocity does not enter), the wave's orbital velocity in the
thrusters' inflow and the hull's damping, breaking waves, shallow water, coupling of heave, roll and
pitch back into the plane.

Everything here is pure: a `WaveField` is a function of time and position; `Seakeeping` advances
when stepped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from lotsen.model._jit import njit
from lotsen.model.environment import GRAVITY_MPS2, Waves

RHO_WATER = 1000.0

# rows of `WaveField.components` (one column per component)
_W, _K, _COS, _SIN, _AMP, _PHASE, _D_ACC, _D_P, _DRIFT = range(9)
# entries of the loads' output vector
LOADS = ("X_N", "Y_N", "N_Nm", "X_drift_N", "Y_drift_N", "N_drift_Nm", "heave_target_m", "pitch_target_rad",
         "roll_target_rad", "elevation_m", "orbital_north_mps", "orbital_east_mps")


@dataclass(frozen=True)
class HullForm:
    """What the waves see of the simulated hull: its waterline, draft and bow, and how it heaves,
    rolls and pitches (natural period, damping ratio), and how high the GNSS antenna sits above the
    roll and pitch centre. Defaults: the lake boat (0.99 m, 0.30 m wide, 13 kg)."""

    length_m: float = 0.99
    beam_m: float = 0.30
    draft_m: float = 0.08
    bow_half_angle_deg: float = 25.0
    heave_period_s: float = 0.55
    heave_damping_ratio: float = 0.35
    roll_period_s: float = 0.75
    roll_damping_ratio: float = 0.20  # bilge keels and the hull's corners
    roll_quadratic_damping: float = 1.0  # 1/rad: roll damping |p| p per unit inertia
    pitch_period_s: float = 0.55
    pitch_damping_ratio: float = 0.35
    gnss_antenna_height_m: float = 0.25  # above the roll/pitch centre (the waterline, amidships)

    def waterline(self) -> np.ndarray:
        """Segments of the waterline polygon (a box with a wedge bow), rows [n_x, n_y, length, x_mid,
        y_mid] in body axes, n the outward normal."""
        L, B = self.length_m, self.beam_m
        a = math.radians(self.bow_half_angle_deg)
        bow = min(0.5 * B / math.tan(a), 0.5 * L)
        x_sh = 0.5 * L - bow  # where the sides meet the bow's wedge
        side = x_sh + 0.5 * L
        face = math.hypot(bow, 0.5 * B)
        rows = [(-1.0, 0.0, B, -0.5 * L, 0.0),  # transom
                (0.0, 1.0, side, 0.5 * (x_sh - 0.5 * L), 0.5 * B),  # starboard side
                (0.0, -1.0, side, 0.5 * (x_sh - 0.5 * L), -0.5 * B),  # port side
                (math.sin(a), math.cos(a), face, x_sh + 0.5 * bow, 0.25 * B),  # bow, starboard face
                (math.sin(a), -math.cos(a), face, x_sh + 0.5 * bow, -0.25 * B)]  # bow, port face
        return np.array(rows, dtype=float)


def jonswap(omega: np.ndarray, hs_m: float, tp_s: float, gamma: float = 3.3) -> np.ndarray:
    """JONSWAP spectral density S(w) in m^2 s/rad (DNV-RP-C205 eq. 3.5.5), normalised so that its
    integral over 0.2-10 peak frequencies is Hs^2 / 16 (the zeroth moment of a sea of that Hs)."""
    wp = 2.0 * math.pi / tp_s

    def shape(w: np.ndarray) -> np.ndarray:
        w = np.asarray(w, dtype=float)
        sigma = np.where(w <= wp, 0.07, 0.09)
        peak = gamma ** np.exp(-((w - wp) ** 2) / (2.0 * sigma ** 2 * wp ** 2))
        return w ** -5.0 * np.exp(-1.25 * (wp / w) ** 4) * peak

    grid = np.linspace(0.2 * wp, 10.0 * wp, 20000)
    m0 = float(np.trapezoid(shape(grid), grid))
    return shape(omega) * (hs_m ** 2 / 16.0) / m0


def spreading_directions(rng: np.random.Generator, n: int, spreading: float) -> np.ndarray:
    """n angles (rad) about the mean direction drawn from the cos-2s spreading function
    D(theta) ~ cos^(2s)(theta / 2) (Longuet-Higgins et al. 1963); s = 0: all 0 (long-crested)."""
    if spreading <= 0.0:
        return np.zeros(n)
    grid = np.linspace(-math.pi, math.pi, 4001)
    pdf = np.cos(0.5 * grid) ** (2.0 * spreading)
    cdf = np.cumsum(pdf)
    cdf /= cdf[-1]
    return np.interp(rng.uniform(0.0, 1.0, n), cdf, grid)


class WaveField:
    """One realisation of a directional sea (`Waves`) for a hull (`HullForm`): elevation anywhere,
    loads on the hull at its pose (module docstring). Seeded by `rng`; `n_components` components."""

    def __init__(self, waves: Waves, hull: HullForm, rng: np.random.Generator, n_components: int = 64) -> None:
        self.waves, self.hull = waves, hull
        wp = waves.peak_frequency_radps
        edges = np.linspace(0.6 * wp, 3.0 * wp, n_components + 1)
        dw = np.diff(edges)
        w = edges[:-1] + rng.uniform(0.0, 1.0, n_components) * dw  # random within its bin: no repeat period
        amp = np.sqrt(2.0 * jonswap(w, waves.hs_m, waves.tp_s, waves.gamma) * dw)
        travel = math.radians(waves.from_deg) + math.pi + spreading_directions(rng, n_components, waves.spreading)
        phase = rng.uniform(0.0, 2.0 * math.pi, n_components)
        k = w * w / GRAVITY_MPS2
        kT = k * hull.draft_m
        kB = k * hull.beam_m
        c = np.empty((9, n_components))
        c[_W], c[_K], c[_COS], c[_SIN], c[_AMP], c[_PHASE] = w, k, np.cos(travel), np.sin(travel), amp, phase
        c[_D_ACC] = (1.0 - np.exp(-kT)) / kT  # the fluid's acceleration averaged over the draft
        c[_D_P] = np.exp(-0.5 * kT)  # Smith factor: the dynamic pressure at half the draft
        # mean drift per unit length of lit waterline (before (n . k)^2): Faltinsen's short-wave
        # asymptote, less what passes under the keel and what a floating hull follows instead of reflecting
        c[_DRIFT] = 0.5 * RHO_WATER * GRAVITY_MPS2 * amp ** 2 * (1.0 - np.exp(-2.0 * kT)) * kB ** 2 / (1.0 + kB ** 2)
        self.components = c
        self._hull = np.array([hull.length_m, hull.beam_m])
        self._waterline = hull.waterline()

    @property
    def significant_height_m(self) -> float:
        """Hs the discretised sea realises: 4 sqrt(m0), m0 = sum a_i^2 / 2."""
        return 4.0 * math.sqrt(0.5 * float(np.sum(self.components[_AMP] ** 2)))

    def elevation(self, t: float, north: float, east: float) -> float:
        """The surface elevation (m, up) at an earth-fixed point."""
        c = self.components
        theta = c[_W] * t - c[_K] * (north * c[_COS] + east * c[_SIN]) + c[_PHASE]
        return float(np.sum(c[_AMP] * np.cos(theta)))

    def loads(self, t: float, north: float, east: float, psi: float, m11: float, m22: float,
              out: np.ndarray | None = None) -> np.ndarray:
        """The wave loads on the hull at its pose (entries named by `LOADS`): first-order X, Y, N in
        body axes, mean drift X, Y, N, the heave (z down), pitch and roll the hull is driven towards,
        and the elevation at the origin. `m11`, `m22`: the hull's surge and sway mass with added mass."""
        out = np.empty(len(LOADS)) if out is None else out
        if out.shape != (len(LOADS),):  # the compiled kernel writes every entry: a shorter buffer is corrupted memory
            raise ValueError(f"WaveField.loads: `out` must have shape ({len(LOADS)},), got {out.shape}")
        _wave_loads(t, north, east, psi, m11, m22, self.components, self._hull, self._waterline, out)
        return out


def _sinc_py(z):  # type: ignore[no-untyped-def]
    return 1.0 - z * z / 6.0 if abs(z) < 1e-4 else math.sin(z) / z


_sinc = njit(_sinc_py)


def _first_moment_py(kappa, half_length):  # type: ignore[no-untyped-def]
    """G(kappa) = int_{-L/2}^{L/2} x sin(kappa x) dx (odd in kappa; kappa L^3 / 12 for long waves)."""
    z = kappa * half_length
    if abs(z) < 1e-3:
        return kappa * (2.0 * half_length) ** 3 / 12.0
    return 2.0 * (math.sin(z) / (kappa * kappa) - half_length * math.cos(z) / kappa)


_first_moment = njit(_first_moment_py)


def _wave_loads_py(t, north, east, psi, m11, m22, comp, hull, waterline, out):  # type: ignore[no-untyped-def]
    """The module docstring's sums over the components, in place on `out` (see `LOADS`)."""
    length, beam = hull[0], hull[1]
    half = 0.5 * length
    cp, sp = math.cos(psi), math.sin(psi)
    for j in range(12):
        out[j] = 0.0
    for i in range(comp.shape[1]):
        w, k, cb, sb, a = comp[0, i], comp[1, i], comp[2, i], comp[3, i], comp[4, i]
        d_acc, d_p, drift = comp[6, i], comp[7, i], comp[8, i]
        cchi = cb * cp + sb * sp  # travel direction relative to the bow
        schi = sb * cp - cb * sp
        theta = w * t - k * (north * cb + east * sb) + comp[5, i]
        s0, c0 = math.sin(theta), math.cos(theta)
        kappa = k * cchi
        along = _sinc(kappa * half)
        moment = _first_moment(kappa, half)
        acc = -w * w * a * d_acc  # fluid acceleration amplitude along the travel direction
        out[0] += m11 * acc * cchi * along * s0
        out[1] += m22 * acc * schi * along * s0
        out[2] -= m22 / length * acc * schi * c0 * moment
        out[6] -= a * c0 * along * _sinc(0.5 * k * schi * beam) * d_p  # z down: the hull rises with the crest
        out[7] += a * 12.0 / (length * length * length) * moment * s0 * d_p  # bow up where the surface rises ahead
        out[8] -= a * k * schi * s0 * along * d_p  # starboard up where the surface rises to starboard
        out[9] += a * c0
        orbit = w * a * d_acc * c0 * along  # the water's velocity along the travel, over the hull
        out[10] += orbit * cb
        out[11] += orbit * sb
        for j in range(waterline.shape[0]):
            nx, ny = waterline[j, 0], waterline[j, 1]
            lit = nx * cchi + ny * schi
            if lit < 0.0:  # the face meets the waves
                f = drift * lit * lit * waterline[j, 2]
                out[3] -= f * nx
                out[4] -= f * ny
                out[5] -= f * (waterline[j, 3] * ny - waterline[j, 4] * nx)


_wave_loads = njit(_wave_loads_py)


class BodyMotion(NamedTuple):
    """The motion out of the plane a 3-DOF plant does not carry, at one instant: attitude, heave,
    the body rates (what a gyro measures: on a rolling, pitching hull its z axis is not the heading's
    rate) and the specific force at the body origin in body axes (gravity included: (0, 0, -g) on a
    level boat at rest), what an accelerometer there measures."""

    roll_rad: float
    pitch_rad: float
    heave_m: float  # z down, from the calm waterline
    p_radps: float
    q_radps: float
    specific_force_mps2: tuple[float, float, float]
    r_radps: float = math.nan  # body z rate (NaN: that of a level boat, the planar r)


class Seakeeping:
    """Heave, roll and pitch of the hull as oscillators driven towards the wave surface (module
    docstring), stepped with the plant: semi-implicit Euler in two half-steps (w dt / 2 <= 0.06 at
    the 10 ms step: the frequency error is below 0.1 %)."""

    def __init__(self, hull: HullForm) -> None:
        self.hull = hull
        self._w = [2.0 * math.pi / p for p in (hull.heave_period_s, hull.pitch_period_s, hull.roll_period_s)]
        self._z = [hull.heave_damping_ratio, hull.pitch_damping_ratio, hull.roll_damping_ratio]
        self.position = [0.0, 0.0, 0.0]  # heave (m, down), pitch (rad, bow up), roll (rad, starboard down)
        self.rate = [0.0, 0.0, 0.0]
        self.acceleration = [0.0, 0.0, 0.0]

    def _accel(self, i: int, target: float, x: float, v: float) -> float:
        w, z = self._w[i], self._z[i]
        a = w * w * (target - x) - 2.0 * z * w * v
        if i == 2:
            a -= self.hull.roll_quadratic_damping * abs(v) * v
        return a

    def step(self, dt_s: float, targets: tuple[float, float, float]) -> None:
        """Advance by dt_s towards (heave, pitch, roll) targets held over the step."""
        h = 0.5 * dt_s
        for _ in range(2):
            for i in range(3):
                a = self._accel(i, targets[i], self.position[i], self.rate[i])
                self.rate[i] += h * a
                self.position[i] += h * self.rate[i]
        for i in range(3):
            self.acceleration[i] = self._accel(i, targets[i], self.position[i], self.rate[i])

    def motion(self, planar_accel_xy: tuple[float, float], yaw_rate_radps: float) -> BodyMotion:
        """The BodyMotion now, given the plane's body acceleration (u_dot - v r, v_dot + u r) and the
        heading's rate: the specific force adds gravity's share on the tilted axes (g sin(pitch) on x,
        -g cos(pitch) sin(roll) on y) and the heave acceleration on z; the body rates are the Euler
        rates turned into body axes (Fossen 2021, eq. 2.41 inverted: p = phi_dot - psi_dot sin(theta),
        q = theta_dot cos(phi) + psi_dot cos(theta) sin(phi), r = -theta_dot sin(phi) + psi_dot
        cos(theta) cos(phi))."""
        z, th, ph = self.position
        zd, thd, phd = self.rate
        g = GRAVITY_MPS2
        f = (planar_accel_xy[0] + g * math.sin(th), planar_accel_xy[1] - g * math.cos(th) * math.sin(ph),
             self.acceleration[0] - g * math.cos(th) * math.cos(ph))
        sp, cp, st, ct = math.sin(ph), math.cos(ph), math.sin(th), math.cos(th)
        psid = yaw_rate_radps
        return BodyMotion(ph, th, z, phd - psid * st, thd * cp + psid * ct * sp, f, -thd * sp + psid * ct * cp)
