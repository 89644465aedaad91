"""The plant: the boat's body behind the simulator (vessel, actuators, and the water and air it
moves in). `lotsen.sim.Simulator` is a plant plus lotsen's sensor models (IMU, magnetometer,
GNSS, tachometers, battery), which make the sensor messages from what the plant reports.

`Plant` is the public interface; two kinds implement it:

- `BoatPlant`, lotsen's own simulated boat (a `SimulatedBoat`: the boat's equations and actuators,
  its thrust dead band, astern ratio and command latency, and the environment: current, wind with
  gusts, waves);
- an external physics: `lotsen.physics.UdpPhysics` speaks ArduPilot SITL's JSON protocol to any
  physics server (docs/physics.md); a Python plant can implement the interface directly.

A plant is stepped by its caller, `dt_s` at a time. `step()` returns what the sensors sample at the
step's *start*: `PlantSample(x, x_dot, actuators)` with the planar state x = [N, E, psi, u, v, r],
its rate x_dot (x_dot[0:2] the velocity over ground in NED, x_dot[3:5] such that x_dot[3] - v r and
x_dot[4] + u r are the boat's acceleration in the plane: `planar_state` builds both from what a 6-DOF
physics reports), the achieved actuators (alpha1, alpha2, n1, n2, nt) and, where the plant has them,
the motion out of the plane (`BodyMotion`: roll, pitch, heave, their rates and the accelerometer's
specific force with gravity): lotsen's IMU then measures that instead of a level boat's, and the GNSS
antenna swings with the roll and pitch. None means the plant has no fresh state
(an external physics that stopped answering): the simulator then measures nothing, the sensors go
stale and the failsafes act.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections import deque
from typing import Any, NamedTuple, Sequence

import numpy as np

from lotsen.errors import LotsenError
from lotsen.model._jit import njit
from lotsen.model.actuators import actuator_step
from lotsen.model.dynamics import VesselModel, rk4_step
from lotsen.model.environment import GRAVITY_MPS2, Environment, WindCoefficients, wind_force
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.sim.actuators import ActuatorDynamics
from lotsen.sim.boat import DEFAULT_BOAT, SimulatedBoat
from lotsen.sim.waves import LOADS, BodyMotion, Seakeeping, WaveField

#: how many independent random streams a simulator spawns from its seed (sensors 0-3, plant 4-6:
#: the Gauss-Markov force, the gusts, the wave field; spawned children do not depend on the count)
RANDOM_STREAMS = 7


class PlantError(LotsenError):
    """A plant cannot do what was asked (e.g. an external physics owns its environment)."""


class PlantSample(NamedTuple):
    """What the sensors sample at one instant: state, its rate, the achieved actuators, and the
    motion out of the plane where the plant has it (None: a level boat)."""

    x: tuple[float, ...]
    x_dot: tuple[float, ...]
    actuators: tuple[float, ...]
    motion: BodyMotion | None = None


def planar_state(north: float, east: float, psi: float, velocity_ne: Sequence[float], r: float,
                 specific_force_xy: Sequence[float], roll: float = 0.0, pitch: float = 0.0,
                 r_dot: float = 0.0, q: float = 0.0) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(x, x_dot) of the planar state from what a 6-DOF physics reports: position, heading, the
    velocity over ground (NED), the body yaw rate, the accelerometer's specific force (body x, y)
    and the attitude. u, v are the velocity over ground in the heading's axes. lotsen's IMU model
    is level: it reads the accelerometer as x_dot[3] - v r and x_dot[4] + u r (`ImuModel.sample`),
    the boat's acceleration; gravity's share in a heeled or trimmed physics's specific force
    (g sin(pitch) on x, -g cos(pitch) sin(roll) on y: 0.17 m/s^2 a degree) is taken out here, as
    the level model has no tilt. `r` is the body z rate; the planar state's is the heading's rate,
    (q sin(roll) + r cos(roll)) / cos(pitch) with q the body y rate (ZYX Euler kinematics)."""
    r = (q * math.sin(roll) + r * math.cos(roll)) / math.cos(pitch)
    c, s = math.cos(psi), math.sin(psi)
    vn, ve = velocity_ne[0], velocity_ne[1]
    u, v = c * vn + s * ve, -s * vn + c * ve
    ax = specific_force_xy[0] - GRAVITY_MPS2 * math.sin(pitch)
    ay = specific_force_xy[1] + GRAVITY_MPS2 * math.cos(pitch) * math.sin(roll)
    return (north, east, psi, u, v, r), (vn, ve, r, ax + v * r, ay - u * r, r_dot)


