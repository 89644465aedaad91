"""Roll and pitch of the hull from the IMU, so that the accelerometer's gravity share can be taken out.

An accelerometer on a heeled or pitching hull reads gravity on its horizontal axes: g sin(pitch) on
x, -g cos(pitch) sin(roll) on y (0.17 m/s^2 a degree), far more than the accelerations a model-aided
filter compares it with. A boat heels in turns and in wind, and rolls and pitches at wave frequency
by degrees. `TiltFilter` is a complementary filter with gyro-bias estimation (Mahony, Hamel and
Pflimlin 2008, the explicit complementary filter, written for the two tilt angles): the body rates
p, q, r carry roll and pitch through the Euler kinematics (exact at wave frequency, where they move
fastest), and the accelerometer, with the acceleration the navigation filter knows subtracted,
pulls them towards the gravity direction with time constant `time_constant_s`, so the gyro's
offsets and the unknown accelerations average out (a wave-frequency acceleration of 0.5 m/s^2 at
1 Hz moves the estimate by ~0.02 deg at 20 s). An integral term estimates the x and y gyro offsets.
The known acceleration is the GNSS velocity's rate of change where there is one (the navigation
filter's model would turn its own force errors into tilt).

    level_x = f_x - g sin(pitch'),  level_y = f_y + g cos(pitch') sin(roll')

is then the acceleration of the body origin in the plane (u_dot - v r, v_dot + u r), what a level
boat's accelerometer would read (`level`), where roll' and pitch' are the tilt less its slow part
(an exponential average over `slow_time_constant_s`): a constant heel or trim is indistinguishable
from an accelerometer offset, and the navigation filter's offset states hold both (levelling with
the whole tilt made a dead-reckoning crash stop on a level hull drift 1.7 m instead of 0.65 m in
10 s: the tilt filter's slow errors are not better than the offset states'). Heel that changes in
turns and wave-frequency roll and pitch are levelled.

Pure: time only from the sample stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lotsen.model.environment import GRAVITY_MPS2


@dataclass(frozen=True)
class TiltConfig:
    time_constant_s: float = 5.0  # the accelerometer's pull on the tilt
    bias_time_constant_s: float = 100.0  # the gyro offsets' integral
    max_gap_s: float = 0.5  # a longer gap between samples: the tilt is held, not integrated
    max_tilt_rad: float = math.radians(45.0)  # a correction never takes the estimate beyond this
    slow_time_constant_s: float = 60.0  # the slow part of the tilt, left to the accelerometer offset states


class TiltFilter:
    """Roll (starboard down positive) and pitch (bow up positive) of the hull (module docstring)."""

    def __init__(self, config: TiltConfig = TiltConfig()) -> None:
        self.config = config
        self.roll_rad = 0.0
        self.pitch_rad = 0.0
        self.bias_p = 0.0
        self.bias_q = 0.0
        self.slow_roll_rad = 0.0
        self.slow_pitch_rad = 0.0
        self._t: float | None = None
        self._k = 1.0 / config.time_constant_s
        self._ki = self._k / config.bias_time_constant_s

    def update(self, t: float, gyro_radps: tuple[float, float, float], accel_mps2: tuple[float, float, float],
               known_accel_xy: tuple[float, float] = (0.0, 0.0)) -> None:
        """One IMU sample: rates (p, q, r) and specific force (f_x, f_y, f_z) at time t, with the body
        acceleration in the plane the navigation filter expects (u_dot - v r, v_dot + u r)."""
        p, q, r = gyro_radps
        fx, fy, fz = accel_mps2
        if not all(math.isfinite(v) for v in (t, p, q, r, fx, fy, fz)):
            return
        prev, self._t = self._t, t
        if prev is None:  # the first sample: the accelerometer's tilt as it is
            self.roll_rad, self.pitch_rad = self.gravity_tilt(accel_mps2, known_accel_xy)
            self.slow_roll_rad, self.slow_pitch_rad = self.roll_rad, self.pitch_rad
            return
        dt = t - prev
        if not 0.0 < dt <= self.config.max_gap_s:
            return
        roll_g, pitch_g = self.gravity_tilt(accel_mps2, known_accel_xy)
        e_roll, e_pitch = roll_g - self.roll_rad, pitch_g - self.pitch_rad
        self.bias_p -= self._ki * e_roll * dt
        self.bias_q -= self._ki * e_pitch * dt
        ph, th = self.roll_rad, self.pitch_rad
        pc, qc = p - self.bias_p, q - self.bias_q
        # ZYX Euler rates (Fossen 2021, eq. 2.41)
        roll_rate = pc + (qc * math.sin(ph) + r * math.cos(ph)) * math.tan(th)
        pitch_rate = qc * math.cos(ph) - r * math.sin(ph)
        lim = self.config.max_tilt_rad
        self.roll_rad = min(max(ph + (roll_rate + self._k * e_roll) * dt, -lim), lim)
        self.pitch_rad = min(max(th + (pitch_rate + self._k * e_pitch) * dt, -lim), lim)
        a = dt / self.config.slow_time_constant_s
        self.slow_roll_rad += a * (self.roll_rad - self.slow_roll_rad)
        self.slow_pitch_rad += a * (self.pitch_rad - self.slow_pitch_rad)

    @staticmethod
    def gravity_tilt(accel_mps2: tuple[float, float, float], known_accel_xy: tuple[float, float]) -> tuple[float, float]:
        """(roll, pitch) that puts gravity where the accelerometer sees it, once the known
        acceleration is subtracted: f_x - a_x = g sin(pitch), f_y - a_y = -g cos(pitch) sin(roll)."""
        gx = accel_mps2[0] - known_accel_xy[0]
        gy = accel_mps2[1] - known_accel_xy[1]
        gz = accel_mps2[2]
        pitch = math.atan2(gx, math.hypot(gy, gz))
        roll = math.atan2(-gy, -gz)
        return roll, pitch

    def level(self, accel_mps2: tuple[float, float, float]) -> tuple[float, float]:
        """The specific force's horizontal axes without gravity's share of the tilt's moving part
        (the module docstring: the slow part stays, for the navigation filter's offset states)."""
        th, ph = self.pitch_rad, self.roll_rad
        th0, ph0 = self.slow_pitch_rad, self.slow_roll_rad
        return (accel_mps2[0] - GRAVITY_MPS2 * (math.sin(th) - math.sin(th0)),
                accel_mps2[1] + GRAVITY_MPS2 * (math.cos(th) * math.sin(ph) - math.cos(th0) * math.sin(ph0)))
