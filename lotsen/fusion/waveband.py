"""How much the sea moves the hull, from the IMU, within seconds: the intensities and the frequency the
estimator's wave states are given (lotsen.fusion.ekf, docs/fusion.md "Waves").

Only motions that waves excite and manoeuvres hardly do are used: the heave acceleration (the
accelerometer's z axis, gravity removed) and the roll and pitch rates (the gyro's x and y axes). A
crash stop or a turn changes the horizontal accelerations and the yaw rate in the same band as
waves do (the first version of this module used them, and the wave states then took 22 cm of a
crash stop's motion for waves); it hardly heaves, rolls or pitches the hull at wave frequency.

Each signal passes a second-order band-pass (RBJ biquad, `band_hz` = 0.3-3 Hz: the wave band of a
1 m hull on a lake, encounter frequencies included) and an exponential average of its square with
time constant `time_constant_s`; the heave acceleration also through a leaky integration to the
heave velocity. From these:

- heave: its acceleration's standard deviation a_z (m/s^2) and the displacement's, a_z / w^2;
- tilt: the roll and pitch angles' combined standard deviation, from the rates, / w (rad);
- the frequency w (rad/s): sqrt(E[a_z^2] / E[v_z^2]), the mean frequency of the heave velocity's
  spectrum (close to the peak of the encounter spectrum for a wind sea).

The band's own noise floor (the sensors' white noise through the band-pass) is subtracted, so flat
water reads ~0. Pure: time only from the sample stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lotsen.model.environment import GRAVITY_MPS2


@dataclass(frozen=True)
class WaveBandConfig:
    band_hz: tuple[float, float] = (0.3, 3.0)
    time_constant_s: float = 8.0
    # white noise per sample the band lets through (subtracted from the variances; the simulator's
    # MPU9250: 0.003 rad/s, 0.04 m/s^2)
    gyro_noise_radps: float = 0.003
    accel_noise_mps2: float = 0.04
    leak_time_constant_s: float = 3.0  # of the heave velocity's integration (below the band)
    max_gap_s: float = 0.5


class BandPass:
    """Second-order band-pass (RBJ cookbook, constant 0 dB peak gain) at centre sqrt(f1 f2)."""

    __slots__ = ("b0", "b2", "a1", "a2", "x1", "x2", "y1", "y2")

    def __init__(self, f1_hz: float, f2_hz: float, rate_hz: float) -> None:
        f0 = math.sqrt(f1_hz * f2_hz)
        q = f0 / (f2_hz - f1_hz)
        w0 = 2.0 * math.pi * min(f0 / rate_hz, 0.45)
        alpha = math.sin(w0) / (2.0 * q)
        a0 = 1.0 + alpha
        self.b0, self.b2 = alpha / a0, -alpha / a0
        self.a1, self.a2 = -2.0 * math.cos(w0) / a0, (1.0 - alpha) / a0
        self.x1 = self.x2 = self.y1 = self.y2 = 0.0

    def __call__(self, x: float) -> float:
        y = self.b0 * x + self.b2 * self.x2 - self.a1 * self.y1 - self.a2 * self.y2
        self.x2, self.x1 = self.x1, x
        self.y2, self.y1 = self.y1, y
        return y


class WaveBand:
    """Wave-band statistics of heave, roll and pitch (module docstring)."""

    def __init__(self, config: WaveBandConfig = WaveBandConfig()) -> None:
        self.config = config
        self._t: float | None = None
        self._filters: list[BandPass] | None = None
        self._rate_hz = 0.0
        self._v = 0.0  # heave velocity (band-passed acceleration, leaky-integrated)
        self._sq = [0.0, 0.0, 0.0, 0.0]  # E[x^2]: heave acceleration, roll rate, pitch rate, heave velocity
        self._weight = 0.0  # how much of the average is data (the figures are scaled by it)

    def update(self, t: float, gyro_radps: tuple[float, float, float], accel_z_mps2: float) -> None:
        """One IMU sample: the body rates (p, q, r) and the accelerometer's z axis."""
        if not all(math.isfinite(v) for v in (t, gyro_radps[0], gyro_radps[1], accel_z_mps2)):
            return
        prev, self._t = self._t, t
        if prev is None:
            return
        dt = t - prev
        if not 0.0 < dt <= self.config.max_gap_s:
            return
        if self._filters is None:  # designed for the first interval's rate (the IMU's rate is fixed)
            self._rate_hz = 1.0 / dt
            f1, f2 = self.config.band_hz
            self._filters = [BandPass(f1, f2, self._rate_hz) for _ in range(3)]
        c = self.config
        a = dt / c.time_constant_s
        self._weight += a * (1.0 - self._weight)
        az = self._filters[0](accel_z_mps2 + GRAVITY_MPS2)
        self._v = (self._v + az * dt) * (1.0 - dt / c.leak_time_constant_s)
        for i, y in enumerate((az, self._filters[1](gyro_radps[0]), self._filters[2](gyro_radps[1]), self._v)):
            self._sq[i] += a * (y * y - self._sq[i])

    def _noise_var(self, sensor_std: float) -> float:
        """The band-passed variance of white noise of `sensor_std` per sample (the band's noise
        bandwidth, pi/2 times its width, over the Nyquist band)."""
        if not self._rate_hz:
            return 0.0
        f1, f2 = self.config.band_hz
        return sensor_std ** 2 * (f2 - f1) * (math.pi / 2.0) / (0.5 * self._rate_hz)

    def _var(self, i: int, noise: float) -> float:
        return max(self._sq[i] / self._weight - noise, 0.0) if self._weight > 0.0 else 0.0

    @property
    def ready(self) -> bool:
        """The averages hold at least one time constant of data."""
        return self._weight > 0.63

    @property
    def heave_accel_std_mps2(self) -> float:
        return math.sqrt(self._var(0, self._noise_var(self.config.accel_noise_mps2)))

    @property
    def frequency_radps(self) -> float:
        """The heave's mean frequency (NaN while the heave is within the accelerometer's noise)."""
        noise = self._noise_var(self.config.accel_noise_mps2)
        if self._weight <= 0.0 or self._sq[0] / self._weight < 4.0 * noise or self._sq[3] <= 0.0:
            return math.nan
        return math.sqrt(self._var(0, noise) / (self._sq[3] / self._weight))

    def heave_std_m(self, w_radps: float) -> float:
        """The heave displacement's standard deviation at wave frequency `w_radps`."""
        return self.heave_accel_std_mps2 / (w_radps * w_radps)

    def tilt_std_rad(self, w_radps: float) -> float:
        """Roll and pitch angles' combined standard deviation at wave frequency `w_radps`."""
        noise = self._noise_var(self.config.gyro_noise_radps)
        return math.sqrt(self._var(1, noise) + self._var(2, noise)) / w_radps
