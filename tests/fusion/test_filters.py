"""Seed filters and the model-aided EKF on simulated data: wrap-around, outliers, NaN, outage."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np
import pytest

from lotsen.fusion import (
    EkfConfig, MagCalibration, ModelAidedEKF, SeedFilters, SeedFiltersConfig, YawKalmanFilter, wrap_angle,
)
from lotsen.fusion.common import feed
from lotsen.harness.estimator import calibrate_from_turn, simulate_calibration_turn
from lotsen.messages import ActuatorState, GnssFix, ImuSample, MagSample, ThrustCommand, VesselState
from lotsen.sim import SimConfig, Simulator

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def calibration() -> MagCalibration:
    return calibrate_from_turn(simulate_calibration_turn(seed=3, duration_s=40.0))


def _origin(sim: Simulator) -> tuple[float, float, float]:
    g = sim.config.gnss
    return (g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m)


def _run(sim: Simulator, filters: list[Any], duration_s: float, command: Callable[[float], tuple],
         tamper: Callable[[Any], Any] | None = None, probe: Callable[[float], None] | None = None) -> None:
    """Step the simulator, feed every filter the (possibly tampered) messages and actuator state."""
    for k in range(int(round(duration_s / sim.config.dt_s))):
        t = sim.t
        sim.command(command(t))
        msgs = sim.step()
        act = sim.actuator_state()
        act.stamp_s = t
        if tamper:
            msgs = [m2 for m2 in map(tamper, msgs) if m2 is not None]
        for f in filters:
            if k % 5 == 0:
                f.on_command(act)
            for m2 in msgs:
                feed(f, m2)
        if probe:
            probe(t)


def _turning(t: float) -> tuple:
    return (0.0, 0.0, 0.0, 0.0, 0.0) if t < 2.0 else (-10 * DEG, -10 * DEG, 50.0, 50.0, 0.0)


def _heading_err_deg(est: VesselState, sim: Simulator) -> float:
    return abs(math.degrees(wrap_angle(est.heading_rad - sim.x[2])))


# -- seed yaw filter (scalar, synthetic) ------------------------------------------------------------
def test_yaw_filter_crosses_wrap_and_gates_spike() -> None:
    truth = -170 * DEG
    kf = YawKalmanFilter(psi0=170 * DEG, P0=(30 * DEG) ** 2)
    rng = np.random.default_rng(0)
    history = []
    for _ in range(200):
        kf.time_update(0.0, 0.01)
        kf.measurement_update(truth + 0.02 * rng.standard_normal())
        history.append(kf.x)
    assert abs(wrap_angle(kf.x - truth)) < 1 * DEG
    # it went the short way across +-180, never through 0
    assert min(abs(h) for h in history) > 160 * DEG
    before = kf.x
    assert kf.measurement_update(truth + 90 * DEG) == "rejected"
    assert kf.x == before
    assert not kf.time_update(float("nan"), 0.01) and not kf.time_update(50.0, 0.01)
    assert kf.x == before


# -- both filters in the simulator --------------------------------------------------------------
@pytest.mark.parametrize("kind", ["seed", "ekf"])
def test_converges_from_wrong_heading_across_wrap(kind: str, calibration: MagCalibration) -> None:
    sim = Simulator(config=SimConfig(seed=11), x0=(0, 0, 175 * DEG, 0, 0, 0))
    init = VesselState(stamp_s=0.0, north_m=0, east_m=0, heading_rad=-150 * DEG, u_mps=0, v_mps=0, r_radps=0)
    if kind == "seed":
        f: Any = SeedFilters(calibration, SeedFiltersConfig(origin=_origin(sim)), initial=init,
                             heading_std_rad=math.pi)
    else:
        f = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim)), initial=init)
    _run(sim, [f], 15.0, _turning)
    est = f.estimate(sim.t)
    assert _heading_err_deg(est, sim) < 2.0
    assert math.hypot(est.north_m - sim.x[0], est.east_m - sim.x[1]) < 0.1
    assert math.hypot(est.u_mps - sim.x[3], est.v_mps - sim.x[4]) < 0.15


def test_ekf_outliers_do_not_move_estimate(calibration: MagCalibration) -> None:
    sim = Simulator(config=SimConfig(seed=12))
    ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=sim.boat.gnss_antenna_m))
    seed = SeedFilters(calibration, SeedFiltersConfig(origin=_origin(sim)))
    _run(sim, [ekf, seed], 20.0, _turning)
    deg_per_m = 1.0 / 111_000.0
    spikes = {"gnss": 0, "mag": 0}
    before: dict[str, VesselState] = {}
    errs: list[tuple[float, float]] = []

    def tamper(m: Any) -> Any:
        # one 20 m GNSS jump and one magnetometer spike 0.5 s later
        if isinstance(m, GnssFix) and spikes["gnss"] == 0 and m.stamp_s >= 20.5:
            spikes["gnss"] = 1
            before["ekf"], before["seed"] = ekf.estimate(m.stamp_s), seed.estimate(m.stamp_s)
            return dataclasses.replace(m, lat_deg=m.lat_deg + 20.0 * deg_per_m)
        if isinstance(m, MagSample) and spikes["mag"] == 0 and m.stamp_s >= 21.0:
            spikes["mag"] = 1
            # same norm, heading turned by 60 deg: only the innovation gate can catch it
            c = calibration
            psi = sim.x[2] + 60 * DEG
            w = np.array([math.cos(psi), -math.sin(psi)])
            raw = np.array(c.matrix) @ w + np.array(c.center)
            return MagSample(stamp_s=m.stamp_s, field_uT=(raw[0], raw[1], m.field_uT[2]))
        return m

    def probe(t: float) -> None:
        if 20.4 < t < 22.0:
            e = ekf.estimate(t)
            errs.append((math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1]), _heading_err_deg(e, sim)))

    rej_gnss, rej_mag = ekf.counters.rejected.get("gnss", 0), ekf.counters.rejected.get("mag", 0)
    _run(sim, [ekf, seed], 2.0, _turning, tamper, probe)
    assert spikes == {"gnss": 1, "mag": 1}
    assert ekf.counters.rejected.get("gnss", 0) == rej_gnss + 1
    assert ekf.counters.rejected.get("mag", 0) == rej_mag + 1
    assert max(p for p, _ in errs) < 0.05 and max(h for _, h in errs) < 1.5
    # the seed filters gate the jump's velocity difference and the heading spike too
    assert seed.counters.rejected.get("gnss", 0) >= 1 and seed.counters.rejected.get("mag", 0) >= 1
    s = seed.estimate(sim.t)
    assert math.hypot(s.north_m - sim.x[0], s.east_m - sim.x[1]) < 0.1 and _heading_err_deg(s, sim) < 2.0


@pytest.mark.parametrize("kind", ["seed", "ekf"])
def test_nan_and_missing_samples_are_skipped(kind: str, calibration: MagCalibration) -> None:
    sim = Simulator(config=SimConfig(seed=13))
    if kind == "seed":
        f: Any = SeedFilters(calibration, SeedFiltersConfig(origin=_origin(sim)))
    else:
        f = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim)))
    rng = np.random.default_rng(1)
    nan = float("nan")

    def tamper(m: Any) -> Any:
        u = rng.random()
        if u < 0.2:
            return None  # missing
        if u < 0.3:  # NaN in every kind of message
            if isinstance(m, ImuSample):
                return ImuSample(stamp_s=m.stamp_s, gyro_radps=(0, 0, nan), accel_mps2=(nan, 0, -9.81))
            if isinstance(m, MagSample):
                return MagSample(stamp_s=m.stamp_s, field_uT=(nan, nan, nan))
            if isinstance(m, GnssFix):
                return dataclasses.replace(m, lat_deg=nan)
        return m

    _run(sim, [f], 25.0, _turning, tamper)
    f.on_command(ThrustCommand(stamp_s=sim.t, n1_rps=nan))
    f.on_imu(ImuSample(stamp_s=nan, gyro_radps=(0, 0, 0), accel_mps2=(0, 0, -9.81)))
    est = f.estimate(sim.t)
    assert all(math.isfinite(v) for v in est.as_array_tuple() + est.std)
    assert sum(f.counters.skipped.values()) > 100
    assert _heading_err_deg(est, sim) < 2.0
    assert math.hypot(est.north_m - sim.x[0], est.east_m - sim.x[1]) < 0.1


def test_ekf_position_through_10s_gnss_outage(calibration: MagCalibration) -> None:
    sim = Simulator(config=SimConfig(seed=14))
    ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=sim.boat.gnss_antenna_m))
    _run(sim, [ekf], 25.0, _turning)
    sim.gnss.outage = True
    errs: list[float] = []
    stds: list[float] = []

    def probe(t: float) -> None:
        e = ekf.estimate(t)
        errs.append(math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1]))
        stds.append(math.hypot(e.std[0], e.std[1]))

    _run(sim, [ekf], 10.0, lambda t: (8 * DEG, 8 * DEG, 60.0, 60.0, 0.0), probe=probe)
    assert max(errs) < 0.5  # bound for a 10 s outage at ~1 m/s in a turn
    assert stds[-1] > 3 * stds[0]  # the covariance says it is dead reckoning
    sim.gnss.outage = False
    _run(sim, [ekf], 3.0, lambda t: (0.0, 0.0, 60.0, 60.0, 0.0))
    e = ekf.estimate(sim.t)
    assert math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1]) < 0.05  # re-acquired


def test_ekf_with_model_error_matching_off_still_uses_the_accelerometer(calibration: MagCalibration) -> None:
    """`model_error_time_s = 0` switches the covariance matching off (EkfConfig), not the accelerometer:
    its noise once divided by it (0 / 0), and every accelerometer sample was skipped as non-finite."""
    sim = Simulator(config=SimConfig(seed=14))
    ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=sim.boat.gnss_antenna_m,
                                                                  model_error_time_s=0.0))
    _run(sim, [ekf], 10.0, _turning)
    assert ekf.counters.used.get("accel", 0) > 100
    assert ekf.counters.skipped.get("accel", 0) == 0
    assert np.all(np.isfinite(ekf.P))


def test_ekf_thrust_command_used_without_actuator_state() -> None:
    ekf = ModelAidedEKF(initial=VesselState(stamp_s=0.0, north_m=0, east_m=0, heading_rad=0, u_mps=0,
                                            v_mps=0, r_radps=0))
    ekf.on_command(ThrustCommand(stamp_s=0.0, n1_rps=60.0, n2_rps=60.0))
    assert ekf.estimate(5.0).u_mps > 0.5  # the model drives the prediction
    ekf.on_command(ActuatorState(stamp_s=0.1, alpha1_rad=0, alpha2_rad=0, n1_rps=0, n2_rps=0, nt_rps=0))
    ekf.on_command(ThrustCommand(stamp_s=0.2, n1_rps=60.0, n2_rps=60.0))  # ignored: achieved values are fresh
    assert ekf.u_act[2] == 0.0


def test_ekf_process_jacobian_matches_finite_differences(calibration: MagCalibration) -> None:
    """The EKF's df/dx with the current states (the model's `_jacobians_current` plus the current
    columns) is the derivative of its own process model."""
    sim = Simulator(config=SimConfig(seed=3))
    ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=sim.boat.gnss_antenna_m))
    assert ekf.i_cur is not None
    x = np.zeros(ekf.n)
    x[:6] = [1.0, -2.0, 0.7, 0.45, -0.06, 0.12]
    x[ekf.i_cur:ekf.i_cur + 2] = [0.12, -0.2]
    u = (0.2, -0.1, 40.0, 35.0, 10.0)
    J = ekf._dynamics_jacobian(x, u)
    h = 1e-6
    for j in range(ekf.n):
        dx = np.zeros(ekf.n)
        dx[j] = h
        fd = (np.array(ekf._rhs(x + dx, u)) - np.array(ekf._rhs(x - dx, u))) / (2 * h)
        assert np.allclose(J[:, j], fd, atol=1e-6, rtol=1e-5), (j, J[:, j], fd)


def test_ekf_with_the_antenna_lever_arm_tracks_the_hull_origin_in_turns(calibration: MagCalibration) -> None:
    """The receiver locates the antenna, 30 cm ahead of the origin: in a turn the EKF that knows
    the lever arm estimates the origin; the one that does not is off by about the lever arm."""
    from lotsen.sim import SimulatedBoat

    errors = {}
    for arm in ((0.0, 0.0), (0.3, 0.0)):
        sim = Simulator(SimulatedBoat(gnss_antenna_m=(0.3, 0.0)), config=SimConfig(seed=21))
        ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=arm))
        _run(sim, [ekf], 20.0, _turning)
        errs: list[float] = []

        def probe(t: float) -> None:
            e = ekf.estimate(t)
            errs.append(math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1]))

        _run(sim, [ekf], 20.0, lambda t: (15 * DEG, 15 * DEG, 60.0, 60.0, 0.0), probe=probe)
        errors[arm] = float(np.sqrt(np.mean(np.square(errs))))
    assert errors[(0.3, 0.0)] < 0.05 < 0.2 < errors[(0.0, 0.0)], errors


def _crash_stops(t: float) -> tuple:
    """Full ahead turning, full astern, ahead again, the azimuths against each other: the
    manoeuvres where the model's thruster forces are furthest from a real boat's."""
    if t < 3.0:
        return (0.0, 0.0, 0.0, 0.0, 0.0)
    if t < 9.0:
        return (-6 * DEG, 18 * DEG, 100.0, 100.0, -80.0)
    if t < 12.0:
        return (-6 * DEG, 6 * DEG, -100.0, -100.0, 80.0)
    if t < 16.0:
        return (20 * DEG, 20 * DEG, 100.0, 60.0, 80.0)
    if t < 18.0:
        return (0.0, 0.0, -100.0, 100.0, -80.0)
    return (0.0, 0.0, 30.0, 30.0, 0.0)


@pytest.mark.parametrize("seed", [0, 1])
def test_ekf_stays_consistent_through_crash_stops_on_a_boat_that_is_not_its_model(
        calibration: MagCalibration, seed: int) -> None:
    """The lake boat (weaker astern, a dead band, coefficients 10-20 % off the default model) in
    current and wind, driven full ahead and full astern: the model's deceleration is wrong by ~40 %.
    The filter must say so in its covariance (actuator force uncertainty) rather than trust the
    model until the accelerometer and GNSS fall out of its gates: no sensor declared inconsistent,
    the speed error within 3 reported sigma, position within a few centimetres."""
    from lotsen.harness.lab_loop import LAB_ENVIRONMENT

    sim = Simulator(config=SimConfig(seed=seed, environment=LAB_ENVIRONMENT))
    ekf = ModelAidedEKF(calibration=calibration, config=EkfConfig(origin=_origin(sim), gnss_antenna_m=sim.boat.gnss_antenna_m))
    faults: set[str] = set()
    pos_err: list[float] = []
    u_sigmas: list[float] = []

    def probe(t: float) -> None:
        if t < 2.0 or round(t * 100) % 5:
            return
        e = ekf.estimate(t)
        faults.update(f.split(" (")[0] for f in ekf.health(t).faults)
        pos_err.append(math.hypot(e.north_m - sim.x[0], e.east_m - sim.x[1]))
        u_sigmas.append(abs(e.u_mps - sim.x[3]) / e.std[3])

    _run(sim, [ekf], 22.0, _crash_stops, probe=probe)
    assert not faults, faults
    assert max(pos_err) < 0.05, max(pos_err)
    assert np.mean(np.array(u_sigmas) < 3.0) > 0.97, np.percentile(u_sigmas, [50, 90, 99])


def test_a_real_current_is_still_learnt() -> None:
    """The current's start uncertainty is 0.15 m/s (EkfConfig.P0_current_std_mps; the hull B case it
    guards against: tests/physics/test_hull_b_experiment.py). A stronger current, 0.2 m/s on the
    turning manoeuvre, is still learnt to within 3 cm/s."""
    from lotsen.harness.estimator import EvaluationConfig, evaluate
    from lotsen.model.environment import Environment

    env = Environment(current_speed_mps=0.2, current_to_deg=60.0, wind_speed_mps=3.0, wind_from_deg=200.0)
    ekf = evaluate(EvaluationConfig(duration_s=90.0, outage_start_s=75.0, calibration_turn_s=40.0, seed=5,
                                    environment=env))["filters"]["ekf"]
    assert ekf["current_err_end_mps"] < 0.03, ekf["current_est_ne_mps"]
    assert ekf["fault_codes_seen"] == []

