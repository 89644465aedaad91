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
    M nu_r_dot + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D(nu_r) nu_r + g(eta) = tau_thr + tau_wind
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
  speed and a wandering (Ornstein-Uhlenbeck) wind direction. All seeded.

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
    sinusoids (`current_variation` of the speed, `current_wander_deg`, period `current_period_s`)."""

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
    seed: int = 0


def _strip_positions(L: float, n: int) -> tuple[list[float], float]:
    dx = L / n
    return [-L / 2 + (i + 0.5) * dx for i in range(n)], dx


class Hull6DOF:
    """The hull in its water: `command(...)`, then `advance(seconds)`; `x3` is lotsen's 3-DOF state
    [N, E, psi, u, v, r]; `eta`, `nu` the 6-DOF ones; `actuators` the achieved (alpha1, alpha2, n1,
    n2, nt); `measure()` the NED velocity and what an accelerometer at the origin measures."""

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
        N = p.lift_centre_m * Y_lift - p.yaw_linear_kgm2_s * r
        ycf = ncf = 0.0
        for xs in self._strips:
            vl = vr + xs * r
            f = vl * abs(vl)
            ycf += f
            ncf += xs * f
        Y -= self._k_cf * ycf
        N -= self._k_cf * ncf
        # heave, roll, pitch: hydrostatics (sines for larger angles) and damping
        Z = -self._k_heave * z - self._d_heave * wr
        K = -self._k_roll * sph * cth - self._d_roll * pr - p.roll_quadratic * abs(pr) * pr
        Mm = -self._k_pitch * sth - self._d_pitch * q
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
                           gust_fraction=opts.gust_fraction, wind_wander_deg=opts.wind_wander_deg, seed=opts.seed)


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


def environment_arguments(a: Any) -> dict[str, Any]:
    """The parsed flags of `add_environment_arguments` as HullEnvironment (and RecordOptions) fields."""
    cs, cd = (float(v) for v in a.current.split(","))
    ws, wd = (float(v) for v in a.wind.split(","))
    return dict(current_mps=cs, current_to_deg=cd, current_variation=a.current_variation, wind_mps=ws,
                wind_from_deg=wd, gust_fraction=a.gusts, wind_wander_deg=a.wander, seed=a.seed)


def main(argv: Sequence[str] | None = None) -> int:
    """`python tests/physics/hull6dof.py --out REC.csv [--duration 600] [--seed 0] [--current 0.08,30]
    [--wind 4,250] [--gusts 0.2] [--wander 15]`: a record for `lotsen identify REC.csv [--lake]`."""
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
