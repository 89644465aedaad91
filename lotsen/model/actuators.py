"""Actuator dynamics of the vessel model: steering servos and ESC + motor speed loops.

Servo: the angle follows its set-point, limited to +-alpha_max and slewing at most
alpha_rate_max (a hobby servo is a rate-limited position loop). Motor: first-order speed
response n_dot = (n_cmd - n) / T_m, integrated exactly over a step for a held set-point, with
the ESC's ramp limit. The parameters are the named fields of `ActuatorLimits`.

One model for every user: the simulated boat (with its own `ActuatorLimits`, and effects this
model does not have), the MPC's prediction of the achieved thrust, the EKF's input filter and
the thruster monitor.
"""

from __future__ import annotations

import math
from typing import Sequence

from lotsen.model._jit import njit
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits


def _actuator_step_py(state, command, active, max_dalpha, motor_gain, max_dn):  # type: ignore[no-untyped-def]
    """One step of servo slew (rate limit) and first-order motor response (exact for a held set-point).

    `active` = (servo1, servo2, motor1, motor2, motor_bow) as 1.0/0.0: a stuck servo keeps its
    angle, a failed motor spins down to zero. `max_dalpha` = alpha_rate_max dt,
    `motor_gain` = 1 - exp(-dt / T_m), `max_dn` = n_rate_max dt.
    """
    a1 = state[0]
    a2 = state[1]
    if active[0] > 0.0:
        a1 += min(max(command[0] - a1, -max_dalpha), max_dalpha)
    if active[1] > 0.0:
        a2 += min(max(command[1] - a2, -max_dalpha), max_dalpha)
    n1 = state[2] + min(max(motor_gain * (command[2] * active[2] - state[2]), -max_dn), max_dn)
    n2 = state[3] + min(max(motor_gain * (command[3] * active[3] - state[3]), -max_dn), max_dn)
    nt = state[4] + min(max(motor_gain * (command[4] * active[4] - state[4]), -max_dn), max_dn)
    return (a1, a2, n1, n2, nt)


actuator_step = njit(_actuator_step_py)


def step_gains(limits: ActuatorLimits, dt_s: float) -> tuple[float, float, float]:
    """(max_dalpha, motor_gain, max_dn) of `actuator_step` for a step of dt_s."""
    return (limits.alpha_rate_max_radps * dt_s, 1.0 - math.exp(-dt_s / limits.motor_time_constant_s),
            limits.n_rate_max_rps2 * dt_s)


def _motor_steps_py(n1, n2, nt, c1, c2, ct, steps, motor_gain, max_dn):  # type: ignore[no-untyped-def]
    st = (0.0, 0.0, n1, n2, nt)
    for _ in range(steps):
        st = actuator_step(st, (0.0, 0.0, c1, c2, ct), (0.0, 0.0, 1.0, 1.0, 1.0), 0.0, motor_gain, max_dn)
    return st[2], st[3], st[4]


_motor_steps = njit(_motor_steps_py)


def advance_motors(n: Sequence[float], command_n: Sequence[float], dt_s: float,
                   limits: ActuatorLimits = DEFAULT_LIMITS, steps: int = 1) -> tuple[float, float, float]:
    """Propeller speeds (n1, n2, nt; rev/s) `dt_s` after `n` under the held set-points `command_n`,
    in `steps` equal steps of `actuator_step`. Scalar arguments, so one compiled signature serves
    every caller."""
    h = dt_s / steps
    _, gain, max_dn = step_gains(limits, h)
    return _motor_steps(float(n[0]), float(n[1]), float(n[2]), float(command_n[0]), float(command_n[1]),
                        float(command_n[2]), int(steps), gain, max_dn)


def slew_servos(alpha: Sequence[float], command_alpha: Sequence[float], dt_s: float,
                limits: ActuatorLimits = DEFAULT_LIMITS) -> tuple[float, float]:
    """Servo angles (rad) `dt_s` after `alpha` under the held set-points: the rate limit of `actuator_step`."""
    da = limits.alpha_rate_max_radps * dt_s
    return (alpha[0] + min(max(command_alpha[0] - alpha[0], -da), da),
            alpha[1] + min(max(command_alpha[1] - alpha[1], -da), da))
