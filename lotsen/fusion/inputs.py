"""The model input of the EKF's prediction: achieved actuator values where measured, an emulation
of the actuators from the set-points where not.

Two sources reach the estimator:
- set-points (`ThrustCommand` on ship_command), exact and without lag, but they say what was
  asked, not what happened (ESCs still arming, a failed motor, a servo at its stop);
- achieved values (`ActuatorState` from the simulated boat or the drivers: servo angles and
  measured propeller speeds; `RpmSample` from the tachometers). On the boat the speeds are
  counted tachometer edges: 20 Hz, quantised to 20 Hz / 6 pulses = 3.3 rev/s, plus jitter.

How they are combined (per unit):
- **Servo angles**: the angles of a fresh `ActuatorState` (younger than `actuator_timeout_s`) as
  they are; otherwise the set-point passed through the servo's slew-rate limit.
- **Propeller speeds**: n_hat = n_model + d. n_model is the set-point passed through the ESC +
  motor model of `ActuatorLimits` (first-order lag, ramp limit, speed limits; zero while the
  ESCs report that they are not armed). d is the offset between the measured and the modelled
  speed, a random walk estimated by a scalar Kalman filter from every measured speed
  (R = quantisation + jitter). A measurement further than `offset_jump_sigma` standard
  deviations from n_hat is not noise but an ESC that does not follow (arming, failure, a
  stalled propeller): that unit then runs on its measured speeds alone (held between samples)
  until `agree_samples` measurements in a row agree with the model again. Without a fresh
  set-point the measurement is the model. Without measurements for `speed_timeout_s`, d decays
  to zero over `offset_decay_s` (the set-points are then all there is).

So a quantised tachometer does not put its steps into the thrust (n_model carries the
feed-forward, d averages the measurements), while an ESC that stays at neutral when the
set-points say "thrust" is followed from the first measurement that shows it. Everything is pure: time
advances only through `advance(dt)`, called by the filter's prediction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.model.actuators import advance_motors, slew_servos

NEUTRAL = (0.0, 0.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class InputConfig:
    limits: ActuatorLimits = DEFAULT_LIMITS
    actuator_timeout_s: float = 0.25  # ActuatorState angles younger than this are used as they are
    command_timeout_s: float = 1.0  # an older set-point no longer drives the motor model (held)
    # tachometer: uniform quantisation of 3.3 rev/s (std 0.96) plus 0.2 rev/s jitter, rounded up
    speed_meas_std_rps: float = 1.1
    offset_walk_rps_sqrt_s: float = 1.5  # how fast measured-minus-modelled speed may change
    offset_jump_sigma: float = 5.0  # further off than this: the ESC does not follow the model
    agree_samples: int = 5  # measurements in a row that agree with the model again end that
    speed_timeout_s: float = 0.5  # no speed measurement for this long: the offset decays ...
    offset_decay_s: float = 2.0  # ... to zero with this time constant


class ActuatorInputFilter:
    """Achieved actuator values for the prediction: angles, then speeds n_model + d (see module)."""

    __slots__ = ("config", "t", "cmd", "t_cmd", "alpha", "act_alpha", "t_act", "n_model", "d", "p",
                 "t_meas", "armed", "n_last", "direct", "agree")

    def __init__(self, config: InputConfig = InputConfig()) -> None:
        self.config = config
        self.t: float | None = None  # time of the emulation state
        self.cmd: tuple[float, ...] | None = None  # clipped set-point
        self.t_cmd = -math.inf
        self.alpha = [0.0, 0.0]  # emulated servo angles
        self.act_alpha: tuple[float, float] | None = None
        self.t_act = -math.inf
        self.n_model = [0.0, 0.0, 0.0]
        self.d = [0.0, 0.0, 0.0]
        self.p = [config.speed_meas_std_rps ** 2] * 3
        self.t_meas = -math.inf
        self.armed = True
        self.n_last = [0.0, 0.0, 0.0]  # last measured speeds
        self.direct = [False, False, False]  # per motor: the ESC does not follow, use the measurement
        self.agree = [0, 0, 0]

    def copy(self) -> "ActuatorInputFilter":
        c = ActuatorInputFilter.__new__(ActuatorInputFilter)
        for k in self.__slots__:
            v = getattr(self, k)
            setattr(c, k, list(v) if isinstance(v, list) else v)
        return c

    # -- inputs --------------------------------------------------------------------------------
    def set_command(self, stamp_s: float, u: tuple[float, ...]) -> None:
        self.cmd = tuple(float(v) for v in self.config.limits.clip(*u))
        self.t_cmd = stamp_s

    def set_angles(self, stamp_s: float, alpha1: float, alpha2: float) -> None:
        self.act_alpha = (alpha1, alpha2)
        self.t_act = stamp_s
        self.alpha = [alpha1, alpha2]

    def set_armed(self, armed: bool) -> None:
        self.armed = bool(armed)
        if not self.armed:
            self.n_model = [0.0, 0.0, 0.0]
            self.d = [0.0, 0.0, 0.0]

    def measure_speeds(self, stamp_s: float, n: tuple[float, float, float]) -> None:
        """Fuse measured propeller speeds (rev/s, signed) into the offsets d (see the module)."""
        c = self.config
        R = c.speed_meas_std_rps ** 2
        fresh_cmd = self.cmd is not None and stamp_s - self.t_cmd <= c.command_timeout_s
        jump = c.offset_jump_sigma
        for i in range(3):
            z = float(n[i])
            self.n_last[i] = z
            if not fresh_cmd:
                # no set-point to model from: the measurement is the model (held between samples)
                self.n_model[i], self.d[i], self.p[i], self.direct[i] = z, 0.0, R, False
                continue
            if self.direct[i]:
                # the ESC did not follow: measured values only, until they agree with the model again
                if abs(z - self.n_model[i]) <= jump * math.sqrt(R):
                    self.agree[i] += 1
                    if self.agree[i] >= c.agree_samples:
                        self.direct[i], self.d[i], self.p[i] = False, 0.0, R
                else:
                    self.agree[i] = 0
                continue
            y = z - (self.n_model[i] + self.d[i])
            S = self.p[i] + R
            if abs(y) > jump * math.sqrt(S):
                self.direct[i], self.agree[i] = True, 0  # not noise: an ESC that does not follow
                continue
            K = self.p[i] / S
            self.d[i] += K * y
            self.p[i] *= 1.0 - K
        self.t_meas = stamp_s

    # -- time ----------------------------------------------------------------------------------
    def advance(self, t_end: float, dt: float) -> tuple[float, float, float, float, float]:
        """Advance the emulation by dt to t_end (the filter's clock); returns the input to hold
        over this interval (the mean of its values at the start and the end of the interval)."""
        u0 = self.value()
        self.t = t = t_end
        if dt <= 0.0:
            return u0
        c, lim = self.config, self.config.limits
        cmd = self.cmd
        fresh_cmd = cmd is not None and t - self.t_cmd <= c.command_timeout_s
        if self.act_alpha is not None and t - self.t_act <= c.actuator_timeout_s:
            self.alpha = list(self.act_alpha)
        elif fresh_cmd:
            self.alpha = list(slew_servos(self.alpha, cmd[:2], dt, lim))
        if not self.armed:
            targets = [0.0, 0.0, 0.0]
        elif fresh_cmd:
            targets = list(cmd[2:5])
        else:
            targets = list(self.n_model)
        self.n_model = list(advance_motors(self.n_model, targets, dt, lim))
        for i in range(3):
            self.p[i] += c.offset_walk_rps_sqrt_s ** 2 * dt
            if t - self.t_meas > c.speed_timeout_s:
                self.d[i] *= math.exp(-dt / c.offset_decay_s)
                self.direct[i] = False  # no measurement to follow: the set-points are all there is
        u1 = self.value()
        return tuple(0.5 * (a + b) for a, b in zip(u0, u1))  # type: ignore[return-value]

    def value(self) -> tuple[float, float, float, float, float]:
        if not self.armed:
            return (self.alpha[0], self.alpha[1], 0.0, 0.0, 0.0)
        n = [self.n_last[i] if self.direct[i] else self.n_model[i] + self.d[i] for i in range(3)]
        return (self.alpha[0], self.alpha[1], n[0], n[1], n[2])