class Plant(ABC):
    """The boat's body: takes actuator set-points, steps `dt_s` at a time, reports its state.

    Attributes every plant has: `name`, `dt_s`, `limits` (what its actuators can do: the actuator
    guard clips set-points to them), `gnss_antenna_m` (the antenna on the hull, body x/y, where
    lotsen's receiver model places the fixes) and `gnss_antenna_height_m` (its height above the roll
    and pitch centre: the fixes swing with the hull's roll and pitch), `actuators` (an
    `ActuatorDynamics`: `.state` the achieved values, `.command` the set-point, `.set_faults(...)`)."""

    name: str = "plant"
    dt_s: float = 0.01
    limits: ActuatorLimits = DEFAULT_LIMITS
    gnss_antenna_m: tuple[float, float] = (0.0, 0.0)
    gnss_antenna_height_m: float = 0.0
    actuators: ActuatorDynamics
    # what an implementation keeps up to date as it steps (read through the properties below)
    _x: tuple[float, ...] = (0.0,) * 6
    _x_dot: tuple[float, ...] = (0.0,) * 6
    _step_input: tuple[float, ...] = (0.0,) * 5

    @abstractmethod
    def command(self, u: Sequence[float]) -> None:
        """Actuator set-points [alpha1, alpha2, n1, n2, nt]; clipped to the limits, NaN -> neutral."""

    @abstractmethod
    def step(self) -> PlantSample | None:
        """Advance `dt_s`; return the sample at the step's start (None: no fresh state)."""

    @property
    def x(self) -> tuple[float, ...]:
        """The planar state now [N, E, psi, u, v, r]."""
        return self._x

    @property
    def x_dot(self) -> tuple[float, ...]:
        return self._x_dot

    @property
    def step_input(self) -> tuple[float, ...]:
        """The achieved actuators' mean over the last step (what drove the boat during it)."""
        return self._step_input

    @property
    def fresh(self) -> bool:
        """False while the plant has no fresh state (an external physics that stopped answering)."""
        return True

    @property
    def environment(self) -> Environment | None:
        """The environment lotsen configured for this plant (None: the plant's own business)."""
        return None

    @property
    def wind_now(self) -> tuple[float, float]:
        return (math.nan, math.nan)

    def wave_elevation(self) -> float:
        """The sea surface's elevation at the boat now (m; NaN: the plant's own business or no sea)."""
        return math.nan

    def place(self, x: Sequence[float]) -> None:
        """Put the boat at state x = [N, E, psi, u, v, r] (a start pose)."""
        raise PlantError(f"{self.name}: cannot place the boat")

    def set_environment(self, env: Environment) -> None:
        raise PlantError(f"{self.name}: the current and wind belong to the plant itself; set them there")

    def set_faults(self, failed_units: set[int] = frozenset(), stuck_servos: set[int] = frozenset()) -> None:
        self.actuators.set_faults(failed_units, stuck_servos)

    def run_held(self, n: int) -> tuple[list, list, list] | None:
        """`n` steps with the set-point held in one go, if the plant can do that faster: (x at the
        start of each step and after the last (n + 1), x_dot at each step's start (n), actuators at
        each step's start and after the last (n + 1)). None: step one by one."""
        return None

    def warm_up(self) -> None:
        """Prepare anything slow (compiled kernels) before a live loop starts."""

    def close(self) -> None:
        """Release what the plant holds (sockets)."""

    def status(self) -> dict[str, Any]:
        """Counters and health for reports and logs."""
        return {}

    def describe(self, reference: Any = None) -> str:
        return self.name


