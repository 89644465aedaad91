import math

import numpy as np
import pytest

from lotsen.control import (
    ControlConfig, HoldTarget, LOSController, LQController, PathFollower, PurePursuitController,
    StationKeeper, StationKeepingController, make_path_follower,
)
from lotsen.errors import ConfigError
from lotsen.harness.controller_loop import control_ticks, follow_path
from lotsen.model import Environment
from lotsen.sim import SimConfig, Simulator

from .conftest import circle_path, straight_path
from .helpers import assert_commands_within_limits

FALLBACKS = [PurePursuitController, LOSController, LQController]


# the last 5 s of a 35 s run from 0.5 m off the line, on the lake boat: pure pursuit (geometry only,
# no model, no integral) still swings 6.4 cm there and is within 4.2 cm by 50 s (< 5 cm on a boat
# equal to the default model)
@pytest.mark.parametrize("cls,tail_m", [(PurePursuitController, 0.08), (LOSController, 0.05), (LQController, 0.05)])
def test_straight_line_from_an_offset(cls, tail_m):
    c = cls()
    assert isinstance(c, PathFollower)
    run = follow_path(c, straight_path(30.0), 35.0, x0=[0.0, 0.5, 0.0, 0.0, 0.0, 0.0])
    cte, cmds, statuses = run.cross_track_m, run.commands, run.statuses
    assert np.max(np.abs(cte)) < 0.8
    assert np.max(np.abs(cte[-50:])) < tail_m
    assert_commands_within_limits(cmds)


@pytest.mark.parametrize("cls,bound", [(PurePursuitController, 0.15), (LOSController, 0.25), (LQController, 0.1)])
def test_curve_bounded_error(cls, bound):
    c = cls()
    run = follow_path(c, circle_path(), 60.0)
    cte, cmds = run.cross_track_m, run.commands
    assert c.done
    assert np.max(np.abs(cte)) < bound
    assert_commands_within_limits(cmds)


def test_factory_selects_and_validates():
    assert isinstance(make_path_follower(ControlConfig(controller="los")), LOSController)
    assert isinstance(make_path_follower(ControlConfig(controller="lq")), LQController)
    with pytest.raises(ConfigError, match="controller"):
        ControlConfig(controller="pid")


def _hold(env: Environment, duration_s: float, x0, target: HoldTarget):
    k = StationKeepingController()
    assert isinstance(k, StationKeeper)
    sim = Simulator(config=SimConfig(sensors=False, environment=env), x0=x0)
    errs, cmds = [], []
    for tick in control_ticks(sim, lambda t, s: k.update(t, s, target), until_s=duration_s):
        x = sim.x
        errs.append((math.hypot(x[0] - target.north_m, x[1] - target.east_m),
                     abs((x[2] - target.heading_rad + math.pi) % (2 * math.pi) - math.pi)))
        cmds.append(tick.command.as_tuple())
    return np.array(errs), np.array(cmds)


def test_station_keeping_holds_against_current_and_wind():
    """Field notes #1: hold position AND heading in a cross current with wind, using the bow thruster."""
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    target = HoldTarget(0.0, 0.0, 0.0)
    errs, cmds = _hold(env, 60.0, [0.0, 0.0, 0.0, 0.0, 0.0, 0.0], target)
    assert np.max(errs[-100:, 0]) < 0.1  # within 10 cm over the last 10 s (integral action)
    assert np.max(errs[-100:, 1]) < math.radians(3.0)
    assert np.max(np.abs(cmds[-100:, 4])) > 5.0  # the bow thruster is working
    assert_commands_within_limits(cmds)


def test_station_keeping_returns_to_the_target_and_turns_on_the_spot():
    errs, cmds = _hold(Environment(), 40.0, [1.0, -1.0, 1.0, 0.0, 0.0, 0.0], HoldTarget(0.0, 0.0, 0.0))
    assert errs[-1, 0] < 0.05 and errs[-1, 1] < math.radians(2.0)
    assert_commands_within_limits(cmds)


def _heading_wave(heading_rms_deg: float, step: int) -> tuple[float, float, float]:
    """The wave motion an estimate carries at control step `step` (10 Hz): heading only, a 0.13-cycle-per-
    step sine of the given RMS (what sets a controller's sea level; 0.013 deg is the estimator's start in
    flat water)."""
    return (0.0, 0.0, math.radians(heading_rms_deg) * math.sqrt(2.0) * math.sin(2.0 * math.pi * 0.13 * step))


