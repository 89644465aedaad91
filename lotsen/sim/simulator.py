"""The digital twin: a plant (vessel + actuators + environment, `lotsen.sim.plant`) and lotsen's
sensor models, stepped at a fixed rate.

The plant is lotsen's own simulated boat (`BoatPlant`) unless another is given (`plant=`: an
external physics behind `lotsen.physics`, or any `Plant`); the sensors are always lotsen's.
Integration of the own boat: classical RK4 with step `dt_s` (default 0.01 s, 100 Hz) under the actuators'
mean over each step. RK4's local error at this step is below 1e-9 of the state for
this vessel (fastest mechanical pole about -5 1/s; see tests/sim/test_simulator.py, which
compares against a 1 ms reference). Sensors are sampled at step boundaries: a sensor whose rate
does not divide 100 Hz (GNSS at 8 Hz) is sampled at the first step at or after its due time,
so its stamps jitter by at most one step, as a real receiver's arrival times do.

The simulator is pure: no clock, no threads; time advances only by `step()`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from lotsen.messages import ActuatorState, BatteryStatus, GnssFixType, ThrustCommand, VesselState
from lotsen.model.angles import lever_arm_ne, mast_swing_body
from lotsen.model.dynamics import VesselModel
from lotsen.model.environment import Environment, WindCoefficients
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.sim.actuators import ActuatorDynamics
from lotsen.sim.boat import SimulatedBoat
from lotsen.sim.lakebed import LakeBed, SounderConfig, SounderModel, sounder_rng
from lotsen.sim.plant import RANDOM_STREAMS, BoatPlant, Plant
from lotsen.sim.sensors import (
    GnssConfig, GnssModel, ImuConfig, ImuModel, MagnetometerModel, TachometerConfig, TachometerModel,
)


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

    def propulsion_current_a(self, n1_rps: float, n2_rps: float, nt_rps: float) -> float:
        """The motors' electrical current at these propeller speeds (k |n|^3 each, the idle draw not included)."""
        return self.current_per_rps3_a * (abs(n1_rps) ** 3 + abs(n2_rps) ** 3 + abs(nt_rps) ** 3)

    @property
    def nominal_voltage_v(self) -> float:
        return 0.5 * (self.full_voltage_v + self.empty_voltage_v)


