"""Evaluation of the estimators against simulated truth (pure: simulator in, numbers out).

`evaluate(EvaluationConfig(...))`:
1. magnetometer calibration from a simulated turn on the spot (bow thruster + azimuths),
2. a manoeuvre run (open loop: standstill, speed changes, turns, bow thruster, reverse) with the
   simulator's default sensor errors (gyro bias + walk, accelerometer bias, distorted and noisy
   magnetometer, RTK GNSS) and, by default, a light current and wind the filters' calm-water
   model does not know, with a GNSS outage of `outage_duration_s`,
3. the seed filters, the model-aided EKF and (optionally) imufusion's AHRS on the same messages.

Errors are computed at 10 Hz. Heading, velocity and position RMS exclude the warm-up and the
outage plus `recovery_s` after it (the outage has its own rows). Velocity error is the norm of
the body-frame (u, v) error vector.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from lotsen.fusion.common import feed, wrap_angle
from lotsen.fusion.ekf import EkfConfig, ModelAidedEKF
from lotsen.fusion.magcal import MagCalibration, fit_mag_calibration
from lotsen.fusion.seed_filters import SeedFilters, SeedFiltersConfig, YawFilterConfig
from lotsen.messages import ImuSample, MagSample, VesselState
from lotsen.model import DEFAULT_PARAMETERS, Environment, VesselModel, VesselParameters

DEG = math.pi / 180.0

# (duration s, [alpha1 rad, alpha2 rad, n1 rps, n2 rps, nt rps]); about 4 minutes in all
MANOEUVRE: tuple[tuple[float, tuple[float, float, float, float, float]], ...] = (
    (8.0, (0.0, 0.0, 0.0, 0.0, 0.0)),  # standstill (AHRS gyro offset, filters settle)
    (20.0, (0.0, 0.0, 40.0, 40.0, 0.0)),  # ~0.5 m/s ahead
    (15.0, (-15 * DEG, -15 * DEG, 40.0, 40.0, 0.0)),  # turn to starboard
    (15.0, (0.0, 0.0, 65.0, 65.0, 0.0)),  # speed up to ~1 m/s
    (20.0, (12 * DEG, 12 * DEG, 65.0, 65.0, 0.0)),  # turn to port at speed
    (10.0, (0.0, 0.0, 25.0, 25.0, 40.0)),  # slow, bow thruster
    (20.0, (-25 * DEG, -25 * DEG, 55.0, 55.0, 0.0)),
    (10.0, (0.0, 0.0, 0.0, 0.0, 0.0)),  # drift to a stop
    (15.0, (0.0, 0.0, -40.0, -40.0, 0.0)),  # astern
    (15.0, (0.0, 0.0, 80.0, 80.0, 0.0)),  # fast
    (20.0, (20 * DEG, -20 * DEG, 70.0, 70.0, -50.0)),  # toe-in, bow thruster to port
    (25.0, (8 * DEG, 8 * DEG, 60.0, 60.0, 0.0)),  # long port turn (GNSS outage falls here)
    (20.0, (0.0, 0.0, 50.0, 50.0, 0.0)),
    (17.0, (-30 * DEG, -30 * DEG, 30.0, 30.0, 30.0)),  # tight turn at low speed
)


@dataclass(frozen=True)
class EvaluationConfig:
    duration_s: float = 240.0
    seed: int = 1
    calibration_turn_s: float = 45.0
    outage_start_s: float = 175.0
    outage_duration_s: float = 10.0
    recovery_s: float = 5.0
    warmup_s: float = 10.0
    environment: Environment = field(default_factory=lambda: Environment(
        current_speed_mps=0.05, current_to_deg=60.0, wind_speed_mps=2.0, wind_from_deg=200.0))
    model_error: float = 0.0  # relative error of the EKF model's drag/thrust parameters
    initial_heading_error_deg: float = 0.0  # filters start this far off (with large std)
    ekf: EkfConfig = field(default_factory=EkfConfig)
    seed_gyro_bias_from_standstill: bool = False  # give the seed yaw filter a standstill bias
    compare_imufusion: bool = True
    filters: tuple[str, ...] = ("seed_kf", "ekf")  # which estimators to run (imufusion: compare_imufusion)
    sample_hz: float = 10.0


def perturbed_parameters(rel: float, params: VesselParameters = DEFAULT_PARAMETERS) -> VesselParameters:
    """A deliberately wrong model: drag up by `rel`, thrust and inertia down by `rel` (worst-ish case)."""
    d = params.to_dict()
    for k in ("X_u", "X_uu", "Y_v", "Y_r", "N_v", "N_r"):
        d[k] = d[k] * (1.0 + rel)
    for k in ("mu_az", "mu_t", "m11", "m22", "m33"):
        d[k] = d[k] * (1.0 - rel)
    return VesselParameters.from_dict(d)


def simulate_calibration_turn(seed: int, duration_s: float = 45.0) -> list[MagSample]:
    """Raw magnetometer samples of a turn on the spot (default: 1.2 turns)."""
    from lotsen.sim import SimConfig, Simulator

    sim = Simulator(config=SimConfig(seed=seed + 1000))
    sim.command([-0.6, -0.6, 15.0, 15.0, 60.0])
    return [m for m in sim.advance(duration_s) if isinstance(m, MagSample)]


def calibrate_from_turn(samples: list[MagSample]) -> MagCalibration:
    return fit_mag_calibration([m.field_uT[0] for m in samples], [m.field_uT[1] for m in samples], units="uT")


def _manoeuvre_command(t: float) -> tuple[float, ...]:
    t0 = 0.0
    for dur, u in MANOEUVRE:
        if t < t0 + dur:
            return u
        t0 += dur
    return MANOEUVRE[-1][1]


class _ImufusionPeer:
    """x-io Fusion AHRS (imufusion 1.3 API) with its gyro-offset module, NED convention."""

    source = "imufusion"

    def __init__(self, calibration: MagCalibration, rate_hz: float = 100.0) -> None:
        import imufusion

        self._m = imufusion
        self.ahrs = imufusion.Ahrs()
        # rejection off (the binding's default): with 10 deg rejection it rejected the magnetometer
        # for good after a few turns (centripetal acceleration tilts its gravity estimate)
        self.ahrs.set_settings(imufusion.AhrsSettings(sample_rate=rate_hz, convention=imufusion.CONVENTION_NED,
                                                      gain=0.5))
        self.bias = imufusion.Bias()
        self.bias.set_settings(imufusion.BiasSettings(sample_rate=rate_hz))
        self.cal = calibration
        self.mag = None
        self.t_last: float | None = None
        self.heading = float("nan")

    def on_mag(self, m: MagSample) -> None:
        wx, wy = self.cal.apply(m.field_uT[0], m.field_uT[1])
        H = self.cal.radius  # calibrated field back in uT, so the vertical component keeps its ratio
        self.mag = np.array([wx * H, wy * H, m.field_uT[2]])

    def on_imu(self, m: ImuSample) -> None:
        if self.mag is None:
            return
        if self.t_last is not None and m.stamp_s > self.t_last:
            self.ahrs.set_sample_period(m.stamp_s - self.t_last)
        self.t_last = m.stamp_s
        gyr = self.bias.update(np.degrees(np.array(m.gyro_radps)))
        # imufusion 1.3 with CONVENTION_NED wants +1 g on z for a level sensor (the negated specific
        # force of our FRD frame); with -1 g it settles upside down and the heading mirrors
        acc = -np.array(m.accel_mps2) / 9.81
        self.ahrs.update(gyr, acc, self.mag)
        self.heading = math.radians(float(self._m.quaternion_to_euler(self.ahrs.get_quaternion())[2]))


@dataclass
class _Track:
    name: str
    t: list = field(default_factory=list)
    est: list = field(default_factory=list)  # (N, E, psi, u, v)
    cpu_s: float = 0.0
    n_msgs: int = 0


def evaluate(config: EvaluationConfig = EvaluationConfig(),
             clock: Callable[[], float] | None = None) -> dict[str, Any]:
    """Run calibration + manoeuvre; returns {'calibration': {...}, 'filters': {name: metrics}}.

    `clock` (e.g. time.perf_counter) is only used to report CPU time per message; the
    algorithms never read it.
    """
    from lotsen.sim import SimConfig, Simulator

    cal_samples = simulate_calibration_turn(config.seed, config.calibration_turn_s)
    cal = calibrate_from_turn(cal_samples)
    sim = Simulator(config=SimConfig(seed=config.seed, environment=config.environment))
    imu_cfg = sim.config.imu
    S, b = np.array(imu_cfg.soft_iron), np.array(imu_cfg.hard_iron_uT)
    calib_report = {
        "center_err_uT": float(np.linalg.norm(np.array(cal.center) - b)),
        "matrix_rel_err": float(np.linalg.norm(np.array(cal.matrix) / imu_cfg.earth_field_horizontal_uT - S)
                                / np.linalg.norm(S)),
        "residual_rms": cal.residual_rms, "coverage_deg": cal.coverage_deg, "n_points": cal.n_points,
    }
    origin = (sim.config.gnss.origin_lat_deg, sim.config.gnss.origin_lon_deg, sim.config.gnss.origin_height_m)
    psi0 = wrap_angle(sim.x[2] + config.initial_heading_error_deg * DEG)
    init = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.0, heading_rad=psi0, u_mps=0.0, v_mps=0.0, r_radps=0.0)
    ekf_model = VesselModel(params=perturbed_parameters(config.model_error)) if config.model_error else VesselModel()
    ekf = ModelAidedEKF(ekf_model, cal, replace(config.ekf, origin=origin), initial=init,
                        initial_std=(1.0, 1.0, math.pi, 0.5, 0.5, 0.3, 0.03, 0.2, 0.2))
    seed = SeedFilters(cal, SeedFiltersConfig(origin=origin), initial=init)
    filters: dict[str, Any] = {k: f for k, f in (("seed_kf", seed), ("ekf", ekf)) if k in config.filters}
    if config.compare_imufusion:
        filters["imufusion"] = _ImufusionPeer(cal, imu_cfg.rate_hz)
    tracks = {k: _Track(k) for k in filters}
    truth_t: list[float] = []
    truth_x: list[tuple[float, ...]] = []
    steps = int(round(config.duration_s / sim.config.dt_s))
    every = max(1, int(round(1.0 / (config.sample_hz * sim.config.dt_s))))
    t_out0, t_out1 = config.outage_start_s, config.outage_start_s + config.outage_duration_s
    standstill_gyro: list[float] = []
    ekf_std_psi: list[float] = []
    bias_set = False
    for k in range(steps):
        t = sim.t
        sim.gnss.outage = t_out0 <= t < t_out1
        sim.command(_manoeuvre_command(t))
        x_now = sim.x
        msgs = sim.step()
        act = sim.actuator_state()  # achieved values over this step (tachometers + servo feedback)
        act.stamp_s = t
        if config.seed_gyro_bias_from_standstill and not bias_set and "seed_kf" in filters:
            standstill_gyro += [m.gyro_radps[2] for m in msgs if isinstance(m, ImuSample)]
            if t >= MANOEUVRE[0][0] - 1.0:
                bias = float(np.mean(standstill_gyro))
                seed.yaw.config = replace(seed.yaw.config, gyro_bias_radps=bias)
                seed.config = replace(seed.config, yaw=seed.yaw.config)
                bias_set = True
        for name, f in filters.items():
            c0 = clock() if clock else 0.0
            if k % 5 == 0 and hasattr(f, "on_command"):
                f.on_command(act)
            for m in msgs:
                if feed(f, m):
                    tracks[name].n_msgs += 1
            if clock:
                tracks[name].cpu_s += clock() - c0
        if k % every == 0:
            truth_t.append(t)
            truth_x.append(x_now)
            for name, f in filters.items():
                if isinstance(f, _ImufusionPeer):
                    tracks[name].est.append((math.nan, math.nan, f.heading, math.nan, math.nan))
                else:
                    e = f.estimate(t)
                    if name == "ekf" and t >= config.warmup_s:
                        ekf_std_psi.append(e.std[2])
                    tracks[name].est.append((e.north_m, e.east_m, e.heading_rad, e.u_mps, e.v_mps))
    T = np.array(truth_t)
    X = np.array(truth_x)
    normal = (T >= config.warmup_s) & ~((T >= t_out0) & (T < t_out1 + config.recovery_s))
    outage = (T >= t_out0) & (T < t_out1)
    results: dict[str, Any] = {}
    for name, tr in tracks.items():
        E = np.array(tr.est)
        dpsi = np.degrees(np.abs(np.angle(np.exp(1j * (E[:, 2] - X[:, 2])))))
        dvel = np.hypot(E[:, 3] - X[:, 3], E[:, 4] - X[:, 4])
        dpos = np.hypot(E[:, 0] - X[:, 0], E[:, 1] - X[:, 1])
        r: dict[str, Any] = {
            "heading_rms_deg": float(np.sqrt(np.mean(dpsi[normal] ** 2))),
            "heading_max_deg": float(np.max(dpsi[normal])),
            "velocity_rms_mps": float(np.sqrt(np.mean(dvel[normal] ** 2))),
            "position_rms_m": float(np.sqrt(np.mean(dpos[normal] ** 2))),
            "outage_position_err_end_m": float(dpos[outage][-1]) if outage.any() else math.nan,
            "outage_position_err_max_m": float(np.max(dpos[outage])) if outage.any() else math.nan,
            "outage_heading_rms_deg": float(np.sqrt(np.mean(dpsi[outage] ** 2))) if outage.any() else math.nan,
            "cpu_us_per_msg": 1e6 * tr.cpu_s / max(tr.n_msgs, 1) if clock else math.nan,
        }
        f = filters[name]
        if hasattr(f, "counters"):
            r["counters"] = f.counters.as_dict()
        if name == "ekf":
            r["heading_std_mean_deg"] = float(np.degrees(np.mean(ekf_std_psi))) if ekf_std_psi else math.nan
            r["gyro_bias_err_radps"] = float(ekf.gyro_bias_radps - sim.imu.gyro_bias_radps)
        results[name] = r
    return {"calibration": calib_report, "filters": results,
            "speed_max_mps": float(np.max(np.hypot(X[:, 3], X[:, 4]))),
            "truth_final": sim.truth()}