def test_station_keeping_slows_its_loops_in_a_sea_and_not_in_flat_water():
    """Issue 46: in a sea the hold's natural frequencies fall to wave_position_freq_scale and
    wave_heading_freq_scale of calm as the sea level rises (K_p with the square, K_i the cube), so the wave motion left in the estimate is
    chased less; flat water (no wave motion, or the estimator's start-up's 0.013 deg) keeps the calm
    gains to the bit."""
    from dataclasses import replace as _replace

    from lotsen.control.station_keeping import StationKeepingConfig
    from lotsen.messages import VesselState

    state = VesselState(stamp_s=0.0, north_m=0.02, east_m=-0.01, heading_rad=0.01, u_mps=0.0, v_mps=0.0, r_radps=0.0)
    target = HoldTarget(0.0, 0.0, 0.0)

    def hold_after(heading_rms_deg: float) -> StationKeepingController:
        k = StationKeepingController()
        for i in range(200):  # four of the sea level's time constants
            k.update(0.1 * i, _replace(state, stamp_s=0.1 * i, wave_motion=_heading_wave(heading_rms_deg, i)), target)
        return k

    calm, flat, sea = StationKeepingController(), hold_after(0.013), hold_after(0.5)
    assert flat.sea.level == 0.0 and sea.sea.level == pytest.approx(1.0, abs=0.01)
    for a, b in ((flat.kp, calm.kp), (flat.kd, calm.kd), (flat.ki, calm.ki)):
        np.testing.assert_array_equal(a, b)
    cfg = StationKeepingConfig()
    s = np.array([cfg.wave_position_freq_scale, cfg.wave_position_freq_scale, cfg.wave_heading_freq_scale])
    assert np.all(s < 1.0)
    np.testing.assert_allclose(sea.kp, s ** 2 * calm.kp, rtol=0.02)
    np.testing.assert_allclose(sea.ki, s ** 3 * calm.ki, rtol=0.03)
    assert np.all(sea.kd < calm.kd)


def test_station_keeping_damps_on_a_filtered_velocity():
    """The hold's damping reads the velocity estimate through a low-pass (damping_filter_s): white noise
    on the estimate (an EKF's at 10 Hz) reaches the requested force at least 2x weaker than unfiltered,
    while a steady velocity is damped with the full K_d."""
    from dataclasses import replace as _replace

    from lotsen.control.station_keeping import StationKeepingConfig
    from lotsen.messages import VesselState

    assert StationKeepingConfig().damping_filter_s > 0
    target = HoldTarget(0.0, 0.0, 0.0)
    base = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.0, heading_rad=0.0, u_mps=0.0, v_mps=0.0, r_radps=0.0)

    def requests(config: StationKeepingConfig, nu: np.ndarray) -> np.ndarray:
        k = StationKeepingController(config=config)
        taus = []
        allocate = k.allocator.allocate
        k.allocator.allocate = lambda tau, nu=None: (taus.append(np.array(tau)), allocate(tau, nu))[1]
        for i, (u, v, r) in enumerate(nu):
            k.update(0.1 * i, _replace(base, stamp_s=0.1 * i, u_mps=u, v_mps=v, r_radps=r), target)
        return np.array(taus)

    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, [0.012, 0.012, 0.004], size=(300, 3))
    filtered = requests(StationKeepingConfig(), noise)
    raw = requests(StationKeepingConfig(damping_filter_s=0.0), noise)
    assert np.all(np.std(filtered, axis=0) < 0.5 * np.std(raw, axis=0))
    steady = np.tile([0.1, -0.05, 0.02], (100, 1))
    np.testing.assert_allclose(requests(StationKeepingConfig(), steady)[-1], requests(
        StationKeepingConfig(damping_filter_s=0.0), steady)[-1], rtol=1e-3)


def _figure_eight():
    """The closed figure eight of the examples: it starts at its crossing (20, 20) and passes it
    again half way, on the other branch (s ~ 48.2 m)."""
    from lotsen.planning import plan_route
    from lotsen.planning.io import load_route
    from lotsen.stack.stack import example_route

    return plan_route(load_route(example_route("figure_eight_loop")))