# ----------------------------------------------------------------------------------------------
# lotsen's own boat: compiled plant kernels

def _thrusting_py(act, dead_band_rps):  # type: ignore[no-untyped-def]
    """The actuators as the water sees them: a propeller below the dead band makes no thrust."""
    n1 = act[2] if abs(act[2]) >= dead_band_rps else 0.0
    n2 = act[3] if abs(act[3]) >= dead_band_rps else 0.0
    nt = act[4] if abs(act[4]) >= dead_band_rps else 0.0
    return (act[0], act[1], n1, n2, nt)


_thrusting = njit(_thrusting_py)


def _step_mean_py(a, b):  # type: ignore[no-untyped-def]
    """The actuators' mean over a step that starts at `a` and ends at `b` (within a 10 ms step each
    moves almost linearly). The vessel integrates under this mean: the end value would act half
    a step early, and the actuator state, stamped at the step's end, would look 5 ms late to an
    identification that interpolates it (a 1-2 % bias on m33, N_r, mu_t from the time skew alone)."""
    return (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1]), 0.5 * (a[2] + b[2]), 0.5 * (a[3] + b[3]), 0.5 * (a[4] + b[4]))


_step_mean = njit(_step_mean_py)


def _plant_step_py(buf, command, active, mq, c):  # type: ignore[no-untyped-def]
    """Actuators then vessel, one step, in place on `buf` = [x (6), actuators (5), x_dot at start (6)].

    One compiled call per step: passing tuples into numba costs more than the arithmetic, so
    the step's inputs travel as float arrays, the model as `ModelArrays.packed`.
    c = [max_dalpha, motor_gain, max_dn, dt, current_n, current_e, tau_x, tau_y, tau_n, thrust dead band].
    """
    act0 = (buf[6], buf[7], buf[8], buf[9], buf[10])
    act = actuator_step(act0, (command[0], command[1], command[2], command[3], command[4]),
                        (active[0], active[1], active[2], active[3], active[4]), c[0], c[1], c[2])
    x1, k1 = rk4_step((buf[0], buf[1], buf[2], buf[3], buf[4], buf[5]), _thrusting(_step_mean(act0, act), c[9]),
                      mq, c[4], c[5], c[6], c[7], c[8], c[3])
    for i in range(6):
        buf[i] = x1[i]
        buf[11 + i] = k1[i]
    for i in range(5):
        buf[6 + i] = act[i]


_plant_step = njit(_plant_step_py)


def _plant_steps_py(x0, act0, command, active, mq, c, xs, ks, acts):  # type: ignore[no-untyped-def]
    """K = len(ks) steps of `_plant_step` with the set-point held: fills xs (K+1 x 6, xs[0] = x0),
    ks (K x 6, x_dot at the start of each step) and acts (K x 5, actuators during each step)."""
    cmd = (command[0], command[1], command[2], command[3], command[4])
    act_on = (active[0], active[1], active[2], active[3], active[4])
    x = (x0[0], x0[1], x0[2], x0[3], x0[4], x0[5])
    act = (act0[0], act0[1], act0[2], act0[3], act0[4])
    for i in range(6):
        xs[0, i] = x[i]
    for k in range(ks.shape[0]):
        act0 = act
        act = actuator_step(act, cmd, act_on, c[0], c[1], c[2])
        x, k1 = rk4_step(x, _thrusting(_step_mean(act0, act), c[9]), mq, c[4], c[5], c[6], c[7], c[8], c[3])
        for i in range(6):
            xs[k + 1, i] = x[i]
            ks[k, i] = k1[i]
        for i in range(5):
            acts[k, i] = act[i]


_plant_steps = njit(_plant_steps_py)


