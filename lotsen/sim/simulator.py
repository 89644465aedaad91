"""The digital twin: vessel + actuators + sensors + environment, stepped at a fixed rate.

Integration: classical RK4 with step `dt_s` (default 0.01 s, 100 Hz), actuator outputs held
over each step (zero-order hold). RK4's local error at this step is below 1e-9 of the state for
this vessel (fastest mechanical pole about -5 1/s; see tests/sim/test_simulator.py, which
compares against a 1 ms reference). Sensors are sampled at step boundaries: a sensor whose rate
does not divide 100 Hz (GNSS at 8 Hz) is sampled at the first step at or after its due time,
so its stamps jitter by at most one step, as a real receiver's arrival times do.

The simulator is pure: no clock, no threads; time advances only by `step()`.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np

from lotsen.messages import ActuatorState, BatteryStatus, GnssFixType, ThrustCommand, VesselState
from lotsen.model._jit import njit
from lotsen.model.angles import lever_arm_ne
from lotsen.model.dynamics import VesselModel, rk4_step
from lotsen.model.environment import Environment, WindCoefficients, wind_force
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.model.actuators import actuator_step
from lotsen.sim.actuators import ActuatorDynamics
from lotsen.sim.boat import DEFAULT_BOAT, SimulatedBoat
from lotsen.sim.sensors import (
    GnssConfig, GnssModel, ImuConfig, ImuModel, MagnetometerModel, TachometerConfig, TachometerModel,
)


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


@dataclass(frozen=True)
class BatteryConfig:
    capacity_ah: float = 5.0
    full_voltage_v: float = 12.6  # 3S LiPo
    empty_voltage_v: float = 10.5
    internal_resistance_ohm: float = 0.05
    idle_current_a: float = 0.6  # Raspberry Pi, sensors, receiver
    # electrical current ~ k |n|^3 per motor: 2 azimuths at 100 rev/s draw about 2 x 9 A
    current_per_rps3_a: float = 9.0e-6
    initial_charge_frac: float = 1.0
    rate_hz: float = 1.0


@dataclass(frozen=True)
class SimConfig:
    dt_s: float = 0.01
    seed: int = 0
    imu: ImuConfig = field(default_factory=ImuConfig)
    gnss: GnssConfig = field(default_factory=GnssConfig)
    tachometer: TachometerConfig = field(default_factory=TachometerConfig)
    battery: BatteryConfig = field(default_factory=BatteryConfig)
    environment: Environment = field(default_factory=Environment)
    wind: WindCoefficients = field(default_factory=WindCoefficients)
    sensors: bool = True  # False: truth only (identification reference runs, MPC tests)


class _Schedule:
    """Due steps of a periodic sensor on the fixed-step clock (a rate may not divide the step
    rate: GNSS at 8 Hz is due every 12.5 steps and sampled at the first step at or after that)."""

    __slots__ = ("period_steps", "next_k", "last_t")

    def __init__(self, rate_hz: float, dt_s: float) -> None:
        self.period_steps = 1.0 / (rate_hz * dt_s) if rate_hz > 0 else math.inf  # rate 0: off
        self.next_k = 0.0 if rate_hz > 0 else math.inf
        self.last_t = -1.0 / rate_hz if rate_hz > 0 else -math.inf


class Simulator:
    """Simulated boat. `command()` sets actuator set-points; `step()` advances dt_s and returns the
    sensor messages measured during the step (ImuSample, MagSample, GnssFix, RpmSample, BatteryStatus).

    `boat`: a `SimulatedBoat` (default: the lake boat, which is not the default model), or a
    `VesselModel` (with `limits`) for a boat equal to that model ("ideal model")."""

    def __init__(self, boat: SimulatedBoat | VesselModel | None = None, limits: ActuatorLimits | None = None,
                 config: SimConfig = SimConfig(), x0: Sequence[float] | None = None) -> None:
        if boat is None:
            boat = DEFAULT_BOAT
        elif isinstance(boat, VesselModel):
            boat = SimulatedBoat.ideal_for(boat, limits or DEFAULT_LIMITS)
        elif limits is not None and limits != boat.limits:
            raise ValueError("a SimulatedBoat carries its own actuator limits; do not pass `limits` too")
        self.boat = boat
        self.model = boat.model()  # the boat's own equations, not the controllers' model
        limits = boat.limits
        self.limits = limits
        self.config = config
        self._latency = boat.command_latency_s
        self._pending: deque[tuple[float, tuple[float, ...]]] = deque()  # set-points on their way
        self.t = 0.0
        self._k = 0  # step counter; t = k dt keeps time exact over long runs
        self.x: tuple[float, ...] = tuple(float(v) for v in (x0 if x0 is not None else (0.0,) * 6))
        self.x_dot: tuple[float, ...] = (0.0,) * 6
        self.actuators = ActuatorDynamics(limits, config.dt_s)
        # the actuators' mean over the last step: what the vessel integrated under (`_step_mean`)
        self.step_input: tuple[float, ...] = tuple(self.actuators.state)
        seeds = np.random.SeedSequence(config.seed).spawn(6)
        rngs = [np.random.Generator(np.random.PCG64(s)) for s in seeds]
        self.imu = ImuModel(config.imu, rngs[0])
        self.mag = MagnetometerModel(config.imu, rngs[1])
        self.gnss = GnssModel(config.gnss, rngs[2])
        self.tachometer = TachometerModel(config.tachometer, rngs[3])
        self._wave_rng = rngs[4]
        self._wave = [0.0, 0.0, 0.0]
        self._gust_rng = rngs[5]
        self._gust = [0.0, 0.0]  # wind speed deviation (m/s), direction deviation (deg)
        dt = config.dt_s
        self._sched_imu = _Schedule(config.imu.rate_hz, dt)
        self._sched_mag = _Schedule(config.imu.mag_rate_hz, dt)
        self._sched_gnss = _Schedule(config.gnss.rate_hz, dt)
        self._sched_tacho = _Schedule(config.tachometer.rate_hz, dt)
        self._sched_batt = _Schedule(config.battery.rate_hz, dt)
        self.battery_used_ah = (1.0 - config.battery.initial_charge_frac) * config.battery.capacity_ah
        self.environment = config.environment
        self._current_ne = self.environment.current_ne
        self._buf = np.zeros(17)
        self._buf[:6] = self.x
        self._model_arrays = self.model.arrays.packed  # M, D_L, D_NL, thrust, arms for the compiled step
        a = self.actuators
        self._consts = np.array([a._max_dalpha, a._motor_gain, a._max_dn, config.dt_s, 0.0, 0.0, 0.0, 0.0, 0.0,
                                 boat.thrust_dead_band_rps])

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the plant step now, on a throwaway copy without
        sensors (this simulator's state and random streams stay untouched): the first call costs
        0.3 s or more, which a live control loop must not pay in its first tick."""
        Simulator(self.boat, config=replace(self.config, sensors=False), x0=self.x).step()

    # -- inputs -------------------------------------------------------------------------------
    def command(self, u: Sequence[float] | ThrustCommand) -> None:
        """Actuator set-points [alpha1, alpha2, n1, n2, nt]; clipped to the limits, NaN -> neutral."""
        values = u.as_tuple() if isinstance(u, ThrustCommand) else tuple(u)
        if self._latency > 0.0:
            self._pending.append((self.t + self._latency, values))
        else:
            self.actuators.set_command(*values)

    def _apply_due_commands(self) -> None:
        while self._pending and self._pending[0][0] <= self.t + 1e-9:
            self.actuators.set_command(*self._pending.popleft()[1])

    def set_environment(self, env: Environment) -> None:
        self.environment = env
        self._current_ne = env.current_ne

    def set_gnss_fix_type(self, fix_type: GnssFixType) -> None:
        self.gnss.set_fix_type(fix_type)

    # -- stepping -----------------------------------------------------------------------------
    def _external_force(self) -> tuple[float, float, float]:
        env, x = self.environment, self.x
        tau = [0.0, 0.0, 0.0]
        if env.gusty:
            self._advance_gust(env)
            tau = list(wind_force(x[2], x[3], x[4], env, self.config.wind,
                                  max(0.0, env.wind_speed_mps + self._gust[0]), env.wind_from_deg + self._gust[1]))
        elif env.wind_speed_mps:
            tau = list(wind_force(x[2], x[3], x[4], env, self.config.wind))
        if env.wave_force_std_N:
            # first-order Gauss-Markov force per axis (moment scaled by a quarter length)
            a = math.exp(-self.config.dt_s / env.wave_period_s)
            b = math.sqrt(1.0 - a * a) * env.wave_force_std_N
            w = self._wave_rng.standard_normal(3)
            self._wave = [a * self._wave[i] + b * w[i] * (0.25 if i == 2 else 1.0) for i in range(3)]
            tau = [tau[i] + self._wave[i] for i in range(3)]
        return tau[0], tau[1], tau[2]

    def _advance_gust(self, env: Environment) -> None:
        """One step of the Ornstein-Uhlenbeck gusts: speed with tau = wind_gust_time_constant_s,
        direction with 4 tau (the direction wanders more slowly than the speed gusts)."""
        dt, T = self.config.dt_s, max(env.wind_gust_time_constant_s, 1e-3)
        w = self._gust_rng.standard_normal(2)
        for i, (tau, std) in enumerate(((T, env.wind_gust_std_mps), (4.0 * T, env.wind_direction_std_deg))):
            a = math.exp(-dt / tau)
            self._gust[i] = a * self._gust[i] + math.sqrt(1.0 - a * a) * std * float(w[i])

    @property
    def wind_now(self) -> tuple[float, float]:
        """The wind acting now: (speed m/s, from deg), gusts included."""
        env = self.environment
        return max(0.0, env.wind_speed_mps + self._gust[0]), env.wind_from_deg + self._gust[1]

    def step(self) -> list[Any]:
        if self._pending:
            self._apply_due_commands()
        c = self._consts
        c[4], c[5] = self._current_ne
        if self.environment.wind_speed_mps or self.environment.wave_force_std_N or self.environment.gusty:
            c[6], c[7], c[8] = self._external_force()
        else:
            c[6] = c[7] = c[8] = 0.0
        x0 = self.x
        buf = self._buf
        act_cmd = self.actuators
        act0 = act_cmd.state
        _plant_step(buf, act_cmd.command_array, act_cmd.active_array, self._model_arrays, c)
        v = buf.tolist()
        x1 = tuple(v[:6])
        act = tuple(v[6:11])
        k1 = tuple(v[11:])
        act_cmd.state = act
        self.step_input = _step_mean_py(act0, act)
        self.x_dot = k1
        out: list[Any] = []
        if self.config.sensors:
            out = self._sample_sensors(self.t, x0, k1, act0)
        self._k += 1
        self.t = self._k * self.config.dt_s
        self.x = x1
        if not math.isfinite(x1[0] + x1[1] + x1[2] + x1[3] + x1[4] + x1[5]):  # NaN/inf propagate
            raise FloatingPointError(f"simulation diverged at t = {self.t:.2f} s: state {x1}")
        return out

    def _sample_sensors(self, t: float, x: Sequence[float], xd: Sequence[float],
                        act: Sequence[float]) -> list[Any]:
        # runs every step: schedules are compared inline, each sensor only when due; x, xd and the
        # actuators `act` are those at `t`, the start of the step
        k = self._k + 1e-9
        out: list[Any] = []
        s = self._sched_imu
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.imu.sample(t, x, xd, t - s.last_t))
            s.last_t = t
        s = self._sched_mag
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.mag.sample(t, x[2]))
        s = self._sched_gnss
        if k >= s.next_k:
            s.next_k += s.period_steps
            if any(self.boat.gnss_antenna_m):  # the antenna, not the model's origin, is what the receiver locates
                dn, de = lever_arm_ne(x[2], self.boat.gnss_antenna_m)
                r = x[5]
                fix = self.gnss.sample(t, x[0] + dn, x[1] + de, xd[0] - r * de, xd[1] + r * dn, t - s.last_t)
            else:
                fix = self.gnss.sample(t, x[0], x[1], xd[0], xd[1], t - s.last_t)
            s.last_t = t
            if fix is not None:
                out.append(fix)
        s = self._sched_tacho
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.tachometer.sample(t, (act[2], act[3], act[4])))
        s = self._sched_batt
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self._battery_sample(t, act, t - s.last_t))
            s.last_t = t
        return out

    def _battery_sample(self, t: float, act: tuple[float, ...], dt_since_last: float) -> BatteryStatus:
        b = self.config.battery
        current = b.idle_current_a + b.current_per_rps3_a * (abs(act[2]) ** 3 + abs(act[3]) ** 3 + abs(act[4]) ** 3)
        self.battery_used_ah += current * max(dt_since_last, 0.0) / 3600.0
        remaining = max(0.0, 1.0 - self.battery_used_ah / b.capacity_ah)
        voltage = b.empty_voltage_v + (b.full_voltage_v - b.empty_voltage_v) * remaining
        return BatteryStatus(stamp_s=t, voltage_v=voltage - b.internal_resistance_ohm * current,
                             current_a=current, remaining_frac=remaining)

    def advance(self, duration_s: float) -> list[Any]:
        """Step until `duration_s` more seconds have passed with the set-point held; returns all
        sensor messages. Identical to calling `step()` repeatedly (test), but in calm or current-only
        conditions the vessel and actuators are integrated in one compiled call for all steps and
        only the sensors run per step."""
        n = int(round(duration_s / self.config.dt_s))
        env = self.environment
        if n <= 1 or env.wind_speed_mps or env.wave_force_std_N or env.gusty or self._pending:
            # forces that depend on each step's state, or set-points still on their way
            out: list[Any] = []
            for _ in range(n):
                out.extend(self.step())
            return out
        c = self._consts
        c[4], c[5] = self._current_ne
        c[6] = c[7] = c[8] = 0.0
        xs, ks, acts = np.empty((n + 1, 6)), np.empty((n, 6)), np.empty((n, 5))
        a = self.actuators
        _plant_steps(np.array(self.x), np.array(a.state), a.command_array, a.active_array,
                     self._model_arrays, c, xs, ks, acts)
        if not np.isfinite(xs[-1]).all():
            bad = int(np.argmax(~np.isfinite(xs).all(axis=1)))
            raise FloatingPointError(f"simulation diverged at t = {(self._k + bad) * self.config.dt_s:.2f} s")
        xl, kl, al = xs.tolist(), ks.tolist(), [list(a.state)] + acts.tolist()  # al[k]: at the start of step k
        out = []
        dt, sensors = self.config.dt_s, self.config.sensors
        for k in range(n):
            if sensors:
                out.extend(self._sample_sensors(self._k * dt, xl[k], kl[k], al[k]))
            self._k += 1
        self.step_input = _step_mean_py(al[n - 1], al[n])
        self.t = self._k * dt
        self.x = tuple(xl[n])
        self.x_dot = tuple(kl[n - 1])
        a.state = tuple(al[n])
        self._buf[:6] = xs[n]
        self._buf[6:11] = acts[n - 1]
        self._buf[11:] = ks[n - 1]
        return out

    # -- outputs ------------------------------------------------------------------------------
    def truth(self) -> VesselState:
        x = self.x
        return VesselState(stamp_s=self.t, north_m=x[0], east_m=x[1], heading_rad=x[2],
                           u_mps=x[3], v_mps=x[4], r_radps=x[5], source="truth")

    def actuator_state(self) -> ActuatorState:
        a = self.actuators.state
        return ActuatorState(stamp_s=self.t, alpha1_rad=a[0], alpha2_rad=a[1], n1_rps=a[2], n2_rps=a[3], nt_rps=a[4])

    def state_array(self) -> np.ndarray:
        return np.array(self.x)


def simulate_inputs(inputs: np.ndarray, dt_s: float, model: VesselModel | None = None,
                    x0: Sequence[float] | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                    config: SimConfig | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open-loop run of a model (default: the default model): `inputs` (K x 5 set-points, one row per dt_s). Returns t (K+1), x (K+1 x 6),
    achieved actuator values (K x 5: the mean over each step, what the vessel integrated under). Truth only (no sensors)."""
    cfg = config or SimConfig(dt_s=dt_s, sensors=False)
    sim = Simulator(model or VesselModel(), limits, cfg, x0)  # the model's own response (no boat effects)
    K = len(inputs)
    xs = np.empty((K + 1, 6))
    acts = np.empty((K, 5))
    xs[0] = sim.x
    for k in range(K):
        sim.command(inputs[k])
        sim.step()
        xs[k + 1] = sim.x
        acts[k] = sim.step_input
    return np.arange(K + 1) * dt_s, xs, acts
