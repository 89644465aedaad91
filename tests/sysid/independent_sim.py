"""An independent data generator for identification tests (not lotsen's simulator).

The vessel equations are written here again, straight from docs/model.md, on
plain floats, and integrated with scipy's adaptive DOP853 (rtol 1e-9), so a test that identifies
these data checks lotsen's estimator against the model document, not lotsen's simulator against
itself.

Two recording styles:

* ``aligned``: the commands change only at the 8 Hz measurement instants and act directly (no
  actuator dynamics); one row per sample carries both inputs and outputs (the old format).
* ``async_rows``: the same experiment as ``async`` written in the old one-row-per-sample format
  (the achieved actuator values sampled at the measurement instants): it cannot say when an
  input changed between samples (issue 16 reproduces the bias with it).
* ``async`` (as the boat records it): commands at ``command_hz`` (10 Hz) drive first-order
  actuators (servo ``tau_servo_s``, motors ``tau_motor_s``); the achieved actuator values are
  recorded at ``input_hz`` (50 Hz) as the mean over each recording interval (what a tachometer's
  pulse count measures), stamped at the start of the interval so that "an input holds from its
  stamp until the next" reproduces their integral; measurements at 8 Hz with a phase offset to the
  commands. Rows carry either inputs or outputs, never both.

Noise: north/east 0.01 m, psi 0.01 rad, r 0.003 rad/s (white, Gaussian).

A lake (``Lake``, optional): current and wind in forms of this file's own, deliberately not lotsen's
(lotsen.model.environment): a current that varies slowly in time (a constant part plus a sinusoid
in each earth axis), the kinetics acting on the velocity relative to the water (Fossen's
relative-velocity form, with the current's own rate of change); wind as quadratic drag per body axis
of the apparent wind with its own moment arm (``wind_form="axis"``: tau = -[k_x u|u|, k_y v|v|,
l k_y v|v|]) or an Isherwood-like cos/sin form with a sin(2 gamma) moment (``"fossen"``), gusts on the
speed (Ornstein-Uhlenbeck) and a wandering direction, all seeded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

NAMES = ("m11", "m22", "m33", "X_u", "X_uu", "Y_v", "Y_r", "Y_uv", "Y_vv", "Y_rv", "N_v", "N_r", "N_vv", "N_rr",
         "kappa", "C_N", "mu_az", "mu_t")
DEFAULTS = dict(zip(NAMES, (14.0, 24.0, 1.8, 4.0, -5.0, 12.0, 1.0, -8.0, -40.0, -2.0, 0.5, 3.0, -1.0, -1.5,
                            0.02, 1.0, 0.0011, 0.0004)))
# vessel-model.md: azimuth 1 starboard (-0.39, +0.07), azimuth 2 port (-0.39, -0.07), bow at +0.37;
# rho = 1000 kg/m^3, A_r = 0.001 m^2
UNITS = ((-0.39, 0.07), (-0.39, -0.07))
L_XT = 0.37
HALF_RHO_AR = 0.5 * 1000.0 * 0.001
NOISE = {"north": 0.01, "east": 0.01, "psi": 0.01, "r": 0.003}


def perturbed(rng: np.random.Generator, spread: float = 0.15, keep: tuple[str, ...] = ("m11",)) -> dict:
    """Defaults with every parameter except `keep` multiplied by 1 +- `spread` (uniform)."""
    return {n: v if n in keep else v * float(rng.uniform(1 - spread, 1 + spread)) for n, v in DEFAULTS.items()}


@dataclass(frozen=True)
class Lake:
    """Current and wind of this file's own forms (module docstring). Directions: the current flows TO,
    the wind comes FROM, degrees clockwise from north."""

    current_mps: float = 0.0
    current_to_deg: float = 0.0
    current_variation_mps: float = 0.0  # amplitude of the slow variation in each earth axis
    current_period_s: float = 240.0
    wind_mps: float = 0.0
    wind_from_deg: float = 0.0
    gust_fraction: float = 0.25  # gust std / mean wind
    gust_time_constant_s: float = 5.0
    direction_std_deg: float = 15.0
    direction_time_constant_s: float = 30.0
    wind_form: str = "axis"  # "axis" | "fossen"
    k_x: float = 0.02  # 1/2 rho_air C_X A_F
    k_y: float = 0.09  # 1/2 rho_air C_Y A_L
    moment_arm_m: float = 0.08  # "axis": the lateral centre of pressure ahead of the origin
    k_n: float = 0.012  # "fossen": 1/2 rho_air C_N A_L L

    def series(self, duration_s: float, seed: int, dt: float = 0.05) -> "LakeSeries":
        """The environment on a grid, seeded: current (N, E) and its rate, wind velocity of the air (N, E)."""
        rng = np.random.default_rng([seed, 4711])
        t = np.arange(int(math.ceil(duration_s / dt)) + 2) * dt

        def ou(std: float, tc: float) -> np.ndarray:
            a = math.exp(-dt / tc)
            w = rng.standard_normal(len(t)) * std * math.sqrt(1 - a * a)
            out = np.empty(len(t))
            out[0] = std * rng.standard_normal()
            for k in range(1, len(t)):
                out[k] = a * out[k - 1] + w[k]
            return out

        speed = np.maximum(0.0, self.wind_mps * (1.0 + ou(self.gust_fraction, self.gust_time_constant_s)))
        frm = np.radians(self.wind_from_deg) + np.radians(ou(self.direction_std_deg, self.direction_time_constant_s))
        wind = np.column_stack([-speed * np.cos(frm), -speed * np.sin(frm)])  # the air moves away from `frm`
        a = math.radians(self.current_to_deg)
        ph = rng.uniform(0, 2 * math.pi, 2)
        om = 2 * math.pi / self.current_period_s
        cur = np.column_stack([self.current_mps * math.cos(a) + self.current_variation_mps * np.sin(om * t + ph[0]),
                               self.current_mps * math.sin(a) + self.current_variation_mps * np.sin(om * t + ph[1])])
        cur_rate = np.column_stack([self.current_variation_mps * om * np.cos(om * t + ph[0]),
                                    self.current_variation_mps * om * np.cos(om * t + ph[1])])
        return LakeSeries(self, t, cur, cur_rate, wind)


@dataclass
class LakeSeries:
    lake: Lake
    t: np.ndarray
    current: np.ndarray
    current_rate: np.ndarray
    wind: np.ndarray

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = min(int(t / (self.t[1] - self.t[0])), len(self.t) - 2)
        f = (t - self.t[k]) / (self.t[1] - self.t[0])

        def lerp(a: np.ndarray) -> np.ndarray:
            return a[k] * (1 - f) + a[k + 1] * f

        return lerp(self.current), lerp(self.current_rate), lerp(self.wind)

    def wind_force(self, psi: float, u: float, v: float, wind_ne: np.ndarray) -> tuple[float, float, float]:
        L = self.lake
        c, s = math.cos(psi), math.sin(psi)
        urw = u - (wind_ne[0] * c + wind_ne[1] * s)
        vrw = v - (-wind_ne[0] * s + wind_ne[1] * c)
        if L.wind_form == "axis":
            fy = -L.k_y * vrw * abs(vrw)
            return (-L.k_x * urw * abs(urw), fy, L.moment_arm_m * fy)
        V2 = urw * urw + vrw * vrw
        g = math.atan2(vrw, urw)  # the apparent wind's direction in the body frame
        return (-L.k_x * V2 * math.cos(g), -L.k_y * V2 * math.sin(g), -L.k_n * V2 * math.sin(2 * g))


def rhs(x: tuple, a: tuple, p: dict, env: "LakeSeries | None" = None, t: float = 0.0) -> tuple:
    """x_dot of vessel-model.md for state x = (N, E, psi, u, v, r) (u, v over ground), actuators
    a = (alpha1, alpha2, n1, n2, nt); with `env` the kinetics act on the velocity relative to the water
    and the wind force is added."""
    _, _, psi, ug, vg, r = x
    cp, sp = math.cos(psi), math.sin(psi)
    uc = vc = duc = dvc = 0.0
    wX = wY = wN = 0.0
    if env is not None:
        cur, rate, wind = env.at(t)
        uc, vc = cur[0] * cp + cur[1] * sp, -cur[0] * sp + cur[1] * cp
        duc, dvc = rate[0] * cp + rate[1] * sp, -rate[0] * sp + rate[1] * cp
        wX, wY, wN = env.wind_force(psi, ug, vg, wind)
    u, v = ug - uc, vg - vc
    tX = tY = tN = 0.0
    g = HALF_RHO_AR * p["C_N"]
    for (lx, ly), al, n in zip(UNITS, a[:2], a[2:4]):
        c, s = math.cos(al), math.sin(al)
        T = p["mu_az"] * n * abs(n)
        wx = -(u - r * ly) - p["kappa"] * n * c
        wy = -(v + r * lx) - p["kappa"] * n * s
        FN = g * math.hypot(wx, wy) * (-wx * s + wy * c)
        Fx = T * c - FN * s
        Fy = T * s + FN * c
        tX += Fx
        tY += Fy
        tN += lx * Fy - ly * Fx
    Ft = p["mu_t"] * a[4] * abs(a[4])
    tY += Ft
    tN += L_XT * Ft
    tX, tY, tN = tX + wX, tY + wY, tN + wN
    m11, m22, m33 = p["m11"], p["m22"], p["m33"]
    u_dot = (m22 * v * r - p["X_u"] * u + p["X_uu"] * abs(u) * u + tX) / m11
    v_dot = (-m11 * u * r - p["Y_v"] * v - p["Y_r"] * r + p["Y_uv"] * abs(u) * v + p["Y_vv"] * abs(v) * v
             + p["Y_rv"] * abs(r) * v + tY) / m22
    r_dot = ((m11 - m22) * u * v - p["N_v"] * v + p["N_vv"] * abs(v) * v - p["N_r"] * r + p["N_rr"] * abs(r) * r
             + tN) / m33
    # ground velocity in the body frame: nu = nu_r + R^T c, d(R^T c)/dt = r [v_c, -u_c] + R^T c_dot
    return (ug * cp - vg * sp, ug * sp + vg * cp, r, u_dot + r * vc + duc, v_dot - r * uc + dvc, r_dot)


def command_levels(duration_s: float, rng: np.random.Generator, bit_s: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A PRBS-like random schedule of set-points: (switch times, levels K x 5)."""
    n = int(math.ceil(duration_s / bit_s)) + 1
    t = np.arange(n) * bit_s
    # random bit lengths: not periodic
    t[1:] = np.cumsum(rng.uniform(0.5, 1.5, n - 1) * bit_s)
    alpha = np.radians(rng.choice([-30.0, -15.0, 0.0, 15.0, 30.0], n)) + np.radians(rng.uniform(-5, 5, n))
    diff = np.radians(rng.uniform(-8, 8, n))
    base = rng.uniform(35.0, 75.0, n)
    dn = rng.uniform(-25.0, 25.0, n)
    nt = rng.choice([-70.0, -40.0, 0.0, 40.0, 70.0], n)
    L = np.column_stack([alpha + diff, alpha - diff, base + dn, base - dn, nt])
    return t, L


