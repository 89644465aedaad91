"""Model-aided extended Kalman filter (beyond the seed): one filter for pose, velocity and biases.

State x = [N, E, psi, u, v, r, b_g, (b_ax, b_ay)]: position in local NED (m), heading (rad,
clockwise from north), body velocities (m/s, rad/s) over ground, gyro z bias (rad/s) and, by
default, the accelerometer's horizontal biases (m/s^2). The two accelerometer-bias states extend
the issue's seven: without them a 0.05 m/s^2 bias, read through the model's drag derivative,
pulls the surge estimate by centimetres per second (see docs/fusion.md for the numbers).

Process model: the vessel model (lotsen.model, seed eq. 7-8, 22) driven by the achieved (or
commanded) actuator values, integrated with RK4 (`rk4_step`); covariance propagated with
F = I + A dt + (A dt)^2 / 2 from the analytic Jacobian A = df/dx (`VesselModel.jacobians`),
white-acceleration process noise on u, v, r for the model's errors (current, wind, parameters),
random walks for the biases.

Measurements (each gated by its squared Mahalanobis distance against a chi-square quantile;
NaN / non-finite samples are skipped and counted, never used):
- GNSS position (lat/lon -> NED with pymap3d.geodetic2ned at a fixed origin), R per fix type
  from h_acc_m (`GnssNoise`); optionally the receiver's NED velocity.
- Gyro z: r + b_g, every IMU sample.
- Accelerometer x, y (averaged over `accel_decimation` samples): the model's specific force
  [u_dot - v r, v_dot + u r] + b_a of a level boat.
- Calibrated magnetometer heading: psi (innovation wrapped to [-pi, pi)); samples whose
  calibrated field norm is far from 1 are rejected as disturbed before the gate.

A gate that rejects a sensor `max_consecutive_rejects` times in a row re-opens by inflating the
covariance of the states that sensor sees, so a real jump (RTK re-fix) or a wrong start cannot
lock the filter out. Time comes only from message stamps: every message first predicts the
filter to its stamp; a message older than `max_lag_s` is skipped as stale, a slightly late one
is applied at the filter's time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from lotsen.fusion.common import Counters, GnssNoise, LocalFrame, finite, wrap_angle
from lotsen.fusion.magcal import MagCalibration
from lotsen.messages import ActuatorState, GnssFix, ImuSample, MagSample, ThrustCommand, VesselState
from lotsen.model.dynamics import VesselModel, rk4_step

IN, IE, IPSI, IU, IV, IR, IBG, IBAX, IBAY = range(9)


@dataclass(frozen=True)
class EkfConfig:
    # process noise (continuous-time spectral densities, per second)
    sigma_pos_mps: float = 0.05  # slack on N, E (m/sqrt(s)): the unmodelled current; 0.005 left the
    # covariance too small after a 10 s outage in 0.05 m/s current (the gate then refused 2 s of fixes)
    sigma_psi_radps: float = 0.001
    sigma_nu_dot: tuple[float, float, float] = (0.08, 0.08, 0.1)  # model error on u_dot, v_dot, r_dot
    sigma_gyro_bias_walk: float = 0.0005  # rad/s/sqrt(s)
    sigma_accel_bias_walk: float = 0.002  # m/s^2/sqrt(s)
    # measurement noise
    sigma_gyro_radps: float = 0.005
    sigma_accel_mps2: float = 0.08  # of the decimated mean: noise, vibration, model's force error
    sigma_mag_heading_rad: float = math.radians(2.0)
    mag_norm_tolerance: float = 0.3
    gnss_noise: GnssNoise = field(default_factory=GnssNoise)
    use_gnss_velocity: bool = True
    use_accel: bool = True
    accel_bias_states: bool = True
    accel_decimation: int = 5
    # gating
    gate_probability: float = 0.9999  # chi-square quantile: 1 dof -> 15.1, 2 dof -> 18.4
    max_consecutive_rejects: dict = field(default_factory=lambda: {
        "gnss": 16, "gnss_vel": 16, "mag": 100, "gyro": 50, "accel": 40})
    # timing
    max_step_s: float = 0.02  # prediction sub-step
    max_lag_s: float = 0.25  # older messages are skipped
    command_timeout_s: float = 0.5  # a ThrustCommand is used only without fresher ActuatorState
    origin: tuple[float, float, float] | None = None  # lat, lon, h; None: the first usable fix
    # initial uncertainty
    P0_std: tuple[float, ...] = (100.0, 100.0, math.pi, 1.0, 0.5, 0.5, 0.03, 0.2, 0.2)


class ModelAidedEKF:
    """Pure estimator: feed messages in stamp order, read `estimate(t)`."""

    source = "ekf"

    def __init__(self, model: VesselModel | None = None, calibration: MagCalibration | None = None,
                 config: EkfConfig = EkfConfig(), initial: VesselState | None = None,
                 initial_std: tuple[float, ...] | None = None) -> None:
        self.model = model or VesselModel()
        self.calibration = calibration or MagCalibration.identity()
        self.config = config
        self.n = 9 if config.accel_bias_states else 7
        self.x = np.zeros(self.n)
        if initial is not None:
            self.x[:6] = initial.as_array_tuple()
            self.x[IBG] = initial.gyro_bias_radps
        std = np.array(initial_std if initial_std is not None else config.P0_std, dtype=float)[: self.n]
        self.P = np.diag(std ** 2)
        self.t: float | None = initial.stamp_s if initial is not None else None
        self.u_act: tuple[float, ...] = (0.0,) * 5
        self._t_actuator = -math.inf
        self.frame = LocalFrame(*config.origin) if config.origin else None
        self.counters = Counters()
        self._rejects: dict[str, int] = {}
        self._acc_sum = [0.0, 0.0]
        self._acc_n = 0
        c = config
        self._gate = {k: float(chi2.ppf(c.gate_probability, k)) for k in (1, 2)}
        q = [c.sigma_pos_mps ** 2, c.sigma_pos_mps ** 2, c.sigma_psi_radps ** 2,
             c.sigma_nu_dot[0] ** 2, c.sigma_nu_dot[1] ** 2, c.sigma_nu_dot[2] ** 2, c.sigma_gyro_bias_walk ** 2]
        if self.n == 9:
            q += [c.sigma_accel_bias_walk ** 2] * 2
        self._q = np.array(q)
        self._I = np.eye(self.n)

    # -- prediction ------------------------------------------------------------------------------
    def _predict(self, x: np.ndarray, P: np.ndarray, dt_total: float) -> tuple[np.ndarray, np.ndarray]:
        model, u = self.model, self.u_act
        steps = max(1, int(math.ceil(dt_total / self.config.max_step_s - 1e-9)))
        dt = dt_total / steps
        n = self.n
        for _ in range(steps):
            x6 = (x[0], x[1], x[2], x[3], x[4], x[5])
            A, _ = model.jacobians(x6, u)
            x1, _ = rk4_step(x6, u, model.theta, model.geom, 0.0, 0.0, 0.0, 0.0, 0.0, dt)
            x = x.copy()
            x[:6] = x1
            x[IPSI] = wrap_angle(x[IPSI])
            Ad = A * dt
            F = self._I.copy()
            F[:6, :6] += Ad + 0.5 * (Ad @ Ad)  # P = F P F' + Q
            P = F @ P @ F.T
            P[range(n), range(n)] += self._q * dt
        return x, P

    def _advance(self, stamp: float, sensor: str) -> bool:
        """Predict to `stamp`; False (and counted as skipped) if the message is stale or bad."""
        if not math.isfinite(stamp):
            self.counters.count("skipped", sensor)
            return False
        if self.t is None:
            self.t = stamp
            return True
        dt = stamp - self.t
        if dt > 0.0:
            self.x, self.P = self._predict(self.x, self.P, dt)
            self.t = stamp
        elif dt < -self.config.max_lag_s:
            self.counters.count("skipped", sensor)
            return False
        return True

    # -- update ----------------------------------------------------------------------------------
    def _update(self, sensor: str, y: np.ndarray, H: np.ndarray, R: np.ndarray,
                reopen: tuple[int, ...] = ()) -> bool:
        """Gated EKF update. y = z - h(x). Re-opens after many consecutive rejections by inflating
        the covariance of the states in `reopen` by the innovation (so the next sample passes)."""
        P = self.P
        PHt = P @ H.T
        S = H @ PHt + R
        try:
            Sinv = np.linalg.inv(S)
        except np.linalg.LinAlgError:
            self.counters.count("skipped", sensor)
            return False
        d2 = float(y @ Sinv @ y)
        if not math.isfinite(d2):
            self.counters.count("skipped", sensor)
            return False
        if d2 > self._gate[len(y)]:
            k = self._rejects.get(sensor, 0) + 1
            self._rejects[sensor] = k
            self.counters.count("rejected", sensor)
            if k >= self.config.max_consecutive_rejects.get(sensor, 50) and reopen:
                # persistent disagreement: believe the sensor again, at the size of the disagreement
                inflate = float(np.max(np.abs(y))) ** 2 + float(np.max(np.diag(R)))
                for i in reopen:
                    self.P[i, :] *= 0.0
                    self.P[:, i] *= 0.0
                    self.P[i, i] = inflate * 4.0
                self._rejects[sensor] = 0
            return False
        self._rejects[sensor] = 0
        K = PHt @ Sinv  # K = P H' S^-1
        self.x = self.x + K @ y  # x = x + K y
        self.x[IPSI] = wrap_angle(self.x[IPSI])
        IKH = self._I - K @ H
        self.P = IKH @ P @ IKH.T + K @ R @ K.T  # Joseph form: stays symmetric positive definite
        self.counters.count("used", sensor)
        return True

    # -- messages --------------------------------------------------------------------------------
    def on_command(self, m: ThrustCommand | ActuatorState) -> None:
        """Model input: ActuatorState (achieved values) wins; a ThrustCommand (set-points) is used
        when no ActuatorState arrived for `command_timeout_s`."""
        u = m.as_tuple()
        if not finite(m.stamp_s, *u):
            self.counters.count("skipped", "command")
            return
        if isinstance(m, ActuatorState):
            self._t_actuator = m.stamp_s
        elif m.stamp_s - self._t_actuator < self.config.command_timeout_s:
            return
        # predict with the old input up to the stamp, then switch (zero-order hold)
        if self.t is not None and m.stamp_s > self.t:
            self._advance(m.stamp_s, "command")
        self.u_act = u
        self.counters.count("used", "command")

    def on_imu(self, m: ImuSample) -> None:
        gz, ax, ay = m.gyro_radps[2], m.accel_mps2[0], m.accel_mps2[1]
        if not finite(gz):
            self.counters.count("skipped", "gyro")
        elif self._advance(m.stamp_s, "gyro"):
            H = np.zeros((1, self.n))
            H[0, IR] = 1.0
            H[0, IBG] = 1.0
            y = np.array([gz - self.x[IR] - self.x[IBG]])
            self._update("gyro", y, H, np.array([[self.config.sigma_gyro_radps ** 2]]), reopen=(IBG, IR))
        if not self.config.use_accel:
            return
        if not finite(ax, ay, m.stamp_s):
            self.counters.count("skipped", "accel")
            return
        self._acc_sum[0] += ax
        self._acc_sum[1] += ay
        self._acc_n += 1
        if self._acc_n >= self.config.accel_decimation:
            a = (self._acc_sum[0] / self._acc_n, self._acc_sum[1] / self._acc_n)
            self._acc_sum = [0.0, 0.0]
            self._acc_n = 0
            if self.t is not None and m.stamp_s >= self.t - self.config.max_lag_s:
                self._accel_update(a)

    def _accel_update(self, a: tuple[float, float]) -> None:
        x = self.x
        x6 = (x[0], x[1], x[2], x[3], x[4], x[5])
        model = self.model
        f = model.f(0.0, x6, self.u_act)
        A, _ = model.jacobians(x6, self.u_act)
        u, v, r = x[IU], x[IV], x[IR]
        h = np.array([f[3] - v * r, f[4] + u * r])  # specific force of a level boat, body frame
        H = np.zeros((2, self.n))
        H[0, :6] = A[3]
        H[1, :6] = A[4]
        H[0, IV] -= r
        H[0, IR] -= v
        H[1, IU] += r
        H[1, IR] += u
        if self.n == 9:
            h += x[IBAX:IBAY + 1]
            H[0, IBAX] = 1.0
            H[1, IBAY] = 1.0
        R = np.eye(2) * self.config.sigma_accel_mps2 ** 2
        self._update("accel", np.array(a) - h, H, R, reopen=(IU, IV, IR) + ((IBAX, IBAY) if self.n == 9 else ()))

    def on_mag(self, m: MagSample) -> None:
        mx, my = m.field_uT[0], m.field_uT[1]
        if not finite(mx, my):
            self.counters.count("skipped", "mag")
            return
        if not self._advance(m.stamp_s, "mag"):
            return
        wx, wy = self.calibration.apply(mx, my)
        if abs(math.hypot(wx, wy) - 1.0) > self.config.mag_norm_tolerance:
            self.counters.count("rejected", "mag")  # disturbed field (motor currents, steel nearby)
            return
        z = wrap_angle(math.atan2(-wy, wx) + self.calibration.heading_offset_rad)
        H = np.zeros((1, self.n))
        H[0, IPSI] = 1.0
        y = np.array([wrap_angle(z - self.x[IPSI])])  # innovation across +-180 deg
        self._update("mag", y, H, np.array([[self.config.sigma_mag_heading_rad ** 2]]), reopen=(IPSI,))

    def on_gnss(self, fix: GnssFix) -> None:
        if not fix.usable or not finite(fix.stamp_s, fix.lat_deg, fix.lon_deg):
            self.counters.count("skipped", "gnss")
            return
        if not self._advance(fix.stamp_s, "gnss"):
            return
        if self.frame is None:
            self.frame = LocalFrame(fix.lat_deg, fix.lon_deg, fix.height_m if math.isfinite(fix.height_m) else 0.0)
        n, e = self.frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m)
        noise = self.config.gnss_noise
        s = noise.position_sigma_m(fix)
        H = np.zeros((2, self.n))
        H[0, IN] = H[1, IE] = 1.0
        y = np.array([n - self.x[IN], e - self.x[IE]])
        self._update("gnss", y, H, np.eye(2) * s * s, reopen=(IN, IE))
        if self.config.use_gnss_velocity and finite(fix.vel_n_mps, fix.vel_e_mps):
            psi, u, v = self.x[IPSI], self.x[IU], self.x[IV]
            c, sn = math.cos(psi), math.sin(psi)
            h = np.array([c * u - sn * v, sn * u + c * v])
            Hv = np.zeros((2, self.n))
            Hv[0, IPSI], Hv[0, IU], Hv[0, IV] = -sn * u - c * v, c, -sn
            Hv[1, IPSI], Hv[1, IU], Hv[1, IV] = c * u - sn * v, sn, c
            sv = noise.velocity_floor_mps * noise.inflation.get(fix.fix_type, 3.0)
            self._update("gnss_vel", np.array([fix.vel_n_mps, fix.vel_e_mps]) - h, Hv, np.eye(2) * sv * sv,
                         reopen=(IU, IV))

    # -- output ----------------------------------------------------------------------------------
    @property
    def gyro_bias_radps(self) -> float:
        return float(self.x[IBG])

    def estimate(self, t: float | None = None) -> VesselState:
        """The estimate predicted to `t` (the filter itself is not advanced)."""
        x, P, stamp = self.x, self.P, self.t if self.t is not None else (t or 0.0)
        if t is not None and self.t is not None and t > self.t:
            x, P = self._predict(x, P, t - self.t)
            stamp = t
        std = np.sqrt(np.clip(np.diag(P)[:6], 0.0, None))
        return VesselState(stamp_s=float(stamp), north_m=float(x[0]), east_m=float(x[1]),
                           heading_rad=float(wrap_angle(x[2])), u_mps=float(x[3]), v_mps=float(x[4]),
                           r_radps=float(x[5]), source=self.source, std=tuple(float(s) for s in std),
                           gyro_bias_radps=float(x[IBG]))
