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


def rhs(x: tuple, a: tuple, p: dict) -> tuple:
    """x_dot of vessel-model.md for state x = (N, E, psi, u, v, r), actuators a = (alpha1, alpha2, n1, n2, nt)."""
    _, _, psi, u, v, r = x
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
    m11, m22, m33 = p["m11"], p["m22"], p["m33"]
    u_dot = (m22 * v * r - p["X_u"] * u + p["X_uu"] * abs(u) * u + tX) / m11
    v_dot = (-m11 * u * r - p["Y_v"] * v - p["Y_r"] * r + p["Y_uv"] * abs(u) * v + p["Y_vv"] * abs(v) * v
             + p["Y_rv"] * abs(r) * v + tY) / m22
    r_dot = ((m11 - m22) * u * v - p["N_v"] * v + p["N_vv"] * abs(v) * v - p["N_r"] * r + p["N_rr"] * abs(r) * r
             + tN) / m33
    cp, sp = math.cos(psi), math.sin(psi)
    return (u * cp - v * sp, u * sp + v * cp, r, u_dot, v_dot, r_dot)


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
             noise: dict | None = None, x0: tuple = (0.0, 0.0, 0.3, 0.0, 0.0, 0.0)) -> Generated:
    """Simulate and record one experiment (see the module docstring)."""
    from lotsen.sysid.data import IdRecord

    p = dict(DEFAULTS if params is None else params)
    noise = dict(NOISE if noise is None else noise)
    rng = np.random.default_rng(seed)
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
            xd = rhs(tuple(zz[:6]), tuple(a), p)
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