def propulsion_energy_j(t_s: np.ndarray, n_rps: np.ndarray, battery: BatteryConfig = BatteryConfig()) -> float:
    """Electrical energy (J) the three motors draw over a trace of propeller speeds (rows [n1, n2, nt]
    at times t_s; trapezoidal), at the battery's nominal voltage: the figure a mission report and a
    bench compare between calm water and waves."""
    t = np.asarray(t_s, dtype=float)
    n = np.abs(np.asarray(n_rps, dtype=float).reshape(len(t), 3))
    if t.size < 2:
        return 0.0
    power = battery.nominal_voltage_v * battery.current_per_rps3_a * np.sum(n ** 3, axis=1)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))


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
    lakebed: LakeBed | None = None  # a bed under the boat: the sounder pings it (lotsen.sim.lakebed)
    sounder: SounderConfig = field(default_factory=SounderConfig)


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
    `VesselModel` (with `limits`) for a boat equal to that model ("ideal model"), or a `Plant`
    (also as `plant=`): any other body behind the sensors, e.g. an external physics. A plant owns
    its actuators and, unless it is lotsen's own boat, its environment."""

    def __init__(self, boat: SimulatedBoat | VesselModel | Plant | None = None, limits: ActuatorLimits | None = None,
                 config: SimConfig = SimConfig(), x0: Sequence[float] | None = None, *,
                 plant: Plant | None = None) -> None:
        if isinstance(boat, Plant):
            boat, plant = None, boat
        if plant is None:
            plant = BoatPlant(boat, limits, dt_s=config.dt_s, seed=config.seed, environment=config.environment,
                              wind=config.wind, x0=x0)
        else:
            if boat is not None or limits is not None:
                raise ValueError("a Plant carries its own boat and actuator limits; do not pass `boat` or `limits` too")
            if abs(plant.dt_s - config.dt_s) > 1e-12:
                raise ValueError(f"the plant steps {plant.dt_s} s, the simulator's config {config.dt_s} s")
            if config.environment != Environment():
                plant.set_environment(config.environment)  # an external physics refuses: it owns its water
            if x0 is not None:
                plant.place(x0)
        self.plant = plant
        self.boat = getattr(plant, "boat", None)  # lotsen's own boat, None behind an external physics
        self.model = getattr(plant, "model", None)  # the boat's own equations, not the controllers' model
        self.limits = plant.limits
        self.config = config
        self.t = 0.0
        self._k = 0  # step counter; t = k dt keeps time exact over long runs
        streams = np.random.SeedSequence(config.seed).spawn(RANDOM_STREAMS)  # 0-3 here, 4-5 the plant's
        rngs = [np.random.Generator(np.random.PCG64(s)) for s in streams]
        self.imu = ImuModel(config.imu, rngs[0])
        self.mag = MagnetometerModel(config.imu, rngs[1])
        self.gnss = GnssModel(config.gnss, rngs[2])
        self.tachometer = TachometerModel(config.tachometer, rngs[3])
        dt = config.dt_s
        self._sched_imu = _Schedule(config.imu.rate_hz, dt)
        self._sched_mag = _Schedule(config.imu.mag_rate_hz, dt)
        self._sched_gnss = _Schedule(config.gnss.rate_hz, dt)
        self._sched_tacho = _Schedule(config.tachometer.rate_hz, dt)
        self._sched_batt = _Schedule(config.battery.rate_hz, dt)
        self.sounder = (SounderModel(config.sounder, config.lakebed, sounder_rng(config.seed))
                        if config.lakebed is not None else None)
        self._sched_sounder = _Schedule(config.sounder.rate_hz if self.sounder is not None else 0.0, dt)
        self.battery_used_ah = (1.0 - config.battery.initial_charge_frac) * config.battery.capacity_ah
        self._antenna = plant.gnss_antenna_m
        self._antenna_height = plant.gnss_antenna_height_m

    def warm_up(self) -> None:
        """Prepare the plant's compiled step now (this simulator's state and random streams stay
        untouched): the first call costs 0.3 s or more, which a live control loop must not pay."""
        self.plant.warm_up()

    # -- the plant's state ----------------------------------------------------------------------
    @property
    def x(self) -> tuple[float, ...]:
        return self.plant.x

    @x.setter
    def x(self, value: Sequence[float]) -> None:
        """As it has always behaved, for `lotsen.harness.identification.run_on_simulator`, whose lake
        records depend on it: on lotsen's own boat the next step's forces and sensors see `value`,
        but the integrator goes on from where the boat is (`BoatPlant.override_sample_state`). To
        put the boat somewhere, use `place()`."""
        override = getattr(self.plant, "override_sample_state", None)
        if override is not None:
            override(value)
        else:
            self.plant.place(value)

    def place(self, x: Sequence[float]) -> None:
        """Put the boat at state x = [N, E, psi, u, v, r]."""
        self.plant.place(x)

    @property
    def x_dot(self) -> tuple[float, ...]:
        return self.plant.x_dot

    @property
    def actuators(self) -> ActuatorDynamics:
        return self.plant.actuators

    @property
    def step_input(self) -> tuple[float, ...]:
        """The actuators' mean over the last step: what the vessel integrated under."""
        return self.plant.step_input

    @property
    def fresh(self) -> bool:
        """False while the plant has no fresh state (an external physics that stopped answering)."""
        return self.plant.fresh

    @property
    def environment(self) -> Environment | None:
        return self.plant.environment

    @property
    def wind_now(self) -> tuple[float, float]:
        """The wind acting now: (speed m/s, from deg), gusts included (NaN: the plant's own business)."""
        return self.plant.wind_now

    # -- inputs -------------------------------------------------------------------------------
    def command(self, u: Sequence[float] | ThrustCommand) -> None:
        """Actuator set-points [alpha1, alpha2, n1, n2, nt]; clipped to the limits, NaN -> neutral."""
        self.plant.command(u.as_tuple() if isinstance(u, ThrustCommand) else tuple(u))

    def set_environment(self, env: Environment) -> None:
        self.plant.set_environment(env)

    def set_gnss_fix_type(self, fix_type: GnssFixType) -> None:
        self.gnss.set_fix_type(fix_type)

    # -- stepping -----------------------------------------------------------------------------
    def step(self) -> list[Any]:
        sample = self.plant.step()
        out: list[Any] = []
        if sample is not None and self.config.sensors:
            out = self._sample_sensors(self.t, sample[0], sample[1], sample[2], sample.motion)
        self._k += 1
        self.t = self._k * self.config.dt_s
        return out

    def _sample_sensors(self, t: float, x: Sequence[float], xd: Sequence[float],
                        act: Sequence[float], motion: Any = None) -> list[Any]:
        # runs every step: schedules are compared inline, each sensor only when due; x, xd, the
        # actuators `act` and the motion out of the plane are those at `t`, the start of the step
        k = self._k + 1e-9
        out: list[Any] = []
        s = self._sched_imu
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.imu.sample(t, x, xd, t - s.last_t, motion))
            s.last_t = t
        s = self._sched_mag
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.mag.sample(t, x[2]))
        s = self._sched_gnss
        if k >= s.next_k:
            s.next_k += s.period_steps
            if any(self._antenna) or motion is not None:  # the receiver locates the antenna, not the origin
                dn, de = lever_arm_ne(x[2], self._antenna)
                r = x[5]
                vn, ve = xd[0] - r * de, xd[1] + r * dn
                if motion is not None and self._antenna_height:  # carried by the roll and pitch
                    sn, se = lever_arm_ne(x[2], mast_swing_body(self._antenna_height, motion.roll_rad, motion.pitch_rad))
                    dn, de = dn + sn, de + se
                    h, c, sp = self._antenna_height, math.cos(x[2]), math.sin(x[2])
                    # its velocity: d/dt of (-h theta, h phi) in body axes, turned by the heading
                    bx, by = -h * motion.q_radps, h * motion.p_radps
                    vn, ve = vn + c * bx - sp * by, ve + sp * bx + c * by
                fix = self.gnss.sample(t, x[0] + dn, x[1] + de, vn, ve, t - s.last_t)
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
        s = self._sched_sounder
        if k >= s.next_k:
            s.next_k += s.period_steps
            out.append(self.sounder.sample(t, x[0], x[1], x[2]))  # type: ignore[union-attr]
        return out

    def _battery_sample(self, t: float, act: tuple[float, ...], dt_since_last: float) -> BatteryStatus:
        b = self.config.battery
        current = b.idle_current_a + b.propulsion_current_a(act[2], act[3], act[4])
        self.battery_used_ah += current * max(dt_since_last, 0.0) / 3600.0
        remaining = max(0.0, 1.0 - self.battery_used_ah / b.capacity_ah)
        voltage = b.empty_voltage_v + (b.full_voltage_v - b.empty_voltage_v) * remaining
        return BatteryStatus(stamp_s=t, voltage_v=voltage - b.internal_resistance_ohm * current,
                             current_a=current, remaining_frac=remaining)

    def advance(self, duration_s: float) -> list[Any]:
        """Step until `duration_s` more seconds have passed with the set-point held; returns all
        sensor messages. Identical to calling `step()` repeatedly (test), but where the plant can
        (lotsen's own boat in calm or current-only water) the vessel and actuators are integrated
        in one compiled call for all steps and only the sensors run per step."""
        n = int(round(duration_s / self.config.dt_s))
        block = self.plant.run_held(n)
        out: list[Any] = []
        if block is None:
            for _ in range(n):
                out.extend(self.step())
            return out
        xl, kl, al = block
        dt, sensors = self.config.dt_s, self.config.sensors
        for k in range(n):
            if sensors:
                out.extend(self._sample_sensors(self._k * dt, xl[k], kl[k], al[k]))
            self._k += 1
        self.t = self._k * dt
        return out

    # -- outputs ------------------------------------------------------------------------------
    def truth(self) -> VesselState:
        x = self.plant.x
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