@dataclass
class Generated:
    record: object  # lotsen.sysid.data.IdRecord
    params: dict
    t_meas: np.ndarray
    x_meas: np.ndarray  # true states at the measurement times
    style: str


def X_meas_a(Z: np.ndarray, T: np.ndarray, t: np.ndarray) -> np.ndarray:
    return Z[np.searchsorted(T, t)][:, 6:11]


def generate(duration_s: float = 120.0, params: dict | None = None, seed: int = 0, style: str = "async",
             command_hz: float = 10.0, input_hz: float = 50.0, meas_hz: float = 8.0, tau_servo_s: float = 0.06,
             tau_motor_s: float = 0.08, meas_offset_s: float = 0.037, bit_s: float = 2.0,
             noise: dict | None = None, x0: tuple = (0.0, 0.0, 0.3, 0.0, 0.0, 0.0),
             lake: Lake | None = None) -> Generated:
    """Simulate and record one experiment (see the module docstring); `lake`: in current and wind."""
    from lotsen.sysid.data import IdRecord

    p = dict(DEFAULTS if params is None else params)
    noise = dict(NOISE if noise is None else noise)
    rng = np.random.default_rng(seed)
    env = lake.series(duration_s, seed) if lake is not None else None
    t_sw, levels = command_levels(duration_s, rng, bit_s)
    # a small multisine on top of the levels, so that the commands change at every tick
    freqs = rng.uniform(0.2, 2.0, (5, 3))
    phases = rng.uniform(0, 2 * np.pi, (5, 3))
    amp = np.array([np.radians(2.0), np.radians(2.0), 3.0, 3.0, 4.0])

    def setpoint(t: float) -> np.ndarray:
        k = max(0, int(np.searchsorted(t_sw, t, side="right")) - 1)
        wob = amp * np.sin(2 * np.pi * freqs * t + phases).sum(axis=1) / 3.0
        sp = levels[k] + wob
        sp[:2] = np.clip(sp[:2], -math.radians(45), math.radians(45))
        sp[2:4] = np.clip(sp[2:4], -100, 100)
        sp[4] = np.clip(sp[4], -80, 80)
        return sp

    t_meas = meas_offset_s + np.arange(int(math.floor((duration_s - meas_offset_s) * meas_hz)) + 1) / meas_hz
    t_meas = t_meas[t_meas <= duration_s]
    if style == "aligned":
        t_meas = np.arange(int(math.floor(duration_s * meas_hz)) + 1) / meas_hz
        cmd_t = t_meas  # commands change only at the samples and act directly
        tau = None
    elif style in ("async", "async_rows"):
        cmd_t = np.arange(int(math.floor(duration_s * command_hz)) + 1) / command_hz
        tau = np.array([tau_servo_s, tau_servo_s, tau_motor_s, tau_motor_s, tau_motor_s])
    else:
        raise ValueError(style)
    t_in = np.arange(int(math.floor(duration_s * input_hz)) + 1) / input_hz if style != "aligned" else t_meas
    t_eval_all = np.union1d(t_meas, t_in)

    # augmented state: x (6), achieved actuators a (5), integral of a (5)
    z = np.concatenate([np.asarray(x0, float), np.zeros(5), np.zeros(5)])
    cmds = np.array([setpoint(t) for t in cmd_t])
    if tau is None:
        z[6:11] = cmds[0]
    out_t, out_z = [], []
    ends = np.append(cmd_t[1:], duration_s)
    for k in range(len(cmd_t)):
        ta, tb = cmd_t[k], min(ends[k], duration_s)
        if tb <= ta:
            continue
        c = cmds[k]
        if tau is None:
            z[6:11] = c

        def f(t, zz, c=c):  # type: ignore[no-untyped-def]
            a = zz[6:11]
            xd = rhs(tuple(zz[:6]), tuple(a), p, env, t)
            ad = (c - a) / tau if tau is not None else np.zeros(5)
            return np.concatenate([xd, ad, a])

        last = tb >= duration_s
        te = t_eval_all[(t_eval_all >= ta) & ((t_eval_all <= tb) if last else (t_eval_all < tb))]
        te = np.union1d(te, [tb])
        sol = solve_ivp(f, (ta, tb), z, method="DOP853", rtol=1e-9, atol=1e-10, t_eval=te)
        if not sol.success:
            raise RuntimeError(sol.message)
        keep = np.isin(sol.t, t_eval_all) & ((sol.t <= tb) if last else (sol.t < tb))
        out_t.append(sol.t[keep])
        out_z.append(sol.y.T[keep])
        z = sol.y[:, -1].copy()
    T = np.concatenate(out_t)
    Z = np.vstack(out_z)
    # the state exactly at duration_s (the last eval point may be the end itself)
    X_meas = Z[np.searchsorted(T, t_meas)][:, :6]
    Y = X_meas[:, [0, 1, 2, 5]].copy()
    Y[:, 0] += noise["north"] * rng.standard_normal(len(t_meas))
    Y[:, 1] += noise["east"] * rng.standard_normal(len(t_meas))
    Y[:, 2] += noise["psi"] * rng.standard_normal(len(t_meas))
    Y[:, 3] += noise["r"] * rng.standard_normal(len(t_meas))
    Y[:, 2] = np.remainder(Y[:, 2] + np.pi, 2 * np.pi) - np.pi
    if style == "aligned":
        U = cmds[: len(t_meas)]
        rec = IdRecord(t_meas, U, Y, source=f"independent:aligned:{seed}")
    elif style == "async_rows":
        # the old one-row-per-sample format: the achieved values sampled at the measurement instants
        rec = IdRecord(t_meas, X_meas_a(Z, T, t_meas), Y, source=f"independent:async_rows:{seed}")
    else:
        # interval means of the achieved values over [t_in[k], t_in[k+1]), stamped at t_in[k]
        I = Z[np.searchsorted(T, t_in)][:, 11:16]
        U = np.diff(I, axis=0) / np.diff(t_in)[:, None]
        t_u = t_in[:-1]
        t_all = np.union1d(t_u, t_meas)
        Ur = np.full((len(t_all), 5), np.nan)
        Yr = np.full((len(t_all), 4), np.nan)
        Ur[np.searchsorted(t_all, t_u)] = U
        Yr[np.searchsorted(t_all, t_meas)] = Y
        rec = IdRecord(t_all, Ur, Yr, source=f"independent:async:{seed}", input_kind="mean")
    return Generated(rec, p, t_meas, X_meas, style)
