"""Identification experiments on the simulated boat, outside the stack: the `lotsen experiment run
--sim` runner (`run_on_simulator`: the experiment's input generator straight into the simulator,
the measured data as an identification record) and seeded lake records (`lake_run`: a random boat
that is not its model, in current and gusty wind) for the identification's tests and bench. The
lab loop through the whole stack is `lab_loop`."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lotsen.model import DEFAULT_LIMITS, DEFAULT_PARAMETERS, VesselModel, VesselParameters
from lotsen.model.angles import wrap_angle
from lotsen.sysid.data import IdRecord
from lotsen.sysid.experiment import Experiment, InputGenerator
from lotsen.sysid.judge import CORE_PARAMETERS


@dataclass
class SimulatedRun:
    record: IdRecord  # measured (noisy) data as written to the CSV
    truth_t: np.ndarray  # truth at every simulator step, for tests
    truth_x: np.ndarray
    gyro_bias_estimate_radps: float


def run_on_simulator(experiment: Experiment, model: Any = None, seed: int = 0,
                     psi_noise_rad: float = 0.01, environment: Any = None, preroll_s: float = 2.0,
                     keep_truth: bool = False) -> SimulatedRun:
    """Run `experiment` on the simulated boat with sensors; returns the measured record (with the IMU's
    means over each row interval, from which the record's sea state is estimated). `model`: the
    simulated boat (a `SimulatedBoat`, or a `VesselModel` for a boat exactly that model; default the
    default model)."""
    from lotsen.messages import GnssFix, ImuSample
    from lotsen.model.geodetic import LocalFrame
    from lotsen.sim import SimConfig, SimulatedBoat, Simulator

    cfg = SimConfig(seed=seed, sensors=True) if environment is None else SimConfig(
        seed=seed, sensors=True, environment=environment)
    boat = model if model is not None else VesselModel()  # a VesselModel: a boat exactly that model
    sim = Simulator(boat, None if isinstance(boat, SimulatedBoat) else DEFAULT_LIMITS, cfg,
                    x0=(0.0, 0.0, experiment.start_heading_rad, 0.0, 0.0, 0.0))
    g = cfg.gnss
    frame = LocalFrame(g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m)  # the simulated receiver's
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    # gyro bias calibration at rest before the run
    gyro = [m.gyro_radps[2] for m in sim.advance(preroll_s) if isinstance(m, ImuSample)]
    bias = float(np.mean(gyro)) if gyro else 0.0
    sim.x = (0.0, 0.0, experiment.start_heading_rad, experiment.start_speed_mps, 0.0, 0.0)
    dt = cfg.dt_s
    gen = InputGenerator(experiment)
    steps_per_tick = max(1, int(round(1.0 / (experiment.command_rate_hz * dt))))
    n_steps = int(math.ceil(experiment.duration_s / dt))
    rows_t: list[float] = []
    rows_u: list[np.ndarray] = []
    rows_n: list[int] = []
    rows_y: list[list[float]] = []
    rows_imu: list[np.ndarray] = []  # sums of the IMU samples within each row interval, and their count
    truth_t, truth_x = [], []
    last_gyro = 0.0
    for k in range(n_steps):
        t = k * dt
        x_true = sim.x
        psi_meas = x_true[2] + psi_noise_rad * float(rng.standard_normal())
        tick = k % steps_per_tick == 0
        if tick:
            sim.command(gen.command(t, (math.nan, math.nan, psi_meas)))
        msgs = sim.step()
        fix = None
        imu = np.zeros(7)
        for m in msgs:
            if isinstance(m, ImuSample):
                last_gyro = m.gyro_radps[2]
                imu += (*m.accel_mps2, *m.gyro_radps, 1.0)
            elif isinstance(m, GnssFix) and math.isfinite(m.lat_deg):
                fix = m
        if tick or fix is not None:
            y = [math.nan] * 4
            if fix is not None:
                n, e = frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m)
                y = [float(n), float(e), wrap_angle(psi_meas), last_gyro - bias]
            rows_t.append(t)
            rows_u.append(np.zeros(5))
            rows_n.append(0)
            rows_y.append(y)
            rows_imu.append(np.zeros(7))
        rows_imu[-1] += imu
        rows_u[-1] += np.array(sim.step_input)  # what acted during this step
        rows_n[-1] += 1
        if keep_truth:
            truth_t.append(t)
            truth_x.append(x_true)
    U = np.array(rows_u) / np.array(rows_n)[:, None]
    S = np.array(rows_imu).reshape(-1, 7)
    with np.errstate(invalid="ignore", divide="ignore"):
        imu_mean = S[:, :6] / S[:, 6:]  # the IMU's mean over each row interval (NaN: no sample in it)
    rec = IdRecord(np.array(rows_t), U, np.array(rows_y), source=f"sim:{experiment.name}", imu=imu_mean)
    return SimulatedRun(rec, np.array(truth_t), np.array(truth_x).reshape(-1, 6), bias)


LAKE_EXPERIMENT = {
    "name": "lake_prbs", "area": {"size_m": [400, 400]},
    "pieces": [
        {"type": "prbs", "duration_s": 600, "bit_s": 1.5, "seed": 3, "base": {"n_rps": 55},
         "amplitude": {"alpha_deg": 25, "nt_rps": 60, "n1_rps": 25, "n2_rps": 25}},
    ],
}


@dataclass
class LakeRun:
    """A designed experiment on a boat that is not its model, in current and gusty wind."""

    run: SimulatedRun
    boat: VesselParameters  # the simulated boat's true parameters
    environment: Any  # lotsen.model.Environment of the run (current, mean wind, gusts)


def lake_boat(seed: int, core_range: tuple[float, float] = (0.05, 0.25), other_max: float = 0.40,
              keep: tuple[str, ...] = ("m11",)) -> VesselParameters:
    """A random boat around the defaults: the core eight off by 5-25 % (random sign), the rest by up
    to 40 %, `keep` (the scale anchor m11) at its default. Seeded, pure."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 2501]))
    values = DEFAULT_PARAMETERS.to_dict()
    for name in DEFAULT_PARAMETERS.names():
        if name in keep:
            continue
        if name in CORE_PARAMETERS:
            f = rng.uniform(*core_range) * rng.choice((-1.0, 1.0))
        else:
            f = rng.uniform(-other_max, other_max)
        values[name] *= 1.0 + f
    return VesselParameters(**values)


def lake_run(seed: int, duration_s: float = 600.0, current_mps: float | None = None,
             wind_mps: float | None = None, boat: VesselParameters | None = None,
             experiment: Experiment | None = None, waves: Any = None) -> LakeRun:
    """A lake record: `experiment` (default a 10-min PRBS on all five inputs, bow thruster included)
    on the boat `boat` (default `lake_boat(seed)`) in a constant earth-frame current (`current_mps`,
    default random up to 0.1 m/s, random direction) and gusty wind (`wind_mps` mean, default random
    up to 5 m/s; gusts 15-30 % of the mean with a 3-10 s time constant, direction wandering by 10 deg),
    with the simulator's noisy asynchronous sensors (run_on_simulator); `waves` (a
    lotsen.model.Waves): a wind sea besides. Seeded, pure."""
    from lotsen.model import Environment
    from lotsen.sysid.experiment import parse_experiment

    rng = np.random.default_rng(np.random.SeedSequence([seed, 2502]))
    c = float(rng.uniform(0.0, 0.1)) if current_mps is None else float(current_mps)
    w = float(rng.uniform(0.0, 5.0)) if wind_mps is None else float(wind_mps)
    env = Environment(current_speed_mps=c, current_to_deg=float(rng.uniform(0, 360)), wind_speed_mps=w,
                      wind_from_deg=float(rng.uniform(0, 360)), wind_gust_std_mps=w * float(rng.uniform(0.15, 0.3)),
                      wind_gust_time_constant_s=float(rng.uniform(3.0, 10.0)), wind_direction_std_deg=10.0 if w else 0.0,
                      waves=waves)
    if experiment is None:
        spec = dict(LAKE_EXPERIMENT)
        spec["pieces"] = [dict(LAKE_EXPERIMENT["pieces"][0], duration_s=duration_s, seed=seed)]
        experiment = parse_experiment(spec, "lake")
    boat = boat if boat is not None else lake_boat(seed)
    run = run_on_simulator(experiment, VesselModel(boat), seed=seed, environment=env)
    # the rows carry interval means of the achieved actuator values (run_on_simulator)
    run.record = dataclasses.replace(run.record, input_kind="mean")
    return LakeRun(run, boat, env)


def record_sea_state(record: IdRecord) -> Any:
    """The record's sea state from its own IMU (lotsen.fusion.seastate.record_sea_state, the boat's
    estimator run offline), or None for a record without IMU columns."""
    from lotsen.fusion.seastate import record_sea_state as from_imu
    from lotsen.sysid.waves import heading_and_velocity

    if record.imu is None or not np.isfinite(record.imu).all(axis=1).any():
        return None
    psi, velocity = heading_and_velocity(record)
    return from_imu(record.t, record.imu, psi, velocity)
