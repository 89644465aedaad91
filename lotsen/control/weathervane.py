"""Weathervaning: the hold heading that needs the least thrust against the estimated current and wind.

Field notes: a beam current of 0.4 m/s needs ~11 N of sway force, while the bow thruster and
the aft azimuths (|alpha| <= 45 deg) give only ~4.6 N of pure sway; bow-on the same current needs 2.4 N
of surge (capacity 22 N). So in HOLD the heading is a preference, and the vessel points into the load.

Steady state at the target (ground velocity zero, r = 0): the hull sees the relative velocity
nu_r = -nu_c, nu_c = R(psi)^T v_c (Fossen 2021, sec. 10.3), and seed eq. (22) with the time
derivatives set to zero gives the thrust the actuators must deliver:

    u_r = -(c_N cos psi + c_E sin psi),  v_r = -(-c_N sin psi + c_E cos psi)
    tau_X = X_u u_r - X_|u|u |u_r| u_r
    tau_Y = Y_v v_r - Y_|u|v |u_r| v_r - Y_|v|v |v_r| v_r
    tau_N = -(m11 - m22) u_r v_r + N_v v_r - N_|v|v |v_r| v_r          (Munk moment + sway-yaw coupling)

minus the wind force (`lotsen.model.environment.wind_force`, at zero ground speed) and minus any further
external force (the EKF's body-frame `disturbance_tau`, or an earth-frame force such as the station
keeper's integral). The cost of a heading is the thrust normalised by what the actuators can give
per axis (the allocation's per-axis capacity, so a sway newton costs ~5x a surge newton):

    J(psi) = (tau_X / F_X)^2 + (tau_Y / F_Y)^2 + (tau_N / M_N)^2
             + w_pref (1 - cos(psi - psi_pref)) + w_bow (1 - cos(psi - psi_upstream)) J_0

The first preference keeps the operator's heading when the load does not care; the second breaks the
bow/stern symmetry of the drag in favour of bow-into-the-load. Headings are searched on a grid within
`max_offset_rad` of the preferred heading (the operator's limit). Hysteresis: the previous choice is
kept unless the best heading saves more than max(`hysteresis` J_prev, `hysteresis_abs`) and is at least
`min_change_rad` away (near the optimum J is ~0, so a relative margin alone would let a noisy current
estimate make the hull hunt); a load between `release_load_N` and `min_load_N` keeps the choice too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lotsen.errors import ConfigError
from lotsen.model.angles import wrap_angle
from lotsen.model.environment import Environment, wind_force
from lotsen.model.dynamics import surge_drag
from lotsen.model.parameters import VesselParameters


@dataclass(frozen=True)
class WeathervaneConfig:
    capacity_X_N: float = 22.0  # pure surge the allocation can give (both azimuths ahead)
    capacity_Y_N: float = 4.6  # pure sway (bow thruster + azimuths balancing the yaw moment)
    capacity_N_Nm: float = 3.0  # pure yaw moment, order of magnitude
    max_offset_rad: float = math.pi  # allowed |psi - psi_pref| (pi: any heading)
    grid_step_rad: float = math.radians(2.0)
    preference_weight: float = 1e-3  # w_pref: absolute cost, acts when the load is negligible
    bow_into_load_weight: float = 0.05  # w_bow: relative to the load's cost J_0
    hysteresis: float = 0.15  # relative cost margin before the chosen heading changes ...
    hysteresis_abs: float = 0.01  # ... and absolute one (normalised: ~0.46 N sway or 2.2 N surge)
    min_change_rad: float = math.radians(10.0)
    min_load_N: float = 0.3  # below this steady thrust (N) the heading is not re-chosen ...
    release_load_N: float = 0.1  # ... and below this one it goes back to the preferred heading
    # automatic mode (StationKeepingConfig.weathervane = "auto"): vane only when the preferred heading's
    # steady load needs more than `engage_load_ratio` of the capacity on some axis, back to the preferred
    # heading below `release_load_ratio` (hysteresis)
    engage_load_ratio: float = 0.7
    release_load_ratio: float = 0.4

    def __post_init__(self) -> None:
        where = "station_keeping.vane"
        if min(self.capacity_X_N, self.capacity_Y_N, self.capacity_N_Nm, self.grid_step_rad) <= 0.0:
            raise ConfigError(f"{where}: capacities and grid_step_rad must be > 0")
        if not 0.0 <= self.max_offset_rad <= math.pi:
            raise ConfigError(f"{where}.max_offset_rad must be in [0, pi], got {self.max_offset_rad}")
        if not 0.0 <= self.hysteresis < 1.0 or self.hysteresis_abs < 0.0:
            raise ConfigError(f"{where}.hysteresis must be in [0, 1) and hysteresis_abs >= 0")
        if not 0.0 <= self.release_load_N <= self.min_load_N:
            raise ConfigError(f"{where}: need 0 <= release_load_N <= min_load_N")
        if not 0.0 < self.release_load_ratio <= self.engage_load_ratio:
            raise ConfigError(f"{where}: need 0 < release_load_ratio <= engage_load_ratio, got "
                              f"{self.release_load_ratio} and {self.engage_load_ratio}")


def steady_hold_thrust(heading_rad: np.ndarray | float, current_ne_mps: tuple[float, float],
                       params: VesselParameters, wind: Environment | None = None,
                       tau_body: tuple[float, float, float] = (0.0, 0.0, 0.0),
                       force_ne_N: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """Thrust [tau_X, tau_Y, tau_N] (shape (3,) + heading's shape) the actuators must give to hold
    position at `heading_rad` in the current, the wind (its wind fields), a body-frame external force
    `tau_body` (e.g. the EKF's disturbance_tau, valid at any heading: treated as turning with the hull)
    and an earth-frame external force `force_ne_N` (does not turn with the hull)."""
    p = params
    psi = np.asarray(heading_rad, dtype=float)
    c, s = np.cos(psi), np.sin(psi)
    cn, ce = float(current_ne_mps[0]), float(current_ne_mps[1])
    ur = -(cn * c + ce * s)
    vr = -(-cn * s + ce * c)
    aur, avr = np.abs(ur), np.abs(vr)
    tX = surge_drag(p, ur)
    tY = p.Y_v * vr - p.Y_uv * aur * vr - p.Y_vv * avr * vr
    tN = -(p.m11 - p.m22) * ur * vr + p.N_v * vr - p.N_vv * avr * vr
    fn, fe = float(force_ne_N[0]), float(force_ne_N[1])
    tX = tX - (c * fn + s * fe) - tau_body[0]
    tY = tY - (-s * fn + c * fe) - tau_body[1]
    tN = tN - tau_body[2]
    if wind is not None and wind.wind_speed_mps > 0.0:
        w = np.array([wind_force(float(h), 0.0, 0.0, wind) for h in psi.ravel()]).T.reshape((3,) + psi.shape)
        tX, tY, tN = tX - w[0], tY - w[1], tN - w[2]
    return np.stack([tX, tY, tN])


def hold_load_ratio(heading_rad: float, current_ne_mps: tuple[float, float], params: VesselParameters,
                    config: WeathervaneConfig = WeathervaneConfig(), wind: Environment | None = None,
                    tau_body: tuple[float, float, float] = (0.0, 0.0, 0.0),
                    force_ne_N: tuple[float, float] = (0.0, 0.0)) -> float:
    """The largest per-axis fraction of the actuators' capacity that holding at `heading_rad` needs:
    max(|tau_X| / F_X, |tau_Y| / F_Y, |tau_N| / M_N) of `steady_hold_thrust`. Above 1 the heading
    cannot be held; the automatic weathervane engages above `config.engage_load_ratio`."""
    t = steady_hold_thrust(float(heading_rad), current_ne_mps, params, wind, tau_body, force_ne_N)
    return float(max(abs(t[0]) / config.capacity_X_N, abs(t[1]) / config.capacity_Y_N,
                     abs(t[2]) / config.capacity_N_Nm))


def weathervane_heading(preferred_heading_rad: float, previous_heading_rad: float | None,
                        current_ne_mps: tuple[float, float], params: VesselParameters,
                        config: WeathervaneConfig = WeathervaneConfig(), wind: Environment | None = None,
                        tau_body: tuple[float, float, float] = (0.0, 0.0, 0.0),
                        force_ne_N: tuple[float, float] = (0.0, 0.0)) -> float:
    """Heading (rad, wrapped) that minimises the normalised steady hold thrust J(psi) (module docstring),
    within `config.max_offset_rad` of the preferred heading, with hysteresis against `previous_heading_rad`
    (None: no previous choice). Pure."""
    c = config
    n = max(int(math.ceil(2.0 * c.max_offset_rad / c.grid_step_rad)), 1)
    offsets = np.linspace(-c.max_offset_rad, c.max_offset_rad, n + 1)
    if c.max_offset_rad >= math.pi - 1e-9:
        offsets = offsets[:-1]  # -pi and +pi are the same heading
    cand = preferred_heading_rad + offsets

    def thrust(h: np.ndarray) -> np.ndarray:
        return steady_hold_thrust(h, current_ne_mps, params, wind, tau_body, force_ne_N)

    def load_cost(t: np.ndarray) -> np.ndarray:
        return (t[0] / c.capacity_X_N) ** 2 + (t[1] / c.capacity_Y_N) ** 2 + (t[2] / c.capacity_N_Nm) ** 2

    t_pref = thrust(np.array([preferred_heading_rad]))
    # direction the load comes from: the thrust needed, expressed in the earth frame, points upstream
    fx, fy = float(t_pref[0, 0]), float(t_pref[1, 0])
    load_N = math.hypot(fx, fy)
    t_all = thrust(cand)
    load_all = load_cost(t_all)
    max_load_N = max(load_N, float(np.max(np.hypot(t_all[0], t_all[1]))))
    if max_load_N < c.min_load_N:
        # negligible load: the operator's heading; a load between the two thresholds keeps the
        # previous choice (hysteresis on the load too, or a light load makes the hull swing back and forth)
        if previous_heading_rad is not None and max_load_N > c.release_load_N:
            return wrap_angle(float(previous_heading_rad))
        return wrap_angle(preferred_heading_rad)
    upstream = preferred_heading_rad + math.atan2(fy, fx)
    j0 = float(np.max(load_all))
    cost = (load_all + c.preference_weight * (1.0 - np.cos(offsets))
            + c.bow_into_load_weight * j0 * (1.0 - np.cos(cand - upstream)))
    i = int(np.argmin(cost))
    best = float(cand[i])
    if previous_heading_rad is None:
        return wrap_angle(best)
    prev = float(previous_heading_rad)
    prev_off = wrap_angle(prev - preferred_heading_rad)
    if abs(prev_off) > c.max_offset_rad + 1e-9:
        return wrap_angle(best)  # the previous choice is outside the (possibly changed) limits
    t_prev = thrust(np.array([prev]))
    cost_prev = float(load_cost(t_prev)[0] + c.preference_weight * (1.0 - math.cos(prev_off))
                      + c.bow_into_load_weight * j0 * (1.0 - math.cos(prev - upstream)))
    saving = cost_prev - float(cost[i])
    if abs(wrap_angle(best - prev)) < c.min_change_rad or saving < max(c.hysteresis * cost_prev, c.hysteresis_abs):
        return wrap_angle(prev)
    return wrap_angle(best)
