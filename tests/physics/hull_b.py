"""Hull B: a second independent 6-DOF test plant (issue 47), a 1 m, 13 kg catamaran.

Why: tests/physics/hull6dof.py already checks lotsen against a hull that is not lotsen's grey box;
this one checks identification and control against a second hull of another form with other
thruster physics. It is written from the literature (sources below), imports nothing of lotsen and
shares no code with hull6dof.py (numpy only). Same conventions and public surface where the adapter
(tests/physics/hull_b_plant.py) and `record()` need them.

Frames and signs (lotsen's, docs/model.md): earth NED, body x forward, y starboard, z down; heading
psi from north, clockwise. Inputs (alpha1, alpha2, n1, n2, nt): azimuth angles in rad (alpha > 0 turns
a unit's thrust to starboard, which at the stern yaws the bow to PORT), propeller speeds in rev/s,
signed; unit 1 starboard, unit 2 port; nt > 0 pushes the bow to starboard (r > 0), as in hull6dof.

The craft (CatamaranParameters defaults)
----------------------------------------
Two slender demi-hulls, 0.96 m on the waterline (1.00 m overall), demi-hull waterline beam 0.13 m,
centre-to-centre spacing 0.32 m (beam overall 0.45 m), mass 13.0 kg. Waterline of a demi-hull: a
transom stern (breadth 0.85 b at the transom, full breadth at 0.25 L), parallel middle body, an
elliptic entrance over the forward 45 % of the length; section coefficient 0.75, so the draft follows
from the mass (0.078 m; `CatamaranHull.draft_m`; block coefficient 0.66). Centre of gravity 5 cm
above the waterline, longitudinally over the centre of flotation (so the hull floats level); radii
of gyration about it 0.19 m (roll), 0.26 m (pitch), 0.29 m (yaw). One azimuth pod under each demi-hull at x = -0.44 m,
y = +-0.16 m, 0.11 m below the waterline, propeller diameter 42 mm; a bow tunnel thruster (30 mm
tunnel) in a centreline nacelle under the forward cross-beam at x = +0.40 m, 0.05 m deep.
Numbers that follow: GM_T 0.37 m, roll stiffness rho g V GM_T 47 N m/rad (hull6dof: 4.5), roll
period ~0.85 s; heave stiffness 2170 N/m; mass + added mass (diagonal of M) 14.33 kg surge (the m11
for `lotsen identify --fix`), 31.5 kg sway, 23.4 kg heave, 2.56 kg m^2 yaw; steady speed 0.45 m/s at
25 rev/s, 1.0 m/s at 50 rev/s, 2.2 m/s at 100 rev/s (tests check the first two); a 4.5 m turning
circle at 50 rev/s and 20 deg (hull6dof: 2.1 m).

Equations (Fossen 2021, ch. 2-3, 6, 10), eta = [N, E, D, phi, theta, psi], nu = [u, v, w, p, q, r]:

    eta_dot = J(eta) nu                                                     (ZYX Euler angles)
    M_RB nu_dot + C_RB(nu) nu + M_A nu_r_dot + C_A'(nu_r) nu_r + D(nu_r) + g(eta) = tau
    nu_r = nu - nu_c,  nu_c = [R^T v_c; 0],  nu_c_dot = [-omega x R^T v_c; 0] (constant current)

(Fossen 2021 eq. 10.1 style: rigid body in absolute, hydrodynamics in relative velocity.)

- M_RB, C_RB: rigid body with the CG at r_g; C_RB in the form that depends on the angular velocity
  only, [[m S(w), -m S(w) S(r_g)], [m S(r_g) S(w), -S(I_b w)]] (Fossen 2021 sec. 3.3).
- M_A: strip theory (Faltinsen 1990 ch. 7 / Fossen 2021 sec. 6.4): on 24 strips per demi-hull the
  2-D high-frequency added masses a22 = rho pi T^2 / 2 (a plate of depth T with its free-surface
  image) acting at half draft and a33 = rho pi b(x)^2 / 8, plus surge A11 per demi-hull by Soeding's
  (1982) formula 2.7 rho V^(5/3) / L^2, each moved to the origin with the strip's position
  (M_A += H^T diag(a) H, H = [I, -S(p)]): a full symmetric 6x6 matrix with the catamaran's large
  roll added mass (a33 y^2) and the couplings A26, A35, A24 of an asymmetric (transom) hull. Demi-hull
  interaction in the added mass is neglected.
- C_A': Fossen's C_A(nu_r) of the full M_A, [[0, -S(M11 n1 + M12 n2)], [-S(..), -S(M21 n1 + M22 n2)]],
  except that the linear sway/yaw terms each demi-hull's captive-test derivatives already hold are
  taken out of those derivatives instead (next item), so nothing is counted twice.
- Sway / yaw damping per demi-hull (the catamaran as two slender hulls): Clarke, Gedling & Hine
  (1983) linear derivatives from the demi-hull's L, B, T, C_B (Fossen 2021 sec. 7.1, eq. 7.13-7.16),
      Y'v = -pi (T/L)^2 (1 + 0.40 C_B B/T),        Y'r = -pi (T/L)^2 (-1/2 + 2.2 B/L - 0.080 B/T)
      N'v = -pi (T/L)^2 (1/2 + 2.4 T/L),           N'r = -pi (T/L)^2 (1/4 + 0.039 B/T - 0.56 B/L)
  made dimensional with the demi-hull's speed u_h = u_r - y_h r (the two hulls see different speeds
  in a turn; Y_v, N_r with |u_h|, the couplings Y_r, N_v with u_h, so going astern swaps the hull's
  ends as slender-body theory has it), minus the linearised C_A terms of the demi-hull's own added mass
  (the Munk moment (A22 - A11) U v and A11 U r, A26 U r): the measured totals are Clarke's. The
  remaining 2x2 matrix is checked to be dissipative at set-up (its symmetric part positive).
  Plus cross-flow drag (Hoerner's 2-D C_D ~ 0.95 for b / 2T ~ 0.8) integrated along each demi-hull
  in closed form, int (v + x r)|v + x r| dx. No shielding of the lee demi-hull.
- Resistance per demi-hull (it sees u_h = u_r - y_h r, so the hull spacing damps yaw: N = -y_h X_h):
  friction by the Hughes (1954) line C_F = 0.066 / (log10 Re - 2.03)^2 with a catamaran form factor
  (1 + beta k) = 1.45 (Insel & Molland 1992: k of the demi-hull raised by the hulls' interference),
  plus a residuary coefficient C_R(Fn) interpolated in a table shaped like Molland, Wellicome &
  Couser's (1994) slender catamaran series (hump at Fn ~ 0.45-0.5; values assumed, not copied),
  wetted area 0.23 m^2 per demi-hull; a small linear term at creeping speed.
- Heave, roll, pitch: hydrostatics from 96 vertical wall-sided columns (two per strip and demi-hull)
  whose buoyancy rho g a_i max(0, T_e + depth change) acts along the earth vertical at the column's
  centre of buoyancy (Morrish's KB); the CG's weight likewise. Conservative by construction (the
  potential is `potential_energy()`), nonlinear, a demi-hull can lift out. Damping: a linear plus
  quadratic vertical force on every column (its own vertical velocity), which damps heave, roll and
  pitch by the columns' arms (heave damping ratio ~0.3 by default). Valid for heel and trim below
  ~15 deg (the columns stay vertical in the body frame).
- Azimuth pods: propeller thrust T = rho n|n| D^4 K_T(J), torque Q = rho n|n| D^5 K_Q(J), K_T and K_Q
  quadratic in J = V_a / (|n| D) (a B4-55-like P/D 0.9 open-water curve, coefficients assumed; the
  Wageningen polynomials' shape, Oosterveld & van Oossanen 1975), J clipped to [-0.5, 1.3], so a
  propeller overrun by the flow brakes (K_T < 0); astern (n < 0) the same curve in the reversed
  flow times 0.65; V_a = (1 - w) times the inflow along the unit's axis (wake fraction w = 0.08);
  the hull feels (1 - t) T (thrust deduction t = 0.06). Pod + strut side force: a low-aspect foil
  (area 15 cm^2, effective aspect ratio 1.6 with the hull bottom as a mirror, Helmbold's lift slope
  C_La = 2 pi A / (2 + sqrt(A^2 + 4))) in the hull's flow at the pod, normal-force coefficient
  C_La sin a cos a + 1.2 sin a |sin a| (Hoerner's low-aspect-ratio form: lift plus cross-flow), a in
  the pod's inflow angle, plus a small axial drag. No slipstream over the strut (hull6dof has one).
- Motors: a DC motor per propeller with back-EMF and a current limit, driven by an ESC in governor
  mode: V = clip(k_e w_cmd + K_p (w_cmd - w), +-V_bat), i = clip((V - k_e w) / R, +-i_max),
  J_m w_dot = k_t i - Q_prop - c_f w (electrical time constant neglected). So the speed droops a
  little under load, spins up at a current-limited rate that depends on the load, and a propeller's
  speed depends on the boat's speed through K_Q(J). (hull6dof: first-order lag plus ramp limit.)
- Servos: proportional position loop (time constant 0.05 s) with a slew-rate limit of 90 deg/s,
  set-points clipped to +-45 deg. Set-points reach the ESCs and servos after 30 ms.
- Bow tunnel thruster: T0 = rho n|n| D_t^4 K_Tt at rest; forward speed bends its jet away:
  T = T0 f(s), s = |u_r| / V_j, V_j = sqrt(|T0| / (rho A_t)) (momentum theory's jet speed), with
  f(s) = 1 - 2 d x^2 / (1 + x^4), x = s / s0 (d = 0.55, s0 = 0.3): the dip to 1 - d near
  s = s0 and partial recovery beyond that Chislett & Bjoerheden (1966) measured (shape, not their
  numbers). Its motor: the same DC model as the pods' (own numbers).
- Wind (Fossen 2021 sec. 10.1, coefficients of the form C_X = c_x cos, C_Y = c_y sin,
  C_N = c_n sin 2 of the apparent wind's direction): X = q A_F c_x cos g, Y = q A_L c_y sin g,
  N = q A_L L c_n sin 2g, K = -z_w Y, q = 1/2 rho_air V_rw^2, g the direction the apparent wind
  blows TO relative to the bow. Only when a wind is set (no air drag in still air). Gusts: the
  wind speed plus a sum of 40 sinusoids with random phases drawn from the Harris spectrum
  (Fossen 2021 sec. 10.1.3), scaled to std `gust_fraction` x mean; the direction wanders as another
  sum of sinusoids (first-order spectrum, corner 1 / `wander_time_constant_s`, std
  `wind_wander_deg`). Seeded: `seed`. (hull6dof: Ornstein-Uhlenbeck processes.)
- Current: constant in the earth frame (no slow variation, unlike hull6dof).
- Waves: NOT modelled. `CatamaranEnvironment` has wave_hs_m for the same call pattern, and only 0 is
  accepted (a ValueError otherwise).

Assumptions and what is left out: fresh water at 15 C (rho 1000, nu 1.14e-6); added mass constant
(the high-frequency strip values: no frequency dependence, no radiation memory); no interaction of
the demi-hulls in added mass or sway (no shielding of the lee hull, no tunnel flow between them);
resistance the same astern as ahead; the residuary table, the propeller curves, the motor numbers,
the pod foil and the wind coefficients are assumed values of the cited forms, not measurements;
the columns stay vertical in the body frame (small heel and trim); no propeller side force in
oblique flow other than the pod foil's, no ventilation, no thrust dead band (hull6dof has one),
no propeller-hull interaction besides w and t, constant battery voltage, the motor's inductance
neglected; no air drag in still air; the wind acts on the whole hull at one centre of effort.

Integration: Kutta's third-order Runge-Kutta at a fixed internal step of 5 ms (200 Hz) over the
17-state vector (12 rigid-body states, two servo angles, three motor speeds), commands held over a
step; deterministic. `step(u, dt)` sets u (if given) and advances dt (a whole number of steps).

How it differs from hull6dof: form (catamaran vs monohull: roll stiffness ~10x, turning circle ~2x, sway added mass and
yaw damping from two spaced hulls, full added-mass matrix vs diagonal), resistance (Hughes + table vs
ITTC-57 + Froude formula), sway/yaw (Clarke derivatives per demi-hull vs slender-wing lift + strip
cross-flow), hydrostatics (nonlinear columns vs linear stiffness), propellers (quadratic K_T and K_Q
with thrust deduction, torque loading the motor vs linear K_T), pods (Helmbold foil without
slipstream), motors (DC motor with back-EMF and current limit vs first-order lag), servos (P loop +
rate limit), bow thruster fade (dip and recovery with the jet-speed ratio vs 1 / (1 + (u/u0)^2)),
wind (angle coefficients vs per-axis drag), gusts (Harris sum of sinusoids vs OU), integrator (RK3
vs RK4), no waves.

`record(...)` writes an identification record like hull6dof's (lotsen.sysid.data.IdRecord format
only): achieved actuators at 50 Hz as interval means (`# inputs: mean`), GNSS N/E at 8 Hz with 1 cm
noise, psi (0.01 rad) and r (0.003 rad/s) on the fix rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Callable, Sequence

import numpy as np

RHO = 1000.0
RHO_AIR = 1.225
G = 9.81
NU = 1.14e-6  # fresh water at 15 C, m^2/s

# residuary resistance coefficient of a demi-hull in the catamaran (interference included), shaped
# like a slender catamaran series (Molland et al. 1994): values assumed for this 1 m model
_CR_FN = np.array([0.0, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35, 0.40, 0.45, 0.50, 0.60, 0.70, 0.80, 1.00, 2.00])
_CR_1000 = np.array([0.0, 0.3, 0.8, 1.5, 2.3, 3.1, 4.1, 5.4, 6.4, 6.3, 5.0, 3.9, 3.2, 2.4, 1.2])


@dataclass(frozen=True)
class CatamaranParameters:
    """The catamaran, its propulsion and its actuators. SI units, rad; propeller speeds in rev/s."""

    # form
    lwl_m: float = 0.96
    length_overall_m: float = 1.00
    demi_beam_m: float = 0.13
    hull_spacing_m: float = 0.32  # centre to centre
    mass_kg: float = 13.0
    section_coefficient: float = 0.75
    entrance_fraction: float = 0.45  # elliptic bow over this fraction of L
    transom_breadth_ratio: float = 0.85
    cg_height_m: float = 0.05  # above the waterline
    gyration_radii_m: tuple[float, float, float] = (0.19, 0.26, 0.29)
    strips: int = 24
    wetted_area_m2: float = 0.23  # per demi-hull
    form_factor: float = 1.45  # (1 + beta k)
    creep_damping_kg_s: float = 0.6  # per demi-hull
    crossflow_cd: float = 0.95
    heave_damping_ratio: float = 0.30
    vertical_quadratic: float = 60.0  # kg/m per m^2 of waterplane (quadratic vertical damping)
    # azimuth pods: unit 1 (starboard); unit 2 mirrored
    pod_position_m: tuple[float, float, float] = (-0.44, 0.16, 0.11)
    propeller_diameter_m: float = 0.042
    kt: tuple[float, float, float] = (0.36, -0.20, -0.12)  # K_T = kt0 + kt1 J + kt2 J^2
    kq: tuple[float, float, float] = (0.046, -0.018, -0.012)
    astern_factor: float = 0.65
    wake_fraction: float = 0.08
    thrust_deduction: float = 0.06
    pod_area_m2: float = 0.0015
    pod_aspect_ratio: float = 1.6
    pod_crossflow_cd: float = 1.2
    pod_axial_cd: float = 0.05
    # DC motors and ESCs (per propeller)
    battery_v: float = 12.0
    motor_kv_rps_per_v: float = 10.0  # no-load rev/s per volt: k_e = 1 / (2 pi Kv)
    motor_resistance_ohm: float = 0.25
    motor_current_max_a: float = 5.0
    rotor_inertia_kgm2: float = 4.0e-5  # rotor, coupling, shaft, propeller
    motor_friction_nms: float = 2.0e-6
    governor_gain_v_s: float = 0.02  # V per rad/s of speed error
    # bow tunnel thruster
    bow_position_m: tuple[float, float, float] = (0.40, 0.0, 0.05)
    tunnel_diameter_m: float = 0.030
    bow_kt: float = 0.40
    bow_kq: float = 0.05
    bow_fade_depth: float = 0.55
    bow_fade_ratio: float = 0.30
    bow_motor_kv_rps_per_v: float = 9.0
    bow_motor_resistance_ohm: float = 0.5
    bow_motor_current_max_a: float = 4.0
    bow_rotor_inertia_kgm2: float = 1.5e-5
    # servos and limits
    alpha_max_rad: float = math.radians(45.0)
    alpha_rate_radps: float = math.radians(90.0)
    servo_time_constant_s: float = 0.05
    n_max_rps: float = 100.0
    n_bow_max_rps: float = 80.0
    latency_s: float = 0.03


@dataclass(frozen=True)
class CatamaranEnvironment:
    """Water and air; directions in degrees clockwise from north: the current flows TO, the wind comes
    FROM. Gusts: Harris-spectrum sum of sinusoids of std `gust_fraction` x mean; direction wander std
    `wind_wander_deg`. Waves are not modelled: wave_hs_m must be 0."""

    current_mps: float = 0.0
    current_to_deg: float = 0.0
    wind_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_fraction: float = 0.0
    wind_wander_deg: float = 0.0
    wander_time_constant_s: float = 40.0
    frontal_area_m2: float = 0.050
    lateral_area_m2: float = 0.11
    cx: float = 0.60
    cy: float = 0.90
    cn: float = 0.08
    wind_height_m: float = 0.08  # centre of effort above the waterline
    wave_hs_m: float = 0.0
    seed: int = 0


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _cr(a: Any, b: Any) -> np.ndarray:
    """a x b of two 3-vectors (np.cross is slow on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rotation(phi: float, th: float, psi: float) -> np.ndarray:
    cf, sf, ct, st, cp, sp = math.cos(phi), math.sin(phi), math.cos(th), math.sin(th), math.cos(psi), math.sin(psi)
    return np.array([[cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st],
                     [sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf],
                     [-st, ct * sf, ct * cf]])


def _crossflow_integral(v: float, r: float, half: float) -> tuple[float, float]:
    """(int s|s| dx, int x s|s| dx) over x in [-half, half], s = v + x r, in closed form."""
    if abs(r) * half <= abs(v):  # s keeps its sign: s|s| = sign(v) s^2
        sg = 1.0 if v >= 0.0 else -1.0
        L = 2.0 * half
        return sg * (v * v * L + r * r * L ** 3 / 12.0), sg * (2.0 * v * r * L ** 3 / 12.0)
    s1, s0 = v + r * half, v - r * half

    def F(s: float) -> float:  # antiderivative of s|s| in s
        return s * s * abs(s) / 3.0

    def Fx(s: float) -> float:  # antiderivative of (s - v) s|s| in s
        return s ** 3 * abs(s) / 4.0 - v * s * s * abs(s) / 3.0

    return (F(s1) - F(s0)) / r, (Fx(s1) - Fx(s0)) / (r * r)


class _Motor:
    """Numbers of one DC motor + governor ESC."""

    def __init__(self, kv: float, R: float, i_max: float, J: float, friction: float, gain: float, v_bat: float) -> None:
        self.k = 1.0 / (2.0 * math.pi * kv)
        self.R, self.i_max, self.J, self.c, self.kp, self.v = R, i_max, J, friction, gain, v_bat

    def current(self, w_cmd: float, w: float) -> float:
        V = min(max(self.k * w_cmd + self.kp * (w_cmd - w), -self.v), self.v)
        return min(max((V - self.k * w) / self.R, -self.i_max), self.i_max)

    def accel(self, w_cmd: float, w: float, q_load: float) -> float:
        return (self.k * self.current(w_cmd, w) - q_load - self.c * w) / self.J


class _Gusts:
    """A seeded sum of sinusoids with a given one-sided spectrum shape, scaled to a std."""

    def __init__(self, rng: np.random.Generator, f_lo: float, f_hi: float, shape: Callable[[np.ndarray], np.ndarray],
                 std: float, n: int = 40) -> None:
        edges = np.geomspace(f_lo, f_hi, n + 1)
        f = edges[:-1] * (edges[1:] / edges[:-1]) ** rng.uniform(0.0, 1.0, n)
        a = np.sqrt(2.0 * shape(f) * np.diff(edges))
        tot = math.sqrt(0.5 * float(np.sum(a * a)))
        self.a = a * (std / tot if tot > 0 else 0.0)
        self.w = 2.0 * math.pi * f
        self.ph = rng.uniform(0.0, 2.0 * math.pi, n)

    def __call__(self, t: float) -> float:
        return float(np.sum(self.a * np.cos(self.w * t + self.ph)))


class CatamaranHull:
    """The catamaran in its water. `command(...)` then `advance(seconds)`, or `step(u, dt)`; `x3` is
    lotsen's planar state [N, E, psi, u, v, r]; `eta`, `nu` the 6-DOF ones; `actuators` the achieved
    (alpha1, alpha2, n1, n2, nt) with n in rev/s; `measure()` NED velocity and specific force."""

    def __init__(self, params: CatamaranParameters = CatamaranParameters(),
                 environment: CatamaranEnvironment = CatamaranEnvironment(), step_s: float = 0.005,
                 pose: Sequence[float] = (0.0, 0.0, 0.0)) -> None:
        if environment.wave_hs_m != 0.0:
            raise ValueError("hull_b models no waves: wave_hs_m must be 0")
        self.p, self.env, self.h = params, environment, float(step_s)
        self._setup()
        self.reset(pose)

    # -- set-up --------------------------------------------------------------------------------
    def _breadth(self, x: np.ndarray) -> np.ndarray:
        p = self.p
        L, b = p.lwl_m, p.demi_beam_m
        xs = 0.5 * L - p.entrance_fraction * L
        xf = -0.25 * L  # full breadth from here forward (aft of it a straight run to the transom)
        out = np.full_like(x, b)
        fwd = x > xs
        out[fwd] = b * np.sqrt(np.clip(1.0 - ((x[fwd] - xs) / (0.5 * L - xs)) ** 2, 0.0, 1.0))
        aft = x < xf
        out[aft] = b * (p.transom_breadth_ratio + (1.0 - p.transom_breadth_ratio) * (x[aft] + 0.5 * L) / (xf + 0.5 * L))
        return out

    def _setup(self) -> None:
        p = self.p
        m, L = p.mass_kg, p.lwl_m
        yh = 0.5 * p.hull_spacing_m
        self.yh = yh
        n = p.strips
        dx = L / n
        xs = -0.5 * L + (np.arange(n) + 0.5) * dx
        b = self._breadth(xs)
        awp_h = float(np.sum(b) * dx)
        self.waterplane_area_m2 = 2.0 * awp_h
        t_eff = m / (RHO * self.waterplane_area_m2)  # wall-sided effective depth of the columns
        T = t_eff / p.section_coefficient
        self.draft_m = T
        cwp = awp_h / (L * p.demi_beam_m)
        cb = cwp * p.section_coefficient
        self.block_coefficient = cb
        zb = T * (1.0 / 6.0 + cb / (3.0 * cwp))  # centre of buoyancy below the waterline (Morrish)
        x_f = float(np.sum(b * xs) / np.sum(b))  # centre of flotation = LCB of the columns
        self.r_g = np.array([x_f, 0.0, -p.cg_height_m])
        # columns: two per strip and demi-hull, at y_h +- b/4, each half the strip's waterplane
        cx, cy, ca = [], [], []
        for side in (1.0, -1.0):
            for q in (-0.25, 0.25):
                cx.append(xs)
                cy.append(side * yh + q * b)
                ca.append(0.5 * b * dx)
        self._cx, self._cy, self._ca = np.concatenate(cx), np.concatenate(cy), np.concatenate(ca)
        self._cz = zb
        self._t_eff = t_eff
        self._cpts = np.column_stack([self._cx, self._cy, np.full_like(self._cx, zb)])
        # rigid body
        kx, ky, kz = p.gyration_radii_m
        Ig = np.diag([m * kx * kx, m * ky * ky, m * kz * kz])
        Sg = _skew(self.r_g)
        self.I_b = Ig - m * Sg @ Sg
        MRB = np.zeros((6, 6))
        MRB[:3, :3] = m * np.eye(3)
        MRB[:3, 3:] = -m * Sg
        MRB[3:, :3] = m * Sg
        MRB[3:, 3:] = self.I_b
        self.M_RB = MRB
        # added mass by strips (module docstring)
        vol_h = m / RHO / 2.0
        a11_h = 2.7 * RHO * vol_h ** (5.0 / 3.0) / L ** 2
        a22 = RHO * math.pi * T * T / 2.0 * np.ones_like(xs)
        a33 = RHO * math.pi * b * b / 8.0
        MA = np.zeros((6, 6))
        own = np.zeros((6, 6))  # one demi-hull's, about its own midship (for the derivative split)

        def add(M: np.ndarray, pt: Sequence[float], diag: Sequence[float]) -> None:
            H = np.hstack([np.eye(3), -_skew(np.asarray(pt, dtype=float))])
            M += H.T @ np.diag(diag) @ H

        for side in (1.0, -1.0):
            for i, x in enumerate(xs):
                add(MA, (x, side * yh, 0.5 * T), (0.0, a22[i] * dx, 0.0))
                add(MA, (x, side * yh, 0.0), (0.0, 0.0, a33[i] * dx))
            add(MA, (0.0, side * yh, 0.5 * T), (a11_h, 0.0, 0.0))
        for i, x in enumerate(xs):
            add(own, (x, 0.0, 0.0), (0.0, a22[i] * dx, 0.0))
        own[0, 0] += a11_h
        self.M_A = MA
        self.M = MRB + MA
        self.Minv = np.linalg.inv(self.M)
        # hydrostatic numbers (for the docs and tests)
        nabla = m / RHO
        self.k_heave = RHO * G * self.waterplane_area_m2
        i_t = float(np.sum(self._ca * self._cy ** 2))
        self.gm_transverse_m = i_t / nabla - (zb - self.r_g[2])  # BM - BG (B below the waterline by zb)
        self.k_roll = RHO * G * nabla * self.gm_transverse_m
        # vertical damping per column
        c_lin = 2.0 * p.heave_damping_ratio * math.sqrt(self.k_heave * self.M[2, 2])
        self._c1 = c_lin * self._ca / np.sum(self._ca)
        self._c2 = p.vertical_quadratic * self._ca
        # Clarke's derivatives for a demi-hull, dimensional per unit forward speed, minus its own
        # added mass's linearised C_A terms
        B = p.demi_beam_m
        tl = (T / L) ** 2 * math.pi
        Yv = -tl * (1.0 + 0.40 * cb * B / T) * 0.5 * RHO * L ** 2
        Yr = -tl * (-0.5 + 2.2 * B / L - 0.080 * B / T) * 0.5 * RHO * L ** 3
        Nv = -tl * (0.5 + 2.4 * T / L) * 0.5 * RHO * L ** 3
        Nr = -tl * (0.25 + 0.039 * B / T - 0.56 * B / L) * 0.5 * RHO * L ** 4
        A11, A22, A26 = own[0, 0], own[1, 1], own[1, 5]
        # C_A at forward speed U: Y = -A11 U r, N = -(A22 - A11) U v - A26 U r
        D = -np.array([[Yv, Yr + A11], [Nv + (A22 - A11), Nr + A26]])  # damping per U: tau = -U D [v, r]
        sym = 0.5 * (D + D.T)
        if np.min(np.linalg.eigvalsh(sym)) <= 0.0:  # keep it dissipative: shrink the skew-free coupling
            off = 0.5 * (D[0, 1] + D[1, 0])
            lim = 0.95 * math.sqrt(D[0, 0] * D[1, 1])
            scale = lim / abs(off)
            D[0, 1] *= scale
            D[1, 0] *= scale
        self.clarke = {"Yv": Yv, "Yr": Yr, "Nv": Nv, "Nr": Nr}
        self._Dh = D
        self._k_res = 0.5 * RHO * p.wetted_area_m2
        self._k_cf = 0.5 * RHO * T * p.crossflow_cd
        # propulsion
        x, y, z = p.pod_position_m
        self._pods = (np.array([x, y, z]), np.array([x, -y, z]))
        A = p.pod_aspect_ratio
        self._pod_cla = 2.0 * math.pi * A / (2.0 + math.sqrt(A * A + 4.0))
        self._motor = _Motor(p.motor_kv_rps_per_v, p.motor_resistance_ohm, p.motor_current_max_a,
                             p.rotor_inertia_kgm2, p.motor_friction_nms, p.governor_gain_v_s, p.battery_v)
        self._bow_motor = _Motor(p.bow_motor_kv_rps_per_v, p.bow_motor_resistance_ohm, p.bow_motor_current_max_a,
                                 p.bow_rotor_inertia_kgm2, p.motor_friction_nms, p.governor_gain_v_s, p.battery_v)
        self._tunnel_area = math.pi * p.tunnel_diameter_m ** 2 / 4.0

    # equivalent first-order numbers of the motors (lotsen's guard and its models want them)
    @property
    def motor_time_constant_s(self) -> float:
        mo = self._motor
        return mo.J * mo.R / (mo.k * (mo.k + mo.kp))

    @property
    def motor_ramp_rps2(self) -> float:
        mo = self._motor
        return mo.k * mo.i_max / mo.J / (2.0 * math.pi)

    def reset(self, pose: Sequence[float] = (0.0, 0.0, 0.0), t_s: float = 0.0) -> None:
        """At rest, level, at (north, east, heading); actuators neutral; seeded streams restart."""
        self.t = float(t_s)
        self.x = np.zeros(17)
        self.x[0], self.x[1], self.x[5] = float(pose[0]), float(pose[1]), float(pose[2])
        self.cmd = (0.0,) * 5
        self._pending: list[tuple[float, tuple[float, ...]]] = []
        self.step_mean: tuple[float, ...] = (0.0,) * 5
        e = self.env
        rng = np.random.default_rng(np.random.SeedSequence([e.seed, 4747]))
        U = max(e.wind_mps, 0.1)
        Lh, kappa = 1800.0, 0.0026

        def harris(f: np.ndarray) -> np.ndarray:
            return 4.0 * kappa * Lh * U / (2.0 + (Lh * f / U) ** 2) ** (5.0 / 6.0)

        tc = e.wander_time_constant_s

        def first_order(f: np.ndarray) -> np.ndarray:
            return 1.0 / (1.0 + (2.0 * math.pi * f * tc) ** 2)

        self._gust = _Gusts(rng, 0.002, 0.5, harris, e.gust_fraction * e.wind_mps)
        self._wander = _Gusts(rng, 0.0005, 0.1, first_order, math.radians(e.wind_wander_deg))
        c = math.radians(e.current_to_deg)
        self._vc = np.array([e.current_mps * math.cos(c), e.current_mps * math.sin(c), 0.0])
        self._forcing()

    def set_velocity(self, u: float, v: float, r: float) -> None:
        self.x[6], self.x[7], self.x[11] = u, v, r

    # -- inputs --------------------------------------------------------------------------------
    def command(self, alpha1: float, alpha2: float, n1: float, n2: float, nt: float) -> None:
        c = (alpha1, alpha2, n1, n2, nt)
        if not all(math.isfinite(v) for v in c):
            c = (0.0,) * 5
        p = self.p
        am, nm, nb = p.alpha_max_rad, p.n_max_rps, p.n_bow_max_rps
        c = (min(max(c[0], -am), am), min(max(c[1], -am), am), min(max(c[2], -nm), nm),
             min(max(c[3], -nm), nm), min(max(c[4], -nb), nb))
        if p.latency_s > 0.0:
            self._pending.append((self.t + p.latency_s, c))
        else:
            self.cmd = c

    # -- environment ---------------------------------------------------------------------------
    def _forcing(self) -> None:
        e = self.env
        if e.wind_mps:
            W = max(0.0, e.wind_mps + self._gust(self.t))
            d = math.radians(e.wind_from_deg) + self._wander(self.t)
            self._vw = (-W * math.cos(d), -W * math.sin(d))
        else:
            self._vw = (0.0, 0.0)

    @property
    def wind_now(self) -> tuple[float, float]:
        return math.hypot(*self._vw), (math.degrees(math.atan2(-self._vw[1], -self._vw[0])) % 360.0)

    @property
    def current_ne(self) -> tuple[float, float]:
        return float(self._vc[0]), float(self._vc[1])

    # -- the equations -------------------------------------------------------------------------
    def _loads(self, s: np.ndarray, cmd: Sequence[float]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(tau, nu_c_dot, actuator state derivatives (5), R): all loads but inertia at state s."""
        p = self.p
        z, phi, th, psi = s[2], s[3], s[4], s[5]
        nu = s[6:12]
        R = _rotation(phi, th, psi)
        w_b = nu[3:]
        nuc1 = R.T @ self._vc
        nu_c_dot = np.zeros(6)
        nu_c_dot[:3] = -_cr(w_b, nuc1)
        nur = nu.copy()
        nur[:3] -= nuc1
        ur, vr, wr = nur[0], nur[1], nur[2]
        pr, q, r = nu[3], nu[4], nu[5]
        tau = np.zeros(6)
        # rigid body C_RB(nu) nu (angular-velocity form)
        m = p.mass_kg
        v1 = nu[:3]
        wxv = _cr(w_b, v1)
        tau[:3] -= m * wxv + m * _cr(w_b, _cr(w_b, self.r_g))
        tau[3:] -= m * _cr(self.r_g, wxv) + _cr(w_b, self.I_b @ w_b)
        # added mass C_A(nu_r) nu_r of the full M_A
        a = self.M_A[:3, :] @ nur
        bb = self.M_A[3:, :] @ nur
        tau[:3] -= _cr(nur[3:], a)
        tau[3:] -= _cr(nur[:3], a) + _cr(nur[3:], bb)
        # per demi-hull: resistance, Clarke sway/yaw, cross-flow
        L = p.lwl_m
        Dh = self._Dh
        vs = vr - 0.5 * self.draft_m * pr  # sway velocity at half draft, where the sway loads act
        for yh in (self.yh, -self.yh):
            uh = ur - yh * r
            au = abs(uh)
            Re = max(au * L / NU, 2.0e4)
            cf = 0.066 / (math.log10(Re) - 2.03) ** 2
            fn = au / math.sqrt(G * L)
            cr = 1e-3 * float(np.interp(fn, _CR_FN, _CR_1000))
            X = -self._k_res * (p.form_factor * cf + cr) * au * uh - p.creep_damping_kg_s * uh
            # diagonal terms go with |u|, the couplings with u (astern the hull's ends swap roles)
            Y = -(au * Dh[0, 0] * vs + uh * Dh[0, 1] * r)
            N = -(uh * Dh[1, 0] * vs + au * Dh[1, 1] * r)
            iy, ix = _crossflow_integral(vs, r, 0.5 * L)
            Y -= self._k_cf * iy
            N -= self._k_cf * ix
            tau[0] += X
            tau[1] += Y
            tau[5] += N - yh * X
            tau[3] += -0.5 * self.draft_m * Y  # sway loads act at half draft
        # hydrostatics: columns and weight (earth vertical)
        e3 = R[2, :]  # R^T [0, 0, 1] in body axes
        depth = z + self._cpts @ e3 - self._cz  # change of each column's immersion
        imm = np.maximum(self._t_eff + depth, 0.0)
        F = RHO * G * self._ca * imm  # upward
        # body-frame forces at the columns: -F e3; their moments sum(p_i x -F_i e3) = -(sum F_i p_i) x e3
        Ft = float(F.sum())
        Fp = F @ self._cpts
        tau[:3] += (m * G - Ft) * e3
        tau[3:] += -_cr(Fp, e3) + _cr(self.r_g, m * G * e3)
        # vertical damping per column (body z velocity of the column point)
        wc = nu[2] + pr * self._cy - q * self._cx
        fz = -(self._c1 * wc + self._c2 * wc * np.abs(wc))
        tau[2] += fz.sum()
        tau[3] += float(self._cy @ fz)
        tau[4] -= float(self._cx @ fz)
        # actuators: servos and motors (state), propeller loads
        act_dot = np.zeros(5)
        for i in (0, 1):
            al = s[12 + i]
            act_dot[i] = min(max((cmd[i] - al) / p.servo_time_constant_s, -p.alpha_rate_radps), p.alpha_rate_radps)
        D = p.propeller_diameter_m
        for i, pos in enumerate(self._pods):
            al = s[12 + i]
            w_m = s[14 + i]
            n = w_m / (2.0 * math.pi)
            e_ax = np.array([math.cos(al), math.sin(al), 0.0])
            e_pp = np.array([-math.sin(al), math.cos(al), 0.0])
            vloc = nur[:3] + _cr(nur[3:], pos)
            vax = float(vloc @ e_ax)
            vcr = float(vloc @ e_pp)
            va = (1.0 - p.wake_fraction) * vax
            T = Q = 0.0
            if n != 0.0:
                an = abs(n)
                if n > 0.0:
                    J = min(max(va / (an * D), -0.5), 1.3)
                    k = 1.0
                else:
                    J = min(max(-va / (an * D), -0.5), 1.3)
                    k = p.astern_factor
                kt = k * (p.kt[0] + p.kt[1] * J + p.kt[2] * J * J)
                kq = k * (p.kq[0] + p.kq[1] * J + p.kq[2] * J * J)
                T = RHO * n * an * D ** 4 * kt
                Q = RHO * n * an * D ** 5 * kq
            # pod foil in the hull's flow
            U2 = vax * vax + vcr * vcr
            f = (1.0 - p.thrust_deduction) * T * e_ax
            if U2 > 0.0:
                aoa = math.atan2(vcr, abs(vax))
                sa, co = math.sin(aoa), math.cos(aoa)
                cn = self._pod_cla * sa * co + p.pod_crossflow_cd * sa * abs(sa)
                qd = 0.5 * RHO * p.pod_area_m2 * U2
                f = f - qd * cn * e_pp - 0.5 * RHO * p.pod_area_m2 * p.pod_axial_cd * abs(vax) * vax * e_ax
            tau[:3] += f
            tau[3:] += _cr(pos, f)
            act_dot[2 + i] = self._motor.accel(2.0 * math.pi * cmd[2 + i], w_m, Q)
        # bow tunnel thruster
        w_b_m = s[16]
        nt = w_b_m / (2.0 * math.pi)
        Tt = RHO * nt * abs(nt) * p.tunnel_diameter_m ** 4 * p.bow_kt
        Qt = RHO * nt * abs(nt) * p.tunnel_diameter_m ** 5 * p.bow_kq
        if Tt != 0.0:
            vj = math.sqrt(abs(Tt) / (RHO * self._tunnel_area))
            y = min(abs(ur) / (vj * p.bow_fade_ratio), 1.0e6) ** 2  # x^2, bounded (tiny jets)
            Tt *= 1.0 - 2.0 * p.bow_fade_depth * y / (1.0 + y * y)
            bx, by, bz = p.bow_position_m
            tau[1] += Tt
            tau[3] += -bz * Tt
            tau[5] += bx * Tt
        act_dot[4] = self._bow_motor.accel(2.0 * math.pi * cmd[4], w_b_m, Qt)
        # wind
        vwn, vwe = self._vw
        if vwn or vwe:
            e = self.env
            air = R.T @ np.array([vwn, vwe, 0.0]) - nu[:3]  # the air relative to the hull, body axes
            V2 = air[0] ** 2 + air[1] ** 2
            g_ = math.atan2(air[1], air[0])
            qa = 0.5 * RHO_AIR * V2
            Yw = qa * e.lateral_area_m2 * e.cy * math.sin(g_)
            tau[0] += qa * e.frontal_area_m2 * e.cx * math.cos(g_)
            tau[1] += Yw
            tau[5] += qa * e.lateral_area_m2 * p.length_overall_m * e.cn * math.sin(2.0 * g_)
            tau[3] += e.wind_height_m * Yw
        return tau, nu_c_dot, act_dot, R

    def rhs(self, s: np.ndarray, cmd: Sequence[float]) -> np.ndarray:
        tau, ncd, act_dot, R = self._loads(s, cmd)
        nu_dot = self.Minv @ (tau + self.M_A @ ncd)
        phi, th = s[3], s[4]
        cf, sf, ct, tt = math.cos(phi), math.sin(phi), math.cos(th), math.tan(th)
        p_, q, r = s[9], s[10], s[11]
        d = np.empty(17)
        d[:3] = R @ s[6:9]
        d[3] = p_ + sf * tt * q + cf * tt * r
        d[4] = cf * q - sf * r
        d[5] = (sf * q + cf * r) / ct
        d[6:12] = nu_dot
        d[12:] = act_dot
        return d

    # -- stepping ------------------------------------------------------------------------------
    def _one(self) -> None:
        h = self.h
        while self._pending and self._pending[0][0] <= self.t + 1e-9:
            self.cmd = self._pending.pop(0)[1]
        s, c = self.x, self.cmd
        a0 = self.actuators
        k1 = self.rhs(s, c)
        k2 = self.rhs(s + 0.5 * h * k1, c)
        k3 = self.rhs(s + h * (2.0 * k2 - k1), c)
        self.x = s + h / 6.0 * (k1 + 4.0 * k2 + k3)
        self.t += h
        self.step_mean = tuple(0.5 * (u + w) for u, w in zip(a0, self.actuators))
        self._forcing()
        if not np.all(np.isfinite(self.x)):
            raise FloatingPointError(f"hull_b diverged at t = {self.t:.3f} s")

    def advance(self, duration_s: float) -> tuple[float, ...]:
        """Internal steps for `duration_s` (a whole number of them); returns the actuators' mean."""
        n = int(round(duration_s / self.h))
        if n < 1 or abs(n * self.h - duration_s) > 1e-9 * max(1.0, duration_s):
            raise ValueError(f"advance({duration_s!r}): not a whole number of {self.h} s steps")
        acc = np.zeros(5)
        for _ in range(n):
            self._one()
            acc += self.step_mean
        return tuple(float(v) for v in acc / n)

    def step(self, u: Sequence[float] | None = None, dt: float | None = None) -> tuple[float, ...]:
        """Set the command u (if given) and advance dt (default one internal step)."""
        if u is not None:
            self.command(*u)
        return self.advance(self.h if dt is None else dt)

    # -- outputs -------------------------------------------------------------------------------
    @property
    def eta(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.x[:6])

    @property
    def nu(self) -> tuple[float, ...]:
        return tuple(float(v) for v in self.x[6:12])

    @property
    def actuators(self) -> tuple[float, ...]:
        s = self.x
        return (float(s[12]), float(s[13]), float(s[14] / (2 * math.pi)), float(s[15] / (2 * math.pi)),
                float(s[16] / (2 * math.pi)))

    @property
    def x3(self) -> tuple[float, float, float, float, float, float]:
        s = self.x
        return (float(s[0]), float(s[1]), math.remainder(float(s[5]), 2 * math.pi), float(s[6]), float(s[7]),
                float(s[11]))

    def measure(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(NED velocity, specific force at the origin in body axes): v_dot + w x v - R^T g."""
        d = self.rhs(self.x, self.cmd)
        R = _rotation(self.x[3], self.x[4], self.x[5])
        v, w = self.x[6:9], self.x[9:12]
        f = d[6:9] + _cr(w, v) - G * R[2, :]
        return (float(d[0]), float(d[1]), float(d[2])), (float(f[0]), float(f[1]), float(f[2]))

    def kinetic_energy(self) -> float:
        nu = self.x[6:12]
        return 0.5 * float(nu @ self.M @ nu)

    def potential_energy(self) -> float:
        """Hydrostatic + gravity potential, zero at rest level."""
        def pot(s: np.ndarray) -> float:
            e3 = _rotation(s[3], s[4], s[5])[2, :]
            imm = np.maximum(self._t_eff + s[2] + self._cpts @ e3 - self._cz, 0.0)
            return float(0.5 * RHO * G * np.sum(self._ca * imm * imm)) - self.p.mass_kg * G * (s[2] + float(self.r_g @ e3))
        s0 = np.zeros(17)
        return pot(self.x) - pot(s0)


# ----------------------------------------------------------------------------------------------
# identification records (the format of hull6dof's / lotsen's lake records; own code)

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
    start_heading_deg: float = 0.0
    current_mps: float = 0.0
    current_to_deg: float = 0.0
    wind_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_fraction: float = 0.0
    wind_wander_deg: float = 0.0


def random_steps(seed: int = 0, duration_s: float = 600.0) -> Callable[[float, Any], tuple[float, ...]]:
    """Seeded excitation on all five channels: levels held 1-3 s, speeds 30-80 rev/s with a
    differential of up to +-15, common azimuth angle from {-30, -15, 0, 15, 30} deg (+-3 deg apart),
    bow thruster from {-50, 0, 50} rev/s half of the time."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 4748]))
    k = int(duration_s) + 2
    t_sw = np.concatenate([[0.0], np.cumsum(rng.uniform(1.0, 3.0, k))])
    al = np.radians(rng.choice([-30.0, -15.0, 0.0, 15.0, 30.0], k + 1))
    da = np.radians(rng.uniform(-3.0, 3.0, k + 1))
    n = rng.uniform(30.0, 80.0, k + 1)
    dn = rng.uniform(-15.0, 15.0, k + 1)
    bow = rng.choice([-50.0, 0.0, 50.0], k + 1) * (rng.uniform(0, 1, k + 1) < 0.5)
    levels = np.column_stack([al + da, al - da, n + dn, n - dn, bow])

    def command(t: float, state: Any = None) -> tuple[float, ...]:
        i = min(int(np.searchsorted(t_sw, t, side="right")) - 1, len(levels) - 1)
        return tuple(float(v) for v in levels[i])

    return command


@dataclass
class HullRecord:
    record: Any  # lotsen.sysid.data.IdRecord
    truth_t: np.ndarray
    truth_x: np.ndarray
    params: CatamaranParameters
    environment: CatamaranEnvironment

    def save_csv(self, path: Any) -> None:
        from lotsen.sysid.data import save_csv

        save_csv(self.record, path)


def environment_of(opts: RecordOptions) -> CatamaranEnvironment:
    return CatamaranEnvironment(current_mps=opts.current_mps, current_to_deg=opts.current_to_deg,
                                wind_mps=opts.wind_mps, wind_from_deg=opts.wind_from_deg,
                                gust_fraction=opts.gust_fraction, wind_wander_deg=opts.wind_wander_deg, seed=opts.seed)


def record(inputs: Any = None, options: RecordOptions = RecordOptions(),
           params: CatamaranParameters = CatamaranParameters(), **overrides: Any) -> HullRecord:
    """Run `inputs` (a callable command(t, state) -> 5 inputs, or None for `random_steps(seed)`) on
    the catamaran and write a lake-style identification record (module docstring)."""
    from lotsen.sysid.data import IdRecord

    opts = replace(options, **overrides)
    command = random_steps(opts.seed, opts.duration_s) if inputs is None else inputs
    hull = CatamaranHull(params, environment_of(opts), pose=(0.0, 0.0, math.radians(opts.start_heading_deg)))
    h = hull.h
    rng = np.random.default_rng(np.random.SeedSequence([opts.seed, 4749]))
    n_steps = int(round(opts.duration_s / h))
    in_every = int(round(1.0 / (opts.input_rate_hz * h)))
    cmd_every = int(round(1.0 / (opts.command_rate_hz * h)))
    fix_every = int(round(1.0 / (opts.gnss_rate_hz * h)))
    rows: dict[int, list[float]] = {}
    acc = np.zeros(5)
    truth_t, truth_x = [], []
    k_in = 0
    for k in range(n_steps + 1):
        t = k * h
        if k % fix_every == 0:
            x = hull.x3
            y = [x[0] + opts.position_noise_m * rng.standard_normal(),
                 x[1] + opts.position_noise_m * rng.standard_normal(),
                 math.remainder(x[2] + opts.psi_noise_rad * rng.standard_normal(), 2 * math.pi),
                 x[5] + opts.r_noise_radps * rng.standard_normal()]
            rows.setdefault(k, [math.nan] * 9)[5:] = y
            truth_t.append(t)
            truth_x.append(x)
        if k == n_steps:
            break
        if k % cmd_every == 0:
            hull.command(*command(t, (math.nan, math.nan, hull.x3[2])))
        if k % in_every == 0:
            k_in = k
            acc = np.zeros(5)
        hull.advance(h)
        acc += hull.step_mean
        if (k + 1) % in_every == 0:
            rows.setdefault(k_in, [math.nan] * 9)[:5] = list(acc / in_every)
    keys = sorted(rows)
    data = np.array([rows[k] for k in keys])
    rec = IdRecord(np.array(keys) * h, data[:, :5], data[:, 5:], source=f"hull_b:seed {opts.seed}", input_kind="mean")
    return HullRecord(rec, np.array(truth_t), np.array(truth_x), params, hull.env)


def steady_speed(n_rps: float = 50.0, duration_s: float = 40.0,
                 params: CatamaranParameters = CatamaranParameters()) -> float:
    """Forward speed after `duration_s` straight ahead with both propellers commanded to `n_rps`."""
    hull = CatamaranHull(params)
    hull.command(0.0, 0.0, n_rps, n_rps, 0.0)
    hull.advance(duration_s)
    return hull.nu[0]


def bollard_pull(n_rps: float, duration_s: float = 3.0,
                 params: CatamaranParameters = CatamaranParameters()) -> tuple[float, float]:
    """A bollard pull test as a lab runs it: the hull held at rest on a line to a load cell, both pods
    straight, both propellers commanded to `n_rps` (negative: astern). After `duration_s`: (the thrust the
    line holds, N, positive ahead; the propellers' speed a tachometer reads, rev/s)."""
    hull = CatamaranHull(params)
    hull.command(0.0, 0.0, n_rps, n_rps, 0.0)
    for _ in range(int(round(duration_s / hull.h))):
        hull.advance(hull.h)
        hull.x[:12] = 0.0  # the line and the dock hold it: at rest, level
    return float(hull._loads(hull.x, hull.cmd)[0][0]), hull.actuators[2]


def reverse_thrust_ratio(n_rps: float = 50.0, params: CatamaranParameters = CatamaranParameters()) -> float:
    """Astern over ahead bollard pull at equal measured propeller speed (what `lotsen identify
    --reverse-thrust-ratio` asks for): the motors turn faster astern, where the propeller loads them less,
    so each pull is taken per n^2 of the speed the tachometer read."""
    ahead, n_ahead = bollard_pull(n_rps, params=params)
    astern, n_astern = bollard_pull(-n_rps, params=params)
    return (-astern / n_astern ** 2) / (ahead / n_ahead ** 2)

def turning_circle(n_rps: float = 50.0, alpha_deg: float = 20.0, duration_s: float = 60.0,
                   params: CatamaranParameters = CatamaranParameters(),
                   environment: CatamaranEnvironment = CatamaranEnvironment()) -> dict[str, float]:
    """Both azimuths at `alpha_deg` and `n_rps` from rest: the steady turn's track extent over the
    last 20 s (a full circle at these speeds), speed, yaw rate and kinematic diameter 2 U / |r|."""
    hull = CatamaranHull(params, environment)
    a = math.radians(alpha_deg)
    hull.command(a, a, n_rps, n_rps, 0.0)
    hull.advance(duration_s - 20.0)
    pts = []
    for _ in range(200):
        hull.advance(0.1)
        pts.append(hull.x3[:2])
    P = np.array(pts)
    u, v, r = hull.nu[0], hull.nu[1], hull.nu[5]
    U = math.hypot(u, v)
    return {"diameter_m": float(max(np.ptp(P[:, 0]), np.ptp(P[:, 1]))), "speed_mps": U, "u_mps": u,
            "yaw_rate_radps": r, "kinematic_diameter_m": 2.0 * U / abs(r) if r else math.inf}


# hull6dof's names, so code written against hull6dof's surface can take this module instead
HullParameters = CatamaranParameters
HullEnvironment = CatamaranEnvironment
Hull6DOF = CatamaranHull


def main(argv: Sequence[str] | None = None) -> int:
    """`python tests/physics/hull_b.py --out REC.csv [--duration 600] [--seed 0] [--current 0.08,30]
    [--wind 4,250] [--gusts 0.2]`: a record for `lotsen identify REC.csv --fix m11=...`."""
    import argparse

    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--out", required=True)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--current", default="0,0")
    ap.add_argument("--wind", default="0,0")
    ap.add_argument("--gusts", type=float, default=0.0)
    a = ap.parse_args(argv)
    cs, cd = (float(v) for v in a.current.split(","))
    ws, wd = (float(v) for v in a.wind.split(","))
    rec = record(duration_s=a.duration, seed=a.seed, current_mps=cs, current_to_deg=cd, wind_mps=ws,
                 wind_from_deg=wd, gust_fraction=a.gusts)
    rec.save_csv(a.out)
    hull = CatamaranHull()
    print(f"{a.out}: {len(rec.record.t)} rows, {a.duration:g} s on hull B (seed {a.seed}); "
          f"m11 = mass + surge added mass = {hull.M[0, 0]:.2f} kg")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
