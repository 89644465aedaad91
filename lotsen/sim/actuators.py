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

from lotsen.model.actuators import actuator_step, step_gains
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits


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
        self._max_dalpha, self._motor_gain, self._max_dn = step_gains(limits, dt_s)

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
