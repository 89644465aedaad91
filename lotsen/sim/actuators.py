"""Actuator dynamics of the simulated boat: steering servos and ESC + motor speed loops.

Servo: angle limited to +-alpha_max and slewing at most alpha_rate_max (a hobby servo is a
rate-limited position loop). Motor: first-order speed response n_dot = (n_cmd - n) / T_m,
integrated exactly over a step, with a ramp limit and the speed limits. Faults: a unit can be
failed (propeller speed goes to 0 and stays) or its servo stuck.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lotsen.model._jit import njit
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits


def _actuator_step_py(state, command, active, max_dalpha, motor_gain, max_dn):  # type: ignore[no-untyped-def]
    """One step of servo slew (rate limit) and first-order motor response (exact for a held set-point).

    `active` = (servo1, servo2, motor1, motor2, motor_bow) as 1.0/0.0: a stuck servo keeps its
    angle, a failed motor spins down to zero.
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


def _motor_steps_py(n1, n2, nt, c1, c2, ct, steps, motor_gain, max_dn):  # type: ignore[no-untyped-def]
    st = (0.0, 0.0, n1, n2, nt)
    for _ in range(steps):
        st = actuator_step(st, (0.0, 0.0, c1, c2, ct), (0.0, 0.0, 1.0, 1.0, 1.0), 0.0, motor_gain, max_dn)
    return st[2], st[3], st[4]


_motor_steps = njit(_motor_steps_py)


def advance_motors(n: tuple[float, ...] | list[float] | np.ndarray, command_n: tuple[float, ...] | list[float] | np.ndarray,
                   dt_s: float, limits: ActuatorLimits = DEFAULT_LIMITS, steps: int = 1) -> tuple[float, float, float]:
    """Propeller speeds (n1, n2, nt; rev/s) `dt_s` after `n` under the held set-points `command_n`:
    the motor model of `ActuatorDynamics` (first-order response, ramp limit) in `steps` equal steps.
    The one place the controllers, monitors and estimators model what the ESCs did with the commands;
    scalar arguments, so one compiled signature serves every caller."""
    h = dt_s / steps
    return _motor_steps(float(n[0]), float(n[1]), float(n[2]), float(command_n[0]), float(command_n[1]),
                        float(command_n[2]), int(steps), 1.0 - math.exp(-h / limits.motor_time_constant_s),
                        limits.n_rate_max_rps2 * h)


@dataclass
class ActuatorFaults:
    failed_units: set[int] = field(default_factory=set)  # 0 = azimuth 1, 1 = azimuth 2, 2 = bow
    stuck_servos: set[int] = field(default_factory=set)  # 0 or 1


class ActuatorDynamics:
    """State [alpha1, alpha2, n1, n2, nt] following commanded set-points."""

    def __init__(self, limits: ActuatorLimits = DEFAULT_LIMITS, dt_s: float = 0.01) -> None:
        self.limits = limits
        self.dt_s = dt_s
        self.state: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
        self.command: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
        self.faults = ActuatorFaults()
        self._active = (1.0, 1.0, 1.0, 1.0, 1.0)
        # the same two vectors as float arrays, for the simulator's compiled step
        self.command_array = np.zeros(5)
        self.active_array = np.ones(5)
        self._motor_gain = 1.0 - math.exp(-dt_s / limits.motor_time_constant_s)
        self._max_dalpha = limits.alpha_rate_max_radps * dt_s
        self._max_dn = limits.n_rate_max_rps2 * dt_s

    def set_command(self, alpha1: float, alpha2: float, n1: float, n2: float, nt: float) -> None:
        """Store a set-point; non-finite values are replaced by neutral (the driver would do the same)."""
        values = (alpha1, alpha2, n1, n2, nt)
        if not all(math.isfinite(v) for v in values):
            values = (0.0, 0.0, 0.0, 0.0, 0.0)
        self.command = tuple(float(v) for v in self.limits.clip(*values))
        self.command_array[:] = self.command

    def set_faults(self, failed_units: set[int] = frozenset(), stuck_servos: set[int] = frozenset()) -> None:
        """Fail motors (0 = azimuth 1, 1 = azimuth 2, 2 = bow) or freeze servos (0, 1)."""
        self.faults = ActuatorFaults(set(failed_units), set(stuck_servos))
        self._active = tuple(0.0 if (i in stuck_servos) else 1.0 for i in (0, 1)) + tuple(
            0.0 if (i in failed_units) else 1.0 for i in (0, 1, 2))
        self.active_array[:] = self._active

    def step(self) -> tuple[float, ...]:
        self.state = actuator_step(self.state, self.command, self._active, self._max_dalpha,
                                   self._motor_gain, self._max_dn)
        return self.state