@pytest.mark.parametrize("cls", FALLBACKS)
def test_a_fallback_taking_over_at_the_crossing_localises_on_the_boats_branch(cls):
    """A fallback reset with the failed controller's progress (the boat at the figure eight's
    crossing, on its second pass) follows that branch: progress, heading and cross-track continue
    where the boat is. From progress 0 it would take the first branch there (heading ~90 deg off)."""
    from lotsen.messages import VesselState

    path = _figure_eight()
    s_cross = 0.5 * path.length_m
    p = path.sample(s_cross)
    state = VesselState(stamp_s=0.0, north_m=p.north_m, east_m=p.east_m, heading_rad=p.heading_rad,
                        u_mps=0.5, v_mps=0.0, r_radps=0.0)
    c = cls()
    c.reset(path, progress_m=s_cross - 0.3)  # the last localisation, a few steps back
    _cmd, st = c.update(0.0, state)
    assert st.progress_m == pytest.approx(s_cross, abs=0.05)
    assert c.progress_m == pytest.approx(s_cross, abs=0.05)
    assert abs(st.cross_track_error_m) < 0.05
    assert abs(st.heading_error_rad) < math.radians(2.0)
    # and the other branch at the same point is really elsewhere: the test can tell them apart
    first = path.project(p.north_m, p.east_m, s_hint_m=0.0, window_m=1.0)
    assert abs(math.remainder(first.heading_rad - p.heading_rad, 2 * math.pi)) > math.radians(30.0)


def test_los_taking_over_under_way_keeps_the_crab_angle():
    """Bumpless transfer: the LOS integral starts at the value whose guidance heading is the one
    the boat holds (crabbing 10 deg into a current), not at zero (which turns it down-current)."""
    from lotsen.messages import VesselState

    path = straight_path(30.0)
    crab = math.radians(-10.0)
    state = VesselState(stamp_s=0.0, north_m=5.0, east_m=0.0, heading_rad=crab, u_mps=0.5, v_mps=0.0,
                        r_radps=0.0)
    c = LOSController()
    c.reset(path, progress_m=5.0)
    c.update(0.0, state)
    cfg = c.config
    psi_d = -math.atan(cfg.integral_gain * c._e_int / cfg.lookahead_m)
    assert psi_d == pytest.approx(crab, abs=math.radians(1.0))
    c.reset(path)  # a route started at rest: the integral starts at zero
    c.update(0.0, VesselState(stamp_s=0.0, north_m=0.0, east_m=0.0, heading_rad=crab, u_mps=0.0, v_mps=0.0,
                              r_radps=0.0))
    assert abs(c._e_int) < 0.01


def test_los_heading_loop_slows_in_a_sea_and_not_in_flat_water():
    """LOSConfig.wave_heading_natural_freq_radps (set: 1.4 rad/s): with the heading's wave motion of a
    sea in the estimate (0.5 deg RMS) the heading loop acts as one set up at that natural frequency;
    with the largest flat water gave (0.013 deg) the calm loop to the bit; unset (the default), the
    calm loop in the sea too."""
    from dataclasses import replace as _replace

    from lotsen.control.fallback import LOSConfig, LOSController
    from lotsen.messages import VesselState

    path = straight_path(30.0)
    state = VesselState(stamp_s=0.0, north_m=1.0, east_m=0.2, heading_rad=0.1, u_mps=0.5, v_mps=0.0, r_radps=0.02)

    def tau_after(cfg: LOSConfig, heading_rms_deg: float) -> tuple[np.ndarray, float]:
        c = LOSController(config=cfg)
        c.reset(path)
        for k in range(200):  # four of the sea level's time constants
            c._observe(_replace(state, wave_motion=_heading_wave(heading_rms_deg, k)))
        c._observe(_replace(state, wave_motion=(0.0, 0.0, 0.0)))
        x = np.array(state.as_array_tuple())
        s, cte, hdg = c.path.project(x[0], x[1], 0.0)
        return c._tau(0.0, x, s, cte, hdg), c.sea.level

    assert LOSConfig().wave_heading_natural_freq_radps is None
    off_tau, _ = tau_after(LOSConfig(), 0.5)
    cfg = LOSConfig(wave_heading_natural_freq_radps=1.4)
    calm_tau, calm_level = tau_after(cfg, 0.0)
    np.testing.assert_array_equal(off_tau, calm_tau)
    flat_tau, flat_level = tau_after(cfg, 0.013)
    assert flat_level == 0.0 and calm_level == 0.0
    np.testing.assert_array_equal(flat_tau, calm_tau)
    sea_tau, sea_level = tau_after(cfg, 0.5)
    assert sea_level == pytest.approx(1.0, abs=0.01)
    slow_tau, _ = tau_after(_replace(cfg, heading_natural_freq_radps=cfg.wave_heading_natural_freq_radps), 0.0)
    np.testing.assert_allclose(sea_tau, slow_tau, rtol=0.01)
    assert abs(sea_tau[2]) < abs(calm_tau[2])  # the slower loop answers the same error less hard
