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
from lotsen.fusion.ekf import IPSI, EkfConfig, ModelAidedEKF
from lotsen.fusion.magcal import MagCalibration, fit_mag_calibration
from lotsen.fusion.seed_filters import SeedFilters, SeedFiltersConfig, YawFilterConfig
from lotsen.messages import GnssFix, ImuSample, MagSample, VesselState
from lotsen.model import DEFAULT_PARAMETERS, Environment, VesselModel, VesselParameters
from lotsen.model.geodetic import LocalFrame
from lotsen.sim import SimConfig, Simulator
from lotsen.sim.boat import SimulatedBoat

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
    boat: SimulatedBoat | None = None  # the simulated boat; None: the lake boat (not the filters' model)


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

    cal_samples = simulate_calibration_turn(config.seed, config.calibration_turn_s)
    cal = calibrate_from_turn(cal_samples)
    sim = Simulator(config.boat, config=SimConfig(seed=config.seed, environment=config.environment))
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
    ekf = ModelAidedEKF(ekf_model, cal, replace(config.ekf, origin=origin, gnss_antenna_m=sim.boat.gnss_antenna_m,
                                                        gnss_antenna_height_m=sim.boat.hull.gnss_antenna_height_m),
                        initial=init,
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
    ekf_codes: set[str] = set()
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
                        if not (t_out0 <= t < t_out1 + config.recovery_s):  # false alarms outside the outage
                            ekf_codes.update(f.health(t).fault_codes)
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
            r["fault_codes_seen"] = sorted(ekf_codes)  # integrity faults after the warm-up (no fault injected)
            # the water current (zero in the estimate without current states)
            c_true = config.environment.current_ne
            c_est = ekf.current_ne_mps
            r["current_true_ne_mps"] = (float(c_true[0]), float(c_true[1]))
            r["current_est_ne_mps"] = c_est
            r["current_err_end_mps"] = float(math.hypot(c_est[0] - c_true[0], c_est[1] - c_true[1]))
        results[name] = r
    return {"calibration": calib_report, "filters": results,
            "speed_max_mps": float(np.max(np.hypot(X[:, 3], X[:, 4]))),
            "truth_final": sim.truth()}


# -- integrity scenarios: faults injected into the messages the EKF sees ---------------
@dataclass(frozen=True)
class FaultCase:
    """A fault injected at `start_s` for `duration_s`; `expected` is the fault code the monitor
    must declare within `deadline_s` (the documented detection time, docs/fusion.md)."""

    name: str
    expected: str
    start_s: float
    duration_s: float
    deadline_s: float
    text: str = ""


FAULT_CASES: dict[str, FaultCase] = {c.name: c for c in (
    FaultCase("gnss_offset_20m_10s", "gnss.inconsistent", 30.0, 10.0, 1.0, "GNSS position 20 m north for 10 s"),
    FaultCase("gnss_offset_10m_120s", "gnss.inconsistent", 30.0, 120.0, 1.0, "GNSS position 10 m east for 120 s"),
    FaultCase("gnss_frozen_10s", "gnss.stuck", 30.0, 10.0, 1.0, "GNSS repeats its last fix for 10 s"),
    FaultCase("gyro_stuck_30s", "gyro.stuck", 30.0, 30.0, 1.0, "gyro frozen at its last value for 30 s"),
    FaultCase("accel_stuck_30s", "accel.stuck", 30.0, 30.0, 1.0, "accelerometer frozen for 30 s"),
    FaultCase("mag_stuck_30s", "mag.stuck", 30.0, 30.0, 1.0, "magnetometer frozen for 30 s"),
    FaultCase("heading_frozen_10s", "heading.frozen", 60.0, 10.0, 3.0, "heading estimate frozen for 10 s"),
    FaultCase("inputs_lost_1s", "fusion.starved", 30.0, 1.0, 0.25, "no sensor sample reaches the filter for 1 s"),
    FaultCase("mag_disturbance_20s", "mag.inconsistent", 30.0, 20.0, 1.0, "magnetometer offset by 15 uT for 20 s"),
    FaultCase("future_stamp_5s", "", 30.0, 0.0, 0.0, "one IMU sample stamped 5 s ahead (nothing to declare)"),
    FaultCase("imu_spikes_20s", "", 30.0, 20.0, 0.0, "2 % of IMU samples with large spikes (nothing to declare)"),
)}


def _freeze(value: Any, t: float) -> Any:
    """A copy of `value` (a sensor message) stamped t: a stuck sensor repeats itself."""
    return replace(value, stamp_s=t)


def run_fault_case(name: str, seed: int = 1, ekf_config: EkfConfig | None = None,
                   environment: Environment | None = None, health_hz: float = 10.0,
                   after_s: float = 20.0, estimator: str = "ekf",
                   seed_config: SeedFiltersConfig | None = None, start_s: float | None = None,
                   duration_s: float | None = None) -> dict[str, Any]:
    """One integrity scenario on the open-loop manoeuvre (current 0.1 m/s and wind 3 m/s by
    default): the EKF is fed the simulator's messages with the fault of FAULT_CASES[name]
    injected, and its health is read at `health_hz`. Returns the detection delay (s, None if
    never declared), the time the fault stayed declared after it ended, the largest position
    and heading errors from the fault's start to `after_s` after its end, the fault codes seen
    before the fault (false alarms) and the codes seen while it lasted."""

    case = FAULT_CASES[name]
    case = replace(case, start_s=case.start_s if start_s is None else start_s,
                   duration_s=case.duration_s if duration_s is None else duration_s)
    env = environment if environment is not None else Environment(
        current_speed_mps=0.1, current_to_deg=60.0, wind_speed_mps=3.0, wind_from_deg=200.0)
    sim = Simulator(config=SimConfig(seed=seed, environment=env))
    g = sim.config.gnss
    imu = sim.config.imu
    H = imu.earth_field_horizontal_uT
    (s00, s01), (s10, s11) = imu.soft_iron
    cal = MagCalibration(center=tuple(imu.hard_iron_uT), matrix=((H * s00, H * s01), (H * s10, H * s11)))
    init = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.0, heading_rad=sim.x[2], u_mps=0.0, v_mps=0.0, r_radps=0.0)
    cfg = replace(ekf_config or EkfConfig(), origin=(g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m),
                  gnss_antenna_m=sim.boat.gnss_antenna_m,  # measured on the hull
                  gnss_antenna_height_m=sim.boat.hull.gnss_antenna_height_m)
    if estimator == "ekf":
        ekf: Any = ModelAidedEKF(VesselModel(), cal, cfg, initial=init,
                                 initial_std=(0.5, 0.5, 0.2, 0.1, 0.1, 0.1, 0.02))
    else:
        ekf = SeedFilters(cal, replace(seed_config or SeedFiltersConfig(), origin=cfg.origin), initial=init,
                          heading_std_rad=0.2)
    t0, t1 = case.start_s, case.start_s + case.duration_s
    t_end = t1 + after_s
    frame = LocalFrame(*cfg.origin)  # the receiver's: a fix moved by metres in it

    def shifted(fix: GnssFix, north_m: float, east_m: float) -> GnssFix:
        n, e = frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m)
        lat, lon, _ = frame.to_geodetic(n + north_m, e + east_m)
        return replace(fix, lat_deg=lat, lon_deg=lon)

    held: dict[str, Any] = {}
    frozen_psi: list[float] = []
    every = max(1, int(round(1.0 / (health_hz * sim.config.dt_s))))
    first_seen: dict[str, float] = {}
    before: set[str] = set()
    during: set[str] = set()
    declared_until: float | None = None
    pos_err = hdg_err = 0.0
    flags_bad_s = 0.0
    series: list[tuple] = []  # (t, position error m, heading error deg, position_ok, heading_ok, codes)
    future_sent = False

    def tamper(m: Any, t: float) -> Any:
        nonlocal future_sent
        if not (t0 <= t < t1) and name != "future_stamp_5s":
            return m
        if name == "gnss_offset_20m_10s" and isinstance(m, GnssFix):
            return shifted(m, 20.0, 0.0)
        if name == "gnss_offset_10m_120s" and isinstance(m, GnssFix):
            return shifted(m, 0.0, 10.0)
        if name == "gnss_frozen_10s" and isinstance(m, GnssFix):
            return _freeze(held.setdefault("gnss", m), m.stamp_s)
        if name in ("gyro_stuck_30s", "accel_stuck_30s") and isinstance(m, ImuSample):
            last = held.setdefault("imu", m)
            if name == "gyro_stuck_30s":
                return replace(m, gyro_radps=last.gyro_radps)
            return replace(m, accel_mps2=last.accel_mps2)
        if name == "mag_stuck_30s" and isinstance(m, MagSample):
            return _freeze(held.setdefault("mag", m), m.stamp_s)
        if name == "inputs_lost_1s":
            return None
        if name == "future_stamp_5s" and isinstance(m, ImuSample) and t >= t0 and not future_sent:
            future_sent = True
            return replace(m, stamp_s=m.stamp_s + 5.0)
        return m

    steps = int(round(t_end / sim.config.dt_s))
    for k in range(steps):
        t = sim.t
        sim.mag.disturbance_uT = (15.0, 0.0) if name == "mag_disturbance_20s" and t0 <= t < t1 else (0.0, 0.0)
        sim.imu.spike_probability = 0.02 if name == "imu_spikes_20s" and t0 <= t < t1 else 0.0
        sim.command(_manoeuvre_command(t))
        msgs = sim.step()
        if k % 2 == 0:
            act = sim.actuator_state()
            act.stamp_s = t
            ekf.on_command(act)
        for m in msgs:
            m2 = tamper(m, t)
            if m2 is not None:
                feed(ekf, m2)
        if name == "heading_frozen_10s" and t0 <= t < t1:  # an estimator bug: the heading stops moving
            if estimator == "ekf":
                frozen_psi.append(frozen_psi[0] if frozen_psi else float(ekf.x[IPSI]))
                ekf.x[IPSI] = frozen_psi[0]
            else:
                frozen_psi.append(frozen_psi[0] if frozen_psi else ekf.yaw.x)
                ekf.yaw.x = frozen_psi[0]
        if k % every == 0 and t > 1.0:
            h = ekf.health(t)
            codes = set(h.fault_codes)
            for c in codes:
                first_seen.setdefault(c, t)
            if t < t0:
                before |= codes
            elif t < t1 + after_s:
                if t < t1 + 0.5:
                    during |= codes
                if case.expected in codes:
                    declared_until = t
                e = ekf.estimate(t)
                pe = math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1])
                he = abs(math.degrees(wrap_angle(e.heading_rad - sim.x[2])))
                pos_err, hdg_err = max(pos_err, pe), max(hdg_err, he)
                series.append((round(t, 2), pe, he, h.position_ok, h.heading_ok, tuple(sorted(codes))))
                if not (h.position_ok and h.heading_ok and h.velocity_ok):
                    flags_bad_s += every * sim.config.dt_s
    seen = first_seen.get(case.expected) if case.expected else None
    detect = seen - t0 if seen is not None and seen >= t0 else None
    used = {s: ekf.counters.used_fraction(s) for s in ("gyro", "accel", "mag", "gnss", "gnss_vel")}
    return {
        "case": name, "expected": case.expected, "deadline_s": case.deadline_s,
        "detect_s": detect, "declared_after_end_s": (declared_until - t1) if declared_until is not None else None,
        "max_position_error_m": pos_err, "max_heading_error_deg": hdg_err,
        "flags_bad_s": flags_bad_s, "codes_before": sorted(before), "codes_during": sorted(during),
        "used_fraction": used, "events": list(ekf.monitor.events),
        "counters": ekf.counters.as_dict(), "series": series,
    }
