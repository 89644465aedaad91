"""Fallback path followers (seed section 3.5: "Pure Pursuit, or feedforward from the model with PID/LQ").

All three compute generalized forces tau = [tau_X, tau_Y, tau_N] and hand them to the
`ThrustAllocator`; the allocation then respects angle, speed and slew limits.

* `PurePursuitController`: the lookahead point L metres ahead on the path gives the curvature
  command kappa = 2 sin(eta) / L (eta: bearing of the lookahead point relative to the course),
  r_d = U kappa; a yaw-rate P loop with model feedforward makes tau_N; a speed PID makes tau_X.
* `LOSController`: Fossen's integral line-of-sight guidance (Fossen 2021, sec. 12.4; Borhaug et
  al. 2008): psi_d = psi_path - atan((e + sigma e_int) / Delta) - beta, e_int_dot = Delta e /
  (Delta^2 + (e + sigma e_int)^2), beta = atan2(v, u) the measured crab angle (optional); a heading
  PID with yaw-rate damping and curvature feedforward; speed PID. The integral compensates the
  drift that the crab-angle measurement misses.
* `LQController`: model feedforward (the steady forces of seed eq. 22 for the path speed and
  curvature) plus LQR (scipy.linalg.solve_continuous_are) on the path-error model linearised at the
  reference speed, with an integral of the cross-track error (LQI), gain-scheduled in speed:

      x = [e, psi - psi_path, u - U, v, r - U kappa, int e],   input delta tau
      e_dot = U (psi - psi_path) + v,  psi_err_dot = r - U kappa,  nu_dot = A_nu nu + M^-1 tau
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from lotsen.control.allocation import AllocationConfig, ThrustAllocator, rate_limit
from lotsen.control.base import PathReference, SeaLevel, SeaLevelConfig, make_status, state_is_finite, wrap_angle
from lotsen.messages import ControllerStatus, ThrustCommand, VesselState
from lotsen.model.dynamics import VesselModel, surge_drag
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits


@dataclass(frozen=True)
class SpeedPIDConfig:
    kp: float = 1.0  # 1/s (times m11: N per m/s)
    ki: float = 0.3  # 1/s^2
    kd: float = 0.0
    integral_limit_N: float = 3.0


@dataclass(frozen=True)
class PursuitConfig:
    dt_s: float = 0.1
    lookahead_min_m: float = 1.0
    lookahead_time_s: float = 2.0  # L = max(L_min, U * lookahead_time)
    yaw_rate_gain: float = 3.0  # 1/s, yaw-rate loop bandwidth
    min_speed_ref_mps: float = 0.15
    speed: SpeedPIDConfig = SpeedPIDConfig()


@dataclass(frozen=True)
class LOSConfig:
    dt_s: float = 0.1
    lookahead_m: float = 1.5  # Delta
    integral_gain: float = 0.2  # sigma
    integral_limit_m: float = 3.0
    heading_natural_freq_radps: float = 2.0
    heading_damping: float = 1.0
    heading_ki: float = 0.05  # integral of heading error (1/s), times the P gain
    sideslip_compensation: bool = False  # steer the course, not the heading: psi_d -= atan2(v, u)
    min_speed_ref_mps: float = 0.15
    speed: SpeedPIDConfig = SpeedPIDConfig()
    # In a sea the heading loop can slow, as the sea level (`sea`) rises, to this natural frequency
    # (None: off, the default). Measured (lake boat, figure eight, Hs 6 cm, seed 0, x calm): at 0.5 m/s
    # 1.4 rad/s took azimuth travel 2.23 -> 1.19 and reversals 2.98 -> 1.48 at tracking 1.18 -> 1.21; at
    # 1.0 m/s it let the sea knock the hull off course, tracking 1.78 -> 4.6 x calm at 2.7 x the energy
    # (docs/control.md "Waves"). Flat water: unchanged either way.
    wave_heading_natural_freq_radps: float | None = None
    sea: SeaLevelConfig = SeaLevelConfig()


@dataclass(frozen=True)
class LQConfig:
    dt_s: float = 0.1
    q_cross_track: float = 40.0
    q_heading: float = 5.0
    q_speed: float = 20.0
    q_sway: float = 1.0
    q_yaw_rate: float = 1.0
    q_integral: float = 0.2
    r_force: float = 0.05  # per N^2 (X, Y)
    r_moment: float = 0.5  # per (N m)^2
    integral_limit_m: float = 2.0
    speed_schedule_step_mps: float = 0.05
    min_speed_ref_mps: float = 0.15


class _TauFollower:
    """Shared parts: path reference, progress, allocation, rate limits, status."""

    name = "tau"

    def __init__(self, model: VesselModel | None, limits: ActuatorLimits, dt_s: float, min_speed: float,
                 allocation: AllocationConfig = AllocationConfig()) -> None:
        self.model = model or VesselModel()
        self.limits = limits
        self.dt_s = dt_s
        self.min_speed = min_speed
        self.allocator = ThrustAllocator(self.model, limits, allocation)
        self.path: PathReference | None = None
        self.failures = 0
        self._s = 0.0
        self._done = False
        self._cmd_prev: tuple[float, ...] | None = None

    def reset(self, path: Any, progress_m: float = 0.0) -> None:
        self.path = PathReference(path, self.min_speed)
        self.failures = 0
        self._s = float(progress_m)
        self._done = False
        self._cmd_prev = None
        self._first_update = True
        self.allocator.reset()
        self._reset_loops()

    def _reset_loops(self) -> None:
        pass

    def _observe(self, state: VesselState) -> None:
        """What a follower reads of the state beyond the six states, once per update (the sea)."""

    def _take_over(self, x: np.ndarray, cte: float, hdg: float) -> None:
        """First update after reset with the boat already under way (a fallback taking over, a
        return path started at speed): set the loops' integrals so the command continues what the
        boat is doing (bumpless transfer) instead of starting from zero."""

    @property
    def done(self) -> bool:
        return self._done

    @property
    def progress_m(self) -> float:
        return self._s

    def _surge_feedforward(self, U: float) -> float:
        return float(surge_drag(self.model.params, U))

    def _tau(self, t: float, x: np.ndarray, s: float, cte: float, hdg: float) -> np.ndarray:
        raise NotImplementedError

    def update(self, t: float, state: VesselState) -> tuple[ThrustCommand, ControllerStatus]:
        if self.path is None:
            raise RuntimeError(f"{type(self).__name__}.update before reset(path)")
        if not state_is_finite(state):
            self.failures += 1
            cmd = ThrustCommand.neutral(t, self.name)
            self._cmd_prev = cmd.as_tuple()
            return cmd, make_status(t, self.name, float("nan"), float("nan"), state, float("nan"),
                                    self._s, status="safe_stop (state not finite)", failures=self.failures)
        x = np.array(state.as_array_tuple())
        s, cte, hdg = self.path.project(x[0], x[1], self._s)
        self._s = s
        if s >= self.path.length - 0.02:
            self._done = True
        self._observe(state)
        if self._first_update:
            self._first_update = False
            if x[3] >= self.min_speed:
                self._take_over(x, cte, hdg)
        tau = self._tau(t, x, s, cte, hdg)
        status = "ok"
        if not np.all(np.isfinite(tau)):
            self.failures += 1
            tau = np.zeros(3)
            status = "safe_stop (non-finite force)"
        res = self.allocator.allocate(tau, nu=(x[3], x[4], x[5]))
        cmd = rate_limit(self._cmd_prev, res.command, self.dt_s, self.limits)
        self._cmd_prev = cmd
        if res.saturated and status == "ok":
            status = "saturated"
        v_ref = float(self.path.sample(np.array([s]))[4][0])
        return (ThrustCommand.from_tuple(t, cmd, source=self.name),
                make_status(t, self.name, cte, wrap_angle(x[2] - hdg), state, v_ref, s, status=status,
                            failures=self.failures))


class _SpeedPID:
    def __init__(self, cfg: SpeedPIDConfig, m11: float, dt: float) -> None:
        self.cfg, self.m11, self.dt = cfg, m11, dt
        self.integral = 0.0
        self.prev_err: float | None = None

    def reset(self) -> None:
        self.integral = 0.0
        self.prev_err = None

    def __call__(self, err: float) -> float:
        c = self.cfg
        self.integral = min(max(self.integral + c.ki * self.m11 * err * self.dt, -c.integral_limit_N),
                            c.integral_limit_N)
        d = 0.0 if self.prev_err is None else (err - self.prev_err) / self.dt
        self.prev_err = err
        return self.m11 * (c.kp * err + c.kd * d) + self.integral


class PurePursuitController(_TauFollower):
    """Pure pursuit + yaw-rate loop + speed PID (see module docstring)."""

    name = "pursuit"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: PursuitConfig = PursuitConfig()) -> None:
        super().__init__(model, limits, config.dt_s, config.min_speed_ref_mps)
        self.config = config
        self.speed_pid = _SpeedPID(config.speed, self.model.params.m11, config.dt_s)

    def _reset_loops(self) -> None:
        self.speed_pid.reset()

    def _tau(self, t: float, x: np.ndarray, s: float, cte: float, hdg: float) -> np.ndarray:
        assert self.path is not None
        c, p = self.config, self.model.params
        v_ref = float(self.path.sample(np.array([s]))[4][0])
        U = max(math.hypot(x[3], x[4]), 0.05)
        L = max(c.lookahead_min_m, c.lookahead_time_s * max(U, v_ref))
        n, e, _h, _k, _v = self.path.sample(np.array([s + L]))
        bearing = math.atan2(e[0] - x[1], n[0] - x[0])
        course = x[2] + math.atan2(x[4], max(x[3], 0.05))
        eta = wrap_angle(bearing - course)
        dist = max(math.hypot(e[0] - x[1], n[0] - x[0]), 1e-3)
        kappa = 2.0 * math.sin(eta) / dist  # pure pursuit curvature law
        r_d = max(U, v_ref) * kappa
        tau_N = p.m33 * c.yaw_rate_gain * (r_d - x[5]) + p.N_r * r_d
        tau_X = self._surge_feedforward(v_ref) + self.speed_pid(v_ref - x[3])
        return np.array([tau_X, 0.0, tau_N])


class LOSController(_TauFollower):
    """Integral line-of-sight guidance + heading PID + speed PID (see module docstring)."""

    name = "los"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: LOSConfig = LOSConfig()) -> None:
        super().__init__(model, limits, config.dt_s, config.min_speed_ref_mps)
        self.config = config
        self.speed_pid = _SpeedPID(config.speed, self.model.params.m11, config.dt_s)
        self.sea = SeaLevel(config.sea, config.dt_s)
        self._e_int = 0.0
        self._psi_int = 0.0

    def _reset_loops(self) -> None:
        self.speed_pid.reset()
        self.sea.reset()
        self._e_int = 0.0
        self._psi_int = 0.0

    def _observe(self, state: VesselState) -> None:
        self.sea.update(state.wave_motion)

    def _take_over(self, x: np.ndarray, cte: float, hdg: float) -> None:
        """The integral e_int that makes psi_d the present heading: the crab angle the previous
        controller held against current and wind is kept, not relearnt over metres of drift."""
        c = self.config
        psi = x[2] + (math.atan2(x[4], x[3]) if c.sideslip_compensation and x[3] > 0.1 else 0.0)
        lead = wrap_angle(hdg - psi)  # psi_d = hdg - atan((e + sigma e_int) / D)
        if abs(lead) < math.radians(45.0) and c.integral_gain > 0:
            e_int = (c.lookahead_m * math.tan(lead) - cte) / c.integral_gain
            self._e_int = min(max(e_int, -c.integral_limit_m), c.integral_limit_m)

    def _tau(self, t: float, x: np.ndarray, s: float, cte: float, hdg: float) -> np.ndarray:
        assert self.path is not None
        c, p = self.config, self.model.params
        _n, _e, _h, kappa, v = self.path.sample(np.array([s]))
        v_ref, kappa_p = float(v[0]), float(kappa[0])
        D, sigma = c.lookahead_m, c.integral_gain
        ee = cte + sigma * self._e_int
        psi_d = hdg - math.atan(ee / D)
        if c.sideslip_compensation and x[3] > 0.1:
            # the crab angle from the measured ground velocity (current, wind, turning), so the
            # integral only has to learn what the measurement misses (Fossen 2021, sec. 12.4.3)
            psi_d -= math.atan2(x[4], x[3])
        # integral LOS: e_int_dot = D e / (D^2 + (e + sigma e_int)^2)
        self._e_int += self.dt_s * D * cte / (D * D + ee * ee)
        self._e_int = min(max(self._e_int, -c.integral_limit_m), c.integral_limit_m)
        err = wrap_angle(psi_d - x[2])
        U = max(math.hypot(x[3], x[4]), v_ref)
        r_d = U * kappa_p  # curvature feedforward (the LOS angle's own rate is left to the PD)
        w = c.heading_natural_freq_radps
        if c.wave_heading_natural_freq_radps is not None:
            w += (c.wave_heading_natural_freq_radps - w) * self.sea.level  # slower in a sea
        z = c.heading_damping
        kp = p.m33 * w * w
        kd = max(2.0 * z * w * p.m33 - p.N_r, 0.0)
        self._psi_int = min(max(self._psi_int + err * self.dt_s, -1.0), 1.0)
        tau_N = kp * (err + c.heading_ki * self._psi_int) + kd * (r_d - x[5]) + p.N_r * r_d
        tau_X = self._surge_feedforward(v_ref) + self.speed_pid(v_ref - x[3])
        return np.array([tau_X, 0.0, tau_N])


class LQController(_TauFollower):
    """Model feedforward + gain-scheduled LQI on the path-error model (see module docstring)."""

    name = "lq"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: LQConfig = LQConfig()) -> None:
        super().__init__(model, limits, config.dt_s, config.min_speed_ref_mps)
        self.config = config
        self._gains: dict[float, np.ndarray] = {}
        self._e_int = 0.0

    def _reset_loops(self) -> None:
        self._e_int = 0.0

    def gain(self, U: float) -> np.ndarray:
        """LQR gain K (3 x 6) at the reference speed U (cached on a speed grid)."""
        c = self.config
        key = round(max(U, c.min_speed_ref_mps) / c.speed_schedule_step_mps) * c.speed_schedule_step_mps
        K = self._gains.get(key)
        if K is not None:
            return K
        p = self.model.params
        n0 = self.model.propeller_speed_for_surge(key)
        A6, _B = self.model.jacobians([0, 0, 0, key, 0, 0], [0, 0, n0, n0, 0])
        A = np.zeros((6, 6))
        A[0, 1] = key  # e_dot = U psi_err + v
        A[0, 3] = 1.0
        A[1, 4] = 1.0  # psi_err_dot = r - r_ref
        A[2:5, 2:5] = A6[3:6, 3:6]
        A[5, 0] = 1.0  # d/dt int e = e
        B = np.zeros((6, 3))
        B[2:5, :] = np.diag([1.0 / p.m11, 1.0 / p.m22, 1.0 / p.m33])
        Q = np.diag([c.q_cross_track, c.q_heading, c.q_speed, c.q_sway, c.q_yaw_rate, c.q_integral])
        R = np.diag([c.r_force, c.r_force, c.r_moment])
        X = scipy.linalg.solve_continuous_are(A, B, Q, R)
        K = np.linalg.solve(R, B.T @ X)
        self._gains[key] = K
        return K

    def feedforward(self, U: float, r: float) -> np.ndarray:
        """Steady forces of seed eq. (22) at u = U, v = 0, yaw rate r."""
        p = self.model.params
        return np.array([surge_drag(p, U),
                         p.m11 * U * r + p.Y_r * r,
                         p.N_r * r - p.N_rr * abs(r) * r])

    def _tau(self, t: float, x: np.ndarray, s: float, cte: float, hdg: float) -> np.ndarray:
        assert self.path is not None
        c = self.config
        _n, _e, _h, kappa, v = self.path.sample(np.array([s]))
        U, kappa_p = float(v[0]), float(kappa[0])
        r_ref = U * kappa_p
        self._e_int = min(max(self._e_int + cte * self.dt_s, -c.integral_limit_m), c.integral_limit_m)
        dx = np.array([cte, wrap_angle(x[2] - hdg), x[3] - U, x[4], x[5] - r_ref, self._e_int])
        return self.feedforward(U, r_ref) - self.gain(U) @ dx
