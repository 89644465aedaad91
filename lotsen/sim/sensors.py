"""Sensor models of the simulated boat: IMU (gyro, accelerometer, magnetometer with hard- and
soft-iron distortion), RTK GNSS with degradation and dropouts, tachometers, battery.

All randomness comes from numpy Generators seeded by the simulator; each sensor has its own
stream, so turning one sensor on or off does not change another's noise. Noise is drawn in
blocks (one generator call per 512 samples) because per-sample draws dominate the run time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterator, Sequence

import numpy as np

from lotsen.messages import GnssFix, GnssFixType, ImuSample, MagSample, RpmSample
from lotsen.model.environment import GRAVITY_MPS2
from lotsen.model.geodetic import LocalFrame


class NoiseBlock:
    """Standard normal numbers handed out in rows (`next()`), drawn in blocks of `rows`."""

    def __init__(self, rng: np.random.Generator, width: int, rows: int = 512) -> None:
        self.rng, self.width, self.rows = rng, width, rows
        # a generator's __next__ is the cheapest call Python has, and Python floats index ten
        # times faster than numpy scalars in the per-sample code
        self.next = self._rows().__next__

    def _rows(self) -> Iterator[list[float]]:
        while True:
            yield from self.rng.standard_normal((self.rows, self.width)).tolist()


@dataclass(frozen=True)
class ImuConfig:
    rate_hz: float = 100.0
    gyro_noise_radps: float = 0.003  # MPU9250 ~0.01 deg/s/sqrt(Hz) at 100 Hz -> ~0.17 deg/s
    gyro_bias_radps: float = 0.01  # constant z bias of the run (about 0.6 deg/s)
    gyro_bias_walk_radps_sqrt_s: float = 0.0002
    accel_noise_mps2: float = 0.04
    accel_bias_mps2: tuple[float, float] = (0.05, -0.03)
    mag_rate_hz: float = 50.0
    mag_noise_uT: float = 0.3
    earth_field_horizontal_uT: float = 15.5  # southern Sweden: ~50 uT total, 72 deg inclination
    earth_field_down_uT: float = 47.0
    declination_rad: float = 0.0
    hard_iron_uT: tuple[float, float] = (8.0, -5.0)
    # soft iron: symmetric matrix mapping the true horizontal field to the measured one
    soft_iron: tuple[tuple[float, float], tuple[float, float]] = ((1.08, 0.06), (0.06, 0.93))


@dataclass(frozen=True)
class GnssConfig:
    rate_hz: float = 8.0
    origin_lat_deg: float = 57.6905  # a lake near Gothenburg; any origin works
    origin_lon_deg: float = 11.9760
    origin_height_m: float = 10.0
    # horizontal 1-sigma noise per fix type, plus a slowly wandering bias for non-RTK fixes
    noise_m: dict = field(default_factory=lambda: {
        GnssFixType.RTK_FIXED: 0.01, GnssFixType.RTK_FLOAT: 0.15, GnssFixType.FIX_3D: 1.0})
    bias_walk_m_sqrt_s: dict = field(default_factory=lambda: {
        GnssFixType.RTK_FIXED: 0.0, GnssFixType.RTK_FLOAT: 0.02, GnssFixType.FIX_3D: 0.1})
    velocity_noise_mps: float = 0.02
    dropout_probability: float = 0.0  # each fix independently lost
    latency_s: float = 0.0


@dataclass(frozen=True)
class TachometerConfig:
    rate_hz: float = 20.0
    pulses_per_rev: int = 6
    noise_rps: float = 0.2


class ImuModel:
    """Specific force and rate in the body frame (x fwd, y stbd, z down): of a level boat, or, given
    the plant's motion out of the plane (`motion`: roll and pitch rates, the specific force with
    gravity), of the rolling, pitching hull."""

    def __init__(self, config: ImuConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.rng = rng
        self._noise = NoiseBlock(rng, 7)
        self.gyro_bias_radps = config.gyro_bias_radps
        self.spike_probability = 0.0  # fault injection: occasional large spikes
        self.spike_size = 5.0
        self.stuck = False  # fault injection: the chip repeats its last sample (a hung I2C read)
        # fault injection: offsets that appear at once (a shock, a thermal step): gyro z (rad/s), accel x, y (m/s^2)
        self.bias_step = (0.0, 0.0, 0.0)
        self._last: ImuSample | None = None
        self._k = (config.gyro_noise_radps, config.accel_noise_mps2, config.gyro_bias_walk_radps_sqrt_s,
                   config.accel_bias_mps2[0], config.accel_bias_mps2[1])

    def sample(self, t: float, x: Sequence[float], x_dot: Sequence[float], dt_since_last: float,
               motion: Any = None) -> ImuSample:
        """From the state x = [N, E, psi, u, v, r] and its derivative at time t (and the motion out
        of the plane, a `lotsen.sim.waves.BodyMotion`, where the plant has it)."""
        gn, an, walk, bx, by = self._k
        u, v, r = x[3], x[4], x[5]
        w = self._noise.next()
        bias = self.gyro_bias_radps + walk * math.sqrt(dt_since_last) * w[6]
        self.gyro_bias_radps = bias
        if motion is not None:
            f = motion.specific_force_mps2
            gx, gy, fx, fy, fz = motion.p_radps, motion.q_radps, f[0], f[1], f[2]
            if math.isfinite(motion.r_radps):  # the body z rate of a rolling, pitching hull
                r = motion.r_radps
        else:  # a level boat: the acceleration of the body origin, nu_dot + omega x velocity
            gx = gy = 0.0
            fx, fy, fz = x_dot[3] - v * r, x_dot[4] + u * r, -GRAVITY_MPS2
        gz = r + bias + self.bias_step[0] + gn * w[2]
        accel_x = fx + bx + self.bias_step[1] + an * w[3]
        if self.spike_probability and self.rng.random() < self.spike_probability:
            gz += self.spike_size * (1.0 if w[0] > 0 else -1.0)
            accel_x += 10.0 * self.spike_size
        if self.stuck and self._last is not None:
            return ImuSample(stamp_s=t, gyro_radps=self._last.gyro_radps, accel_mps2=self._last.accel_mps2)
        self._last = ImuSample(stamp_s=t, gyro_radps=(gx + gn * w[0], gy + gn * w[1], gz),
                               accel_mps2=(accel_x, fy + by + self.bias_step[2] + an * w[4], fz + an * w[5]))
        return self._last


class MagnetometerModel:
    """Earth field rotated into the body frame, then distorted: m = S h + b + noise (2D)."""

    def __init__(self, config: ImuConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._noise = NoiseBlock(rng, 3)
        self.disturbance_uT = (0.0, 0.0)  # fault injection: e.g. motor currents, a steel hull nearby
        self.stuck = False  # fault injection: the magnetometer repeats its last sample
        self._last: MagSample | None = None

    def true_horizontal(self, psi: float) -> tuple[float, float]:
        c = self.config
        H = c.earth_field_horizontal_uT
        a = psi - c.declination_rad
        return (H * math.cos(a), -H * math.sin(a))

    def sample(self, t: float, psi: float) -> MagSample:
        c = self.config
        H, a = c.earth_field_horizontal_uT, psi - c.declination_rad
        hx, hy = H * math.cos(a), -H * math.sin(a)
        (s00, s01), (s10, s11) = c.soft_iron
        bx, by = c.hard_iron_uT
        dx, dy = self.disturbance_uT
        w = self._noise.next()
        sd = c.mag_noise_uT
        if self.stuck and self._last is not None:
            return MagSample(stamp_s=t, field_uT=self._last.field_uT)
        self._last = MagSample(stamp_s=t, field_uT=(s00 * hx + s01 * hy + bx + dx + sd * w[0],
                                                    s10 * hx + s11 * hy + by + dy + sd * w[1],
                                                    c.earth_field_down_uT + sd * w[2]))
        return self._last


class GnssModel:
    """RTK GNSS fixes at the antenna (at the body origin), with fix-type dependent noise.

    Latitude, longitude and height come from the local NED position through the one geodetic
    frame (`lotsen.model.geodetic.LocalFrame`, exact WGS84), the frame the estimator places the
    fixes in again: no flat-Earth error between the simulated receiver and the estimator.
    """

    def __init__(self, config: GnssConfig, rng: np.random.Generator) -> None:
        self.config = config
        self.rng = rng
        self._noise = NoiseBlock(rng, 6)
        self.fix_type = GnssFixType.RTK_FIXED
        self.outage = False  # fault injection: no fixes at all
        self.offset_ne_m = (0.0, 0.0)  # fault injection: a wrong position (multipath, a wrong RTK fix)
        self._bias = [0.0, 0.0]
        self.frame = LocalFrame(config.origin_lat_deg, config.origin_lon_deg, config.origin_height_m)

    def sample(self, t: float, north: float, east: float, vel_n: float, vel_e: float,
               dt_since_last: float) -> GnssFix | None:
        c = self.config
        if self.outage or (c.dropout_probability and self.rng.random() < c.dropout_probability):
            return None
        w = self._noise.next()
        ft = self.fix_type
        if ft == GnssFixType.NO_FIX:
            return GnssFix(stamp_s=t, lat_deg=float("nan"), lon_deg=float("nan"), height_m=float("nan"),
                           fix_type=ft, h_acc_m=float("inf"), num_sv=3)
        sigma = c.noise_m.get(ft, 2.0)
        walk = c.bias_walk_m_sqrt_s.get(ft, 0.2) * math.sqrt(dt_since_last)
        self._bias[0] += walk * w[2]
        self._bias[1] += walk * w[3]
        n = north + self._bias[0] + sigma * w[0] + self.offset_ne_m[0]
        e = east + self._bias[1] + sigma * w[1] + self.offset_ne_m[1]
        lat, lon, h = self.frame.to_geodetic(n, e)
        return GnssFix(
            stamp_s=t,
            lat_deg=lat,
            lon_deg=lon,
            height_m=h + 2.0 * sigma * w[4],
            fix_type=ft, h_acc_m=1.4 * sigma, v_acc_m=2.0 * sigma,
            vel_n_mps=vel_n + c.velocity_noise_mps * w[5], vel_e_mps=vel_e + c.velocity_noise_mps * w[4],
            num_sv=24, correction_age_s=1.0 if ft >= GnssFixType.RTK_FLOAT else float("nan"),
        )

    def set_fix_type(self, fix_type: GnssFixType) -> None:
        if fix_type >= GnssFixType.RTK_FLOAT > self.fix_type or fix_type < GnssFixType.RTK_FLOAT:
            self._bias = [0.0, 0.0]
        self.fix_type = fix_type


class TachometerModel:
    """Propeller speed from edge counts over the sample window (quantised) plus jitter noise."""

    def __init__(self, config: TachometerConfig, rng: np.random.Generator) -> None:
        self.config = config
        self._noise = NoiseBlock(rng, 3)
        self._quantum = config.rate_hz / config.pulses_per_rev  # one pulse per window, in rev/s

    def sample(self, t: float, n: tuple[float, float, float]) -> RpmSample:
        w = self._noise.next()
        q, s = self._quantum, self.config.noise_rps
        vals = [round((n[i] + s * w[i]) / q) * q for i in range(3)]
        return RpmSample(stamp_s=t, n1_rps=vals[0], n2_rps=vals[1], nt_rps=vals[2])
