"""The seed's two scalar/planar Kalman filters (seed section 3.3, eq. 27-35), run side by side.

- `YawKalmanFilter` (seed eq. 27-31): state psi. Time update with the gyro z rate
  (psi += T u, P += T^2 Q) only if the rate is plausible; measurement update with the calibrated
  magnetometer heading (K = P / (P + R)) only if plausible: finite, calibrated field norm near 1
  and innovation inside a gate. Innovations are wrapped to [-pi, pi) so the filter crosses +-180 deg.
- `VelocityKalmanFilter` (seed eq. 32-35): state v = [v_N, v_E]. Time update with the body
  accelerations rotated by the estimated yaw; measurement update with the velocity from
  successive GNSS positions (difference / sample time).
- `SeedFilters`: both, behind the same interface as `ModelAidedEKF` (on_imu, on_mag, on_gnss,
  on_command, estimate), so the two can run side by side on the same messages.

Two small, documented additions to the seed: (i) the GNSS difference quotient is the *mean*
velocity over the fix interval, so it is compared with the filter's mean velocity over the same
interval (otherwise the update lags by half a GNSS period, 60 ms); (ii) a gate that rejects a
measurement many times in a row is reopened (the filter re-anchors on the measurement), so a
wrong initial state or a real jump cannot lock the filter out for ever.
Neither filter estimates the gyro or accelerometer bias (the seed does not); a known gyro bias
(e.g. from a standstill) can be given in the config.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lotsen.fusion.common import Counters, GnssNoise, finite, wrap_angle
from lotsen.model.geodetic import FixFrame
from lotsen.fusion.integrity import IntegrityConfig, IntegrityMonitor
from lotsen.fusion.magcal import MagCalibration
from lotsen.messages import (
    ActuatorState, EstimatorHealth, GnssFix, ImuSample, MagSample, ThrustCommand, VesselState,
)


@dataclass(frozen=True)
class YawFilterConfig:
    Q_rate: float = 0.1 ** 2  # (rad/s)^2: gyro rate uncertainty incl. unmodelled bias, seed eq. (29)
    R_heading: float = math.radians(2.0) ** 2  # rad^2, magnetometer heading, seed eq. (30)
    max_rate_radps: float = 4.0  # plausibility of the gyro
    mag_norm_tolerance: float = 0.3  # | |w| - 1 | above this: disturbed field, skip
    gate_sigma: float = 4.0  # innovation gate in standard deviations of sqrt(P + R)
    max_consecutive_rejects: int = 100  # then re-anchor (2 s of magnetometer at 50 Hz)
    gyro_bias_radps: float = 0.0  # known bias subtracted (the seed has none)


class YawKalmanFilter:
    """Seed eq. (27)-(31); psi in [-pi, pi)."""

    def __init__(self, config: YawFilterConfig = YawFilterConfig(), psi0: float = 0.0,
                 P0: float = math.pi ** 2) -> None:
        self.config = config
        self.x = wrap_angle(psi0)
        self.P = P0
        self._rejects = 0
        self.last_nis = math.nan

    def time_update(self, rate_radps: float, T: float) -> bool:
        """x += T u, P += T^2 Q (seed eq. 28-29), if the rate is plausible."""
        c = self.config
        if not finite(rate_radps, T) or abs(rate_radps) > c.max_rate_radps or T <= 0.0:
            return False
        self.x = wrap_angle(self.x + T * (rate_radps - c.gyro_bias_radps))  # seed eq. (28)
        self.P += T * T * c.Q_rate  # seed eq. (29)
        return True

    def measurement_update(self, heading_rad: float, R: float | None = None, allow_reanchor: bool = True) -> str:
        """K = P / (P + R), x += K (z - x), P = (1 - K) P (seed eq. 30-31). Returns 'used' or
        'rejected'; `last_nis` is y^2 / S of this sample. A persistent disagreement re-anchors
        on the measurement only if `allow_reanchor` (the integrity monitor decides)."""
        c = self.config
        R = c.R_heading if R is None else R
        y = wrap_angle(heading_rad - self.x)  # innovation across +-180 deg
        S = self.P + R
        self.last_nis = y * y / S
        if abs(y) > c.gate_sigma * math.sqrt(S):
            self._rejects += 1
            if self._rejects < c.max_consecutive_rejects or not allow_reanchor:
                return "rejected"
            self.x, self.P = wrap_angle(heading_rad), R  # re-anchor after a persistent disagreement
            self._rejects = 0
            return "used"
        self._rejects = 0
        K = self.P / S  # seed eq. (30)
        self.x = wrap_angle(self.x + K * y)  # seed eq. (31)
        self.P = (1.0 - K) * self.P
        return "used"


@dataclass(frozen=True)
class VelocityFilterConfig:
    Q_accel: float = 0.6 ** 2  # (m/s^2)^2: accel noise + unestimated bias + heading error, seed eq. (33)
    max_accel_mps2: float = 20.0  # plausibility
    max_speed_mps: float = 5.0  # a GNSS difference above this is implausible
    gate_chi2: float = 23.0  # 2 dof, p ~ 1e-5
    max_consecutive_rejects: int = 16  # 2 s of GNSS at 8 Hz
    max_fix_interval_s: float = 1.0  # longer gaps: restart the difference


class VelocityKalmanFilter:
    """Seed eq. (32)-(35): v = [v_N, v_E]."""

    def __init__(self, config: VelocityFilterConfig = VelocityFilterConfig(), P0: float = 1.0) -> None:
        self.config = config
        self.x = np.zeros(2)
        self.P = np.eye(2) * P0
        self._rejects = 0
        self.last_nis = math.nan

    def time_update(self, accel_body: tuple[float, float], psi: float, T: float) -> bool:
        """v += T R(psi) a, P += T^2 Q (seed eq. 32-33), if the acceleration is plausible."""
        c = self.config
        ax, ay = accel_body
        if not finite(ax, ay, psi, T) or math.hypot(ax, ay) > c.max_accel_mps2 or T <= 0.0:
            return False
        cp, sp = math.cos(psi), math.sin(psi)
        self.x[0] += T * (cp * ax - sp * ay)  # seed eq. (32), body -> NED
        self.x[1] += T * (sp * ax + cp * ay)
        self.P[0, 0] += T * T * c.Q_accel  # seed eq. (33)
        self.P[1, 1] += T * T * c.Q_accel
        return True

    def measurement_update(self, v_meas: np.ndarray, v_pred: np.ndarray, R: float,
                           allow_reanchor: bool = True) -> str:
        """K = P (P + R)^-1, v += K (z - v_pred), P = (I - K) P (seed eq. 34-35). `last_nis` is
        the squared Mahalanobis distance of this sample (inf for an implausible one)."""
        c = self.config
        if not np.all(np.isfinite(v_meas)):
            return "skipped"
        if float(np.hypot(*v_meas)) > c.max_speed_mps:
            self.last_nis = math.inf
            return "rejected"  # implausible: a position jump (seed: only plausible updates)
        y = v_meas - v_pred
        S = self.P + R * np.eye(2)
        d2 = float(y @ np.linalg.solve(S, y))
        self.last_nis = d2
        if d2 > c.gate_chi2:
            self._rejects += 1
            if self._rejects < c.max_consecutive_rejects or not allow_reanchor:
                return "rejected"
            self.x, self.P = v_meas.copy(), R * np.eye(2)
            self._rejects = 0
            return "used"
        self._rejects = 0
        K = self.P @ np.linalg.inv(S)  # seed eq. (34)
        self.x = self.x + K @ y  # seed eq. (35)
        self.P = (np.eye(2) - K) @ self.P
        self.P = 0.5 * (self.P + self.P.T)
        return "used"


@dataclass(frozen=True)
class SeedFiltersConfig:
    yaw: YawFilterConfig = YawFilterConfig()
    velocity: VelocityFilterConfig = VelocityFilterConfig()
    gnss_noise: GnssNoise = GnssNoise()
    origin: tuple[float, float, float] | None = None  # lat, lon, h; None: the first usable fix
    max_imu_gap_s: float = 0.5  # a longer gap is not integrated (the next update re-anchors)
    jump_confirm: int = 5  # IMU samples in a row beyond max_imu_gap_s: a real gap (else a bad stamp)
    no_rate_q: float = 0.5 ** 2  # (rad/s)^2: heading growth while the gyro is declared stuck
    no_accel_q: float = 1.0 ** 2  # (m/s^2)^2: velocity growth while the accelerometer is declared stuck
    pos_walk_m2ps: float = 0.01 ** 2  # m^2/s: growth of the dead-reckoned position's variance
    integrity: IntegrityConfig = IntegrityConfig()


class SeedFilters:
    """The seed's yaw and velocity filters combined, with the EKF's interface.

    Position (not estimated by the seed) is the last GNSS position dead-reckoned with the
    filtered velocity; r is the latest gyro rate (minus the configured bias).
    """

    source = "seed_kf"

    def __init__(self, calibration: MagCalibration | None = None, config: SeedFiltersConfig = SeedFiltersConfig(),
                 initial: VesselState | None = None, heading_std_rad: float = math.pi) -> None:
        self.config = config
        self.calibration = calibration or MagCalibration.identity()
        self.yaw = YawKalmanFilter(config.yaw, initial.heading_rad if initial else 0.0, heading_std_rad ** 2)
        self.vel = VelocityKalmanFilter(config.velocity)
        self.frame = FixFrame(config.origin)
        self.counters = Counters()
        self.t = -math.inf  # time of the state (last IMU sample)
        self.r = 0.0
        self.pos = np.array([initial.north_m, initial.east_m], dtype=float) if initial else np.zeros(2)
        self.pos_sigma = 10.0
        self._pos_var = 0.0  # variance added by dead reckoning since the last fix
        if initial:
            c, s = math.cos(initial.heading_rad), math.sin(initial.heading_rad)
            self.vel.x[:] = (c * initial.u_mps - s * initial.v_mps, s * initial.u_mps + c * initial.v_mps)
        self._last_fix: tuple[float, np.ndarray] | None = None
        self._v_integral = np.zeros(2)  # integral of v since the last fix (mean-velocity comparison)
        # integrity: the seed's sensors are the IMU (gyro + accelerometer together), the
        # magnetometer heading and the GNSS (through the velocity gate)
        self.monitor = IntegrityMonitor(config.integrity, sensors=("imu", "mag", "gnss"))
        self._future_run = 0
        self._gates = {"imu": math.inf, "mag": config.yaw.gate_sigma ** 2, "gnss": config.velocity.gate_chi2}

    # -- messages ------------------------------------------------------------------------------
    def on_imu(self, m: ImuSample) -> None:
        t = m.stamp_s
        gz, ax, ay = m.gyro_radps[2], m.accel_mps2[0], m.accel_mps2[1]
        if not finite(t, gz, ax, ay):
            self.counters.count("skipped", "imu")
            return
        if self.t == -math.inf:
            self.t = t
        T = t - self.t
        if T < 0.0:
            self.counters.count("skipped", "imu")  # out of order
            return
        if T > self.config.max_imu_gap_s:
            # one sample far ahead is a bad stamp (re-syncing on it would make every later sample
            # "out of order"); several in a row are a real gap: re-sync without integrating
            self._future_run += 1
            if self._future_run >= self.config.jump_confirm:
                self.t = t
                self._future_run = 0
                self.monitor.event(t, f"seed filters: IMU time jumped {T:.2f} s")
            self.counters.count("skipped", "imu")
            return
        self._future_run = 0
        mon = self.monitor
        mon.raw("gyro", t, m.gyro_radps)
        mon.raw("accel", t, m.accel_mps2)
        if T == 0.0:  # first sample (or a duplicate stamp): nothing to integrate
            self.counters.count("used", "imu", t)
            mon.used("imu", t)
            return
        # integrate position with the velocity before this step (rectangle rule, as eq. 32)
        self.pos += T * self.vel.x
        self._v_integral += T * self.vel.x
        ok_g = not mon.stuck("gyro") and self.yaw.time_update(gz, T)
        if not ok_g and mon.stuck("gyro"):
            # no rate: the heading may turn at up to ~0.5 rad/s; it follows the magnetometer alone
            self.yaw.P += T * T * max(self.config.yaw.Q_rate, self.config.no_rate_q)
        ok_a = not mon.stuck("accel") and self.vel.time_update((ax, ay), self.yaw.x, T)
        if not ok_a and mon.stuck("accel"):
            self.vel.P += np.eye(2) * (T * T * max(self.config.velocity.Q_accel, self.config.no_accel_q))
        self._pos_var += T * T * float(max(self.vel.P[0, 0], self.vel.P[1, 1])) + T * self.config.pos_walk_m2ps
        if ok_g:
            self.r = gz - self.config.yaw.gyro_bias_radps
            mon.heading(t, self.yaw.x, self.r)
        self.counters.count("used" if ok_g and ok_a else "rejected", "imu", t)
        if ok_g and ok_a:
            mon.used("imu", t)
        self.t = t

    def on_mag(self, m: MagSample) -> None:
        mx, my = m.field_uT[0], m.field_uT[1]
        if not finite(m.stamp_s, mx, my):
            self.counters.count("skipped", "mag")
            return
        wx, wy = self.calibration.apply(mx, my)
        if abs(math.hypot(wx, wy) - 1.0) > self.config.yaw.mag_norm_tolerance:
            self.counters.count("rejected", "mag")  # disturbed field: implausible (seed: skip)
            self.monitor.test("mag", m.stamp_s, math.inf, 1, self._gates["mag"], False)
            return
        psi_m = wrap_angle(math.atan2(-wy, wx) + self.calibration.heading_offset_rad)
        mon = self.monitor
        mon.raw("mag", m.stamp_s, m.field_uT)
        if mon.stuck("mag"):
            self.counters.count("skipped", "mag")
            return
        t = m.stamp_s
        status = self.yaw.measurement_update(psi_m, allow_reanchor=mon.reopen_allowed("mag", t))
        mon.test("mag", t, self.yaw.last_nis, 1, self._gates["mag"], status == "used")
        if status == "used":
            mon.used("mag", t)
        self.counters.count(status, "mag", t)

    def on_gnss(self, fix: GnssFix) -> None:
        if not fix.usable or not finite(fix.stamp_s, fix.lat_deg, fix.lon_deg):
            self.counters.count("skipped", "gnss")
            return
        p = np.array(self.frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m))
        sigma = self.config.gnss_noise.position_sigma_m(fix)
        status = "used"
        if self._last_fix is not None:
            t0, p0 = self._last_fix
            dt = fix.stamp_s - t0
            if dt <= 0.0:
                self.counters.count("skipped", "gnss")
                return
            # after a gap the difference restarts (seed); not while the GNSS is being rejected after
            # agreeing (a jump): then the fixes keep being compared with the dead reckoning
            if dt <= self.config.velocity.max_fix_interval_s or self.monitor.rejecting("gnss"):
                v_meas = (p - p0) / dt  # GNSS velocity by difference (seed)
                v_mean = self._v_integral / dt if self.t > t0 else self.vel.x
                # the quotient is the mean velocity over the interval: compare like with like
                status = self.vel.measurement_update(v_meas, v_mean, 2.0 * sigma ** 2 / dt ** 2,
                                                     allow_reanchor=self.monitor.reopen_allowed("gnss", fix.stamp_s))
                if status != "skipped":
                    self.monitor.test("gnss", fix.stamp_s, self.vel.last_nis, 2, self._gates["gnss"],
                                      status == "used")
        if status == "rejected":
            # the jump itself is not believed; the next fix is differenced against the last good one
            self.counters.count("rejected", "gnss")
            return
        self.counters.count("used" if status == "used" else "skipped", "gnss", fix.stamp_s)
        if status == "used":
            self.monitor.used("gnss", fix.stamp_s)
        self._last_fix = (fix.stamp_s, p)
        self._v_integral = np.zeros(2)
        self.pos, self.pos_sigma = p.copy(), sigma  # a copy: pos is dead-reckoned in place
        self._pos_var = 0.0

    def on_command(self, m: ThrustCommand | ActuatorState) -> None:
        """The seed filters do not use the model; accepted for interface parity."""

    # -- output --------------------------------------------------------------------------------
    def estimate(self, t: float | None = None) -> VesselState:
        """State extrapolated (not changing the filters) to `t` with the last rate and velocity."""
        dt = 0.0 if t is None or self.t == -math.inf else max(0.0, t - self.t)
        psi = wrap_angle(self.yaw.x + dt * self.r)
        vn, ve = self.vel.x
        c, s = math.cos(psi), math.sin(psi)
        Pv = self.vel.P
        pos_std = math.hypot(self.pos_sigma, math.sqrt(self._pos_var))
        return VesselState(
            stamp_s=float(t) if t is not None else self.t,
            north_m=float(self.pos[0] + dt * vn), east_m=float(self.pos[1] + dt * ve), heading_rad=psi,
            u_mps=c * vn + s * ve, v_mps=-s * vn + c * ve, r_radps=self.r, source=self.source,
            std=(pos_std, pos_std,
                 math.sqrt(self.yaw.P), math.sqrt(Pv[0, 0]), math.sqrt(Pv[1, 1]),
                 math.sqrt(self.config.yaw.Q_rate)),
            gyro_bias_radps=self.config.yaw.gyro_bias_radps)

    def reset_integrity(self, t: float, sensor: str | None = None) -> None:
        """Operator: forget a declared inconsistency and let the gates re-anchor again."""
        self.monitor.reset(t, sensor)

    def health(self, t: float | None = None) -> EstimatorHealth:
        """Integrity of the estimate (the same contract as ModelAidedEKF.health, docs/fusion.md)."""
        t = float(t) if t is not None else (self.t if math.isfinite(self.t) else 0.0)
        mon, c = self.monitor, self.config.integrity
        e = self.estimate(t)
        state_finite = all(math.isfinite(v) for v in e.as_array_tuple() + e.std)
        faults = mon.faults(t, self.t if math.isfinite(self.t) else None, state_finite)
        codes = {code for code, _ in faults}
        common = bool(codes & {"fusion.non_finite", "fusion.starved", "fusion.stalled"})
        pos_std, hdg_std, vel_std = max(e.std[0], e.std[1]), e.std[2], max(e.std[3], e.std[4])
        position_ok = not common and "gnss.inconsistent" not in codes and pos_std <= c.max_position_std_m
        heading_ok = (not common and "heading.frozen" not in codes and hdg_std <= c.max_heading_std_rad
                      and not mon.faulty("gyro"))  # as the EKF: no heading without a healthy gyro
        velocity_ok = not common and vel_std <= c.max_velocity_std_mps
        figures = [mon.window_figures(s, t) for s in mon.sensors]
        return EstimatorHealth(
            stamp_s=t, position_ok=position_ok, heading_ok=heading_ok, velocity_ok=velocity_ok,
            faults=tuple(text for _, text in faults), fault_codes=tuple(code for code, _ in faults),
            source=self.source, sensors=mon.sensors, nis=tuple(f[0] for f in figures),
            used_frac=tuple(f[1] for f in figures),
            last_used_age_s=tuple(t - mon.last_used.get(s, -math.inf) for s in mon.sensors),
            filter_age_s=t - self.t, position_std_m=pos_std, heading_std_rad=hdg_std, velocity_std_mps=vel_std,
            event_count=mon.event_count, events=tuple(mon.events))