class BoatPlant(Plant):
    """lotsen's simulated boat as a plant: classical RK4 at `dt_s` under the actuators' mean over the
    step, the boat's actuators (slew, motor lag, dead band, astern ratio, latency) and the
    environment (current in the kinetics; wind with seeded gusts, the Gauss-Markov force and wind
    waves (`lotsen.sim.waves`: first-order loads and mean drift in the plane, heave, roll and pitch for
    the sensors) as forces).

    `boat`: a `SimulatedBoat` (default the lake boat) or a `VesselModel` (with `limits`) for a boat
    equal to that model. `seed` seeds the plant's random streams (gusts, waves) as the simulator
    seeds its own: streams 4-5 of `RANDOM_STREAMS` spawned from the seed, so a plant and a
    simulator on one seed draw the same gusts whether the plant is inside or behind a protocol (and
    the same sea: stream 6)."""

    def __init__(self, boat: SimulatedBoat | VesselModel | None = None, limits: ActuatorLimits | None = None, *,
                 dt_s: float = 0.01, seed: int = 0, environment: Environment = Environment(),
                 wind: WindCoefficients = WindCoefficients(), x0: Sequence[float] | None = None) -> None:
        if boat is None:
            boat = DEFAULT_BOAT
        elif isinstance(boat, VesselModel):
            boat = SimulatedBoat.ideal_for(boat, limits or DEFAULT_LIMITS)
        elif limits is not None and limits != boat.limits:
            raise ValueError("a SimulatedBoat carries its own actuator limits; do not pass `limits` too")
        self.boat = boat
        self.name = boat.name
        self.model = boat.model()  # the boat's own equations, not the controllers' model
        self.limits = boat.limits
        self.gnss_antenna_m = boat.gnss_antenna_m
        self.gnss_antenna_height_m = boat.hull.gnss_antenna_height_m
        self.dt_s = dt_s
        self.seed = seed
        self._wind_coefficients = wind
        self._latency = boat.command_latency_s
        self._pending: deque[tuple[float, tuple[float, ...]]] = deque()  # set-points on their way
        self._k = 0
        self.t = 0.0
        self._x: tuple[float, ...] = tuple(float(v) for v in (x0 if x0 is not None else (0.0,) * 6))
        self._x_dot: tuple[float, ...] = (0.0,) * 6
        self.actuators = ActuatorDynamics(self.limits, dt_s)
        self._step_input: tuple[float, ...] = tuple(self.actuators.state)
        streams = np.random.SeedSequence(seed).spawn(RANDOM_STREAMS)
        self._wave_rng = np.random.Generator(np.random.PCG64(streams[4]))
        self._gust_rng = np.random.Generator(np.random.PCG64(streams[5]))
        self._sea_seed = streams[6]
        self._wave = [0.0, 0.0, 0.0]
        self._gust = [0.0, 0.0]  # wind speed deviation (m/s), direction deviation (deg)
        self._environment = environment
        self._current_ne = self._environment.current_ne
        self._sea: WaveField | None = None
        self._seakeeping = Seakeeping(boat.hull)
        self._loads = np.zeros(len(LOADS))
        self._make_sea(environment)
        self._buf = np.zeros(17)
        self._buf[:6] = self._x
        self._model_arrays = self.model.arrays.packed  # M, D_L, D_NL, thrust, arms for the compiled step
        a = self.actuators
        self._consts = np.array([a._max_dalpha, a._motor_gain, a._max_dn, dt_s, 0.0, 0.0, 0.0, 0.0, 0.0,
                                 boat.thrust_dead_band_rps])

    # -- the Plant interface -------------------------------------------------------------------
    @property
    def environment(self) -> Environment:
        return self._environment

    def place(self, x: Sequence[float]) -> None:
        self._x = tuple(float(v) for v in x)
        self._buf[:6] = self._x

    def override_sample_state(self, x: Sequence[float]) -> None:
        """Until the next step, the state the sensors sample and the wind acts on is x, while the
        integrator goes on from the boat's own state: what `Simulator.x = ...` has always done
        (`run_on_simulator`'s lake records depend on it). Not a way to move the boat: `place()`."""
        self._x = tuple(float(v) for v in x)

    def command(self, u: Sequence[float]) -> None:
        values = tuple(u)
        if self._latency > 0.0:
            self._pending.append((self.t + self._latency, values))
        else:
            self.actuators.set_command(*values)

    def set_environment(self, env: Environment) -> None:
        self._environment = env
        self._current_ne = env.current_ne
        self._make_sea(env)

    def _make_sea(self, env: Environment) -> None:
        """The sea of `env.waves`, realised from the plant's sea stream (the same sea for the same seed)."""
        if env.wavy and (self._sea is None or self._sea.waves != env.waves):
            self._sea = WaveField(env.waves, self.boat.hull, np.random.Generator(np.random.PCG64(self._sea_seed)))
        elif not env.wavy:
            self._sea = None

    @property
    def sea(self) -> WaveField | None:
        """The realised wave field (None: flat water)."""
        return self._sea

    def wave_elevation(self) -> float:
        return self._sea.elevation(self.t, self._x[0], self._x[1]) if self._sea is not None else math.nan

    def motion_now(self, planar_accel_xy: tuple[float, float]) -> BodyMotion | None:
        """The motion out of the plane now (None in flat water: a level boat), given the plane's
        body acceleration now (for a physics server that reports it)."""
        return self._seakeeping.motion(planar_accel_xy, self._x[5]) if self._sea is not None else None

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the plant step now, on a throwaway copy: the first call
        costs 0.3 s or more, which a live control loop must not pay in its first tick."""
        BoatPlant(self.boat, dt_s=self.dt_s, x0=self._x, environment=self._environment).step()

    def describe(self, reference: Any = None) -> str:
        return self.boat.describe(reference) if reference is not None else self.boat.describe()

    def rate_now(self) -> tuple[float, ...]:
        """x_dot at the present state under the present actuators (the last step's current and wind
        force held): what the boat's accelerometer feels now, for a physics server that reports it."""
        c = self._consts
        return tuple(self.model.f(0.0, self._x, _thrusting_py(self.actuators.state, c[9]), (c[4], c[5]),
                                  (c[6], c[7], c[8])).tolist())

    # -- stepping ------------------------------------------------------------------------------
    def _apply_due_commands(self) -> None:
        while self._pending and self._pending[0][0] <= self.t + 1e-9:
            self.actuators.set_command(*self._pending.popleft()[1])

    def _external_force(self) -> tuple[float, float, float]:
        env, x = self._environment, self._x
        tau = [0.0, 0.0, 0.0]
        if env.gusty:
            self._advance_gust(env)
            tau = list(wind_force(x[2], x[3], x[4], env, self._wind_coefficients,
                                  max(0.0, env.wind_speed_mps + self._gust[0]), env.wind_from_deg + self._gust[1]))
        elif env.wind_speed_mps:
            tau = list(wind_force(x[2], x[3], x[4], env, self._wind_coefficients))
        if env.wave_force_std_N:
            # first-order Gauss-Markov force per axis (moment scaled by a quarter length)
            a = math.exp(-self.dt_s / env.wave_period_s)
            b = math.sqrt(1.0 - a * a) * env.wave_force_std_N
            w = self._wave_rng.standard_normal(3)
            self._wave = [a * self._wave[i] + b * w[i] * (0.25 if i == 2 else 1.0) for i in range(3)]
            tau = [tau[i] + self._wave[i] for i in range(3)]
        if self._sea is not None:
            p = self.model.params
            w = self._sea.loads(self.t, x[0], x[1], x[2], p.m11, p.m22, self._loads).tolist()
            tau = [tau[0] + w[0] + w[3], tau[1] + w[1] + w[4], tau[2] + w[2] + w[5]]
        return tau[0], tau[1], tau[2]

    def _advance_gust(self, env: Environment) -> None:
        """One step of the Ornstein-Uhlenbeck gusts: speed with tau = wind_gust_time_constant_s,
        direction with 4 tau (the direction wanders more slowly than the speed gusts)."""
        dt, T = self.dt_s, max(env.wind_gust_time_constant_s, 1e-3)
        w = self._gust_rng.standard_normal(2)
        for i, (tau, std) in enumerate(((T, env.wind_gust_std_mps), (4.0 * T, env.wind_direction_std_deg))):
            a = math.exp(-dt / tau)
            self._gust[i] = a * self._gust[i] + math.sqrt(1.0 - a * a) * std * float(w[i])

    @property
    def wind_now(self) -> tuple[float, float]:
        """The wind acting now: (speed m/s, from deg), gusts included."""
        env = self._environment
        return max(0.0, env.wind_speed_mps + self._gust[0]), env.wind_from_deg + self._gust[1]

    def step(self) -> PlantSample:
        if self._pending:
            self._apply_due_commands()
        c = self._consts
        c[4], c[5] = self._current_ne
        env = self._environment
        sea = self._sea
        if env.wind_speed_mps or env.wave_force_std_N or env.gusty or sea is not None:
            c[6], c[7], c[8] = self._external_force()
            if sea is not None:  # the hull moves through the water's orbit: relative-velocity forces
                c[4] += float(self._loads[10])
                c[5] += float(self._loads[11])
        else:
            c[6] = c[7] = c[8] = 0.0
        x0 = self._x
        motion = None
        buf = self._buf
        act_cmd = self.actuators
        act0 = act_cmd.state
        _plant_step(buf, act_cmd.command_array, act_cmd.active_array, self._model_arrays, c)
        v = buf.tolist()
        x1 = tuple(v[:6])
        k1 = tuple(v[11:])
        act_cmd.state = tuple(v[6:11])
        self._step_input = _step_mean_py(act0, act_cmd.state)
        if sea is not None:  # heave, roll, pitch at the step's start, then driven on over the step
            motion = self._seakeeping.motion((k1[3] - x0[4] * x0[5], k1[4] + x0[3] * x0[5]), x0[5])
            ld = self._loads
            self._seakeeping.step(self.dt_s, (float(ld[6]), float(ld[7]), float(ld[8])))
        self._x_dot = k1
        self._k += 1
        self.t = self._k * self.dt_s
        self._x = x1
        if not math.isfinite(x1[0] + x1[1] + x1[2] + x1[3] + x1[4] + x1[5]):  # NaN/inf propagate
            raise FloatingPointError(f"simulation diverged at t = {self.t:.2f} s: state {x1}")
        return PlantSample(x0, k1, act0, motion)

    def run_held(self, n: int) -> tuple[list, list, list] | None:
        """In calm or current-only water with no set-point on its way, all `n` steps in one compiled call."""
        env = self._environment
        if n <= 1 or env.wind_speed_mps or env.wave_force_std_N or env.gusty or self._sea is not None or self._pending:
            return None  # forces that depend on each step's state, or set-points still on their way
        c = self._consts
        c[4], c[5] = self._current_ne
        c[6] = c[7] = c[8] = 0.0
        xs, ks, acts = np.empty((n + 1, 6)), np.empty((n, 6)), np.empty((n, 5))
        a = self.actuators
        _plant_steps(np.array(self._x), np.array(a.state), a.command_array, a.active_array,
                     self._model_arrays, c, xs, ks, acts)
        if not np.isfinite(xs[-1]).all():
            bad = int(np.argmax(~np.isfinite(xs).all(axis=1)))
            raise FloatingPointError(f"simulation diverged at t = {(self._k + bad) * self.dt_s:.2f} s")
        xl, kl, al = xs.tolist(), ks.tolist(), [list(a.state)] + acts.tolist()  # al[k]: at the start of step k
        self._k += n
        self.t = self._k * self.dt_s
        self._step_input = _step_mean_py(al[n - 1], al[n])
        self._x = tuple(xl[n])
        self._x_dot = tuple(kl[n - 1])
        a.state = tuple(al[n])
        self._buf[:6] = xs[n]
        self._buf[6:11] = acts[n - 1]
        self._buf[11:] = ks[n - 1]
        return xl, kl, al
