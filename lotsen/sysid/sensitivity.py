"""Simulation of the grey-box model over identification windows, with forward sensitivities.

The model equations come from `lotsen.model.symbolic_rhs` (the very code the simulator runs,
re-bound to CasADi), integrated by classical RK4. Within a step the input is a line,
u(s) = u0 + du s (du = 0 for held commands; the reconstructed achieved values of lotsen.sysid.data
are linear within each row interval, and steps never cross a row), and RK4 evaluates it at its
stages s = 0, h/2, h: exact for the reconstruction, so the steps need not resolve the actuators'
motion (5-ms steps of the step-average input did that before, 4-12x the steps). One CasADi step
function propagates the state and its sensitivity

    S = d x / d [x0 (6), theta (NTHETA)],   S_{j+1} = dPhi/dx S_j + [0, dPhi/dtheta]

and the compiled chunk kernels of lotsen.sysid.kernels run it over all steps of all windows,
CHUNK steps per call (a reset flag at each window start loads the window's initial state and
S = [I, 0]); about 4 us per step with the 6 x 24 sensitivity, memory bounded by the chunk.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from lotsen.model import VesselParameters, symbolic_rhs
from lotsen.sysid.data import Segment, step_input_lines

NTHETA = len(VesselParameters.names())  # seed eq. (26)'s 18 and the optional model terms
NU = 5
NS = 6 + NTHETA  # sensitivity columns: initial state, then parameters
# The lake model (lotsen.sysid.multiple, `lake=True`): the state gets two entries per shooting interval,
# the gust factors g (along the mean wind) and h (across it; dg/dt = dh/dt = 0), and theta 7
# environment entries: the earth-frame current (c_N, c_E), the earth-frame velocity of the air
# w = (w_N, w_E) and the wind drag coefficients (k_X, k_Y, k_N, k_Nv) of
# lotsen.model.environment.apparent_wind_force. In the interval the air moves with g w + h (-w_E, w_N):
# gusts change the wind's speed (g) and turn it (h ~ the turn in radians; a 10 deg wander swings the
# cross-wind by 17 % of the speed, as much as the gusts change it).
ENV_NAMES = ("current_n", "current_e", "wind_n", "wind_e", "k_wind_x", "k_wind_y", "k_wind_n", "k_wind_nv")
NX_LAKE = 8
NTHETA_LAKE = NTHETA + len(ENV_NAMES)

_FUNCTION_CACHE: dict[tuple, tuple[Any, Any]] = {}


def _build_step_functions(geom: tuple[float, ...], jit: bool, lake: bool = False) -> tuple[Any, Any]:
    import casadi as ca

    from lotsen.model.environment import apparent_wind_force

    key = (geom, jit, lake)
    if key in _FUNCTION_CACHE:
        return _FUNCTION_CACHE[key]
    f = symbolic_rhs(ca)
    nx, nth = (NX_LAKE, NTHETA_LAKE) if lake else (6, NTHETA)
    x = ca.SX.sym("x", nx)
    u = ca.SX.sym("u", 2 * NU)  # the input's line over the step: u0 (5), du (5)
    th = ca.SX.sym("theta", nth)
    h = ca.SX.sym("h")
    rho = ca.SX.sym("reset")
    xr = ca.SX.sym("xr", nx)
    S = ca.SX.sym("S", nx, nx + nth)
    thl = ca.vertsplit(th)
    u0, du = u[:NU], u[NU:]

    def rhs(xx: Any, s: Any) -> Any:
        xl = ca.vertsplit(xx)
        ul = ca.vertsplit(u0 + s * du)
        if not lake:
            return ca.vertcat(*f(xl, ul, thl, geom))
        g, c = xl[6], xl[7]
        e = thl[NTHETA:]  # ENV_NAMES
        tau = apparent_wind_force(xl[2], xl[3], xl[4], g * e[2] - c * e[3], g * e[3] + c * e[2],
                                  e[4], e[5], e[6], e[7], ca.cos, ca.sin, ca.sqrt)
        return ca.vertcat(*f(xl[:6], ul, thl[:NTHETA], geom, (e[0], e[1]), tau), 0, 0)

    k1 = rhs(x, 0)
    k2 = rhs(x + h / 2 * k1, h / 2)
    k3 = rhs(x + h / 2 * k2, h / 2)
    k4 = rhs(x + h * k3, h)
    xn = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)  # classical RK4, the input's line at the stages
    phi = ca.Function("phi", [x, u, th, h], [xn, ca.jacobian(xn, x), ca.jacobian(xn, th)])
    xs = (1 - rho) * x + rho * xr  # window start: load the initial state
    xn_s, Jx_s, Jt_s = phi(xs, u, th, h)
    S0 = ca.horzcat(ca.SX.eye(nx), ca.SX.zeros(nx, nth))
    Ss = (1 - rho) * S + rho * S0
    Sn = ca.mtimes(Jx_s, Ss) + ca.horzcat(ca.SX.zeros(nx, nx), Jt_s)
    xn = xn_s
    opts: dict[str, Any] = {}
    if jit:
        # compile in the temp directory, not the caller's working directory
        opts = dict(jit=True, compiler="shell", jit_options=dict(flags=["-O1"], verbose=False,
                                                                 directory=tempfile.gettempdir() + os.sep))
    step_sens = ca.Function("step_sens", [x, S, u, th, h, rho, xr], [xn, Sn], opts)
    step = ca.Function("step", [x, u, th, h, rho, xr], [xn], opts)
    _FUNCTION_CACHE[key] = (step, step_sens)
    return step, step_sens


def jit_available() -> bool:
    return shutil.which("gcc") is not None or shutil.which("cc") is not None


@dataclass
class StepGrid:
    """All integration steps of a list of windows, flattened.

    Step j integrates over h[j] with the input line U[:, j] (u0, du; lotsen.sysid.data.step_input_lines);
    `reset[j]` = 1 marks a window's first
    (zero-length) step, which loads that window's initial state. `sample_step[i]` is the step after
    which sample i (global numbering over windows) is reached; `window_of_sample[i]` its window.
    """

    h: np.ndarray
    U: np.ndarray
    reset: np.ndarray
    window_start_step: np.ndarray
    sample_step: np.ndarray
    window_of_sample: np.ndarray
    n_windows: int


def make_grid(windows: Sequence[Segment], h_max: float) -> StepGrid:
    """The steps of all windows (vectorised: prediction scores overlapping windows over whole records)."""
    hs, us, resets, wstart, sstep, wos = [], [], [], [], [], []
    offset = 0
    for w, seg in enumerate(windows):
        n = len(seg.t)
        dt = np.diff(seg.t)
        m = np.maximum(1, np.ceil(dt / h_max - 1e-9).astype(int)) if n > 1 else np.zeros(0, int)
        # step 0: the window's zero-length reset step; then m[k] steps inside row interval k
        row = np.repeat(np.arange(n - 1), m)
        first = np.concatenate([[0], np.cumsum(m)[:-1]]) if n > 1 else np.zeros(0, int)
        sub = np.arange(len(row)) - first[row] if len(row) else np.zeros(0, int)
        h_in = dt[row] / m[row] if len(row) else np.zeros(0)
        hs.append(np.concatenate([[0.0], h_in]))
        u0 = step_input_lines(seg, 0, 0.0)[None, :]
        lines = step_input_lines(seg, row, sub / np.maximum(m[row], 1)) if len(row) else np.zeros((0, 10))
        us.append(np.vstack([u0, np.atleast_2d(lines)]))
        resets.append(np.concatenate([[1.0], np.zeros(len(row))]))
        wstart.append(offset)
        # sample k is reached after the last step of row interval k - 1 (sample 0: the reset step)
        sstep.append(offset + np.concatenate([[0], np.cumsum(m)]) if n > 1 else np.array([offset]))
        wos.append(np.full(n, w))
        offset += 1 + len(row)
    # U as a C-ordered lines x steps, each window's block transposed alone (one transposing copy of the
    # whole took 0.03 s on a 10-min record's prediction windows)
    U = np.concatenate([u.T for u in us], axis=1, out=np.empty((2 * NU, offset)))
    return StepGrid(np.concatenate(hs), U, np.concatenate(resets), np.array(wstart), np.concatenate(sstep),
                    np.concatenate(wos), len(windows))