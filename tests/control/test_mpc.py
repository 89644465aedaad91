import itertools
from dataclasses import replace
import math
from types import SimpleNamespace

import numpy as np
import osqp
import pytest

from lotsen.control import MPCConfig, MPCController, PathFollower
from lotsen.harness.controller_loop import control_ticks, follow_path
from lotsen.messages import VesselState
from lotsen.model import Environment, VesselModel

from .conftest import circle_path, straight_path
from .helpers import WEIGHTS_BEFORE_RETUNING, assert_commands_within_limits, one_metre_off_at_rest, rms


# OSQP's wall-clock time limit is a product safeguard; in unit tests it would make the outcome depend on
# the machine's load (a loaded CI runner hit it and counted an extra failure), so the tests switch it off.
NO_TIME_LIMIT = MPCConfig(time_limit_s=0.0)


@pytest.fixture(scope="module")
def mpc() -> MPCController:
    return MPCController(config=NO_TIME_LIMIT)


def test_follows_the_path_follower_protocol(mpc):
    """The supervisor drives every follower alike: reset(path), update(t, state) -> (command, status), done."""
    assert isinstance(mpc, PathFollower)
    path = straight_path(10.0)
    mpc.reset(path)
    assert not mpc.done
    cmd, status = mpc.update(0.0, VesselState(stamp_s=0.0, north_m=0.0, east_m=0.1, heading_rad=0.0,
                                              u_mps=0.0, v_mps=0.0, r_radps=0.0))
    assert cmd.n1_rps > 0.0 and cmd.n2_rps > 0.0  # at rest at the start: it drives ahead
    assert status.cross_track_error_m == pytest.approx(0.1, abs=1e-6) and status.status == "ok"


def test_straight_line_converges_from_an_offset(mpc):
    path = straight_path(30.0)
    run = follow_path(mpc, path, 30.0, x0=[0.0, 0.6, 0.0, 0.0, 0.0, 0.0])
    cte, cmds, statuses = run.cross_track_m, run.commands, run.statuses
    assert abs(cte[0]) == pytest.approx(0.6, abs=1e-6)
    assert np.max(np.abs(cte)) <= 0.61  # no overshoot beyond the start offset
    assert np.max(np.abs(cte[-50:])) < 0.01  # converged after 25 s
    assert_commands_within_limits(cmds)
    assert all(s.status == "ok" for s in statuses)
    assert mpc.failures == 0


def test_curve_is_tracked_closely(mpc):
    path = circle_path()
    run = follow_path(mpc, path, 60.0)
    cte, cmds, statuses = run.cross_track_m, run.commands, run.statuses
    assert mpc.done
    assert rms(cte) < 0.03
    assert np.max(np.abs(cte)) < 0.08
    assert_commands_within_limits(cmds)
    # the prediction is published for display
    assert len(statuses[-1].predicted_north_m) == mpc.N + 1


def test_current_and_wind_are_compensated(mpc):
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    run = follow_path(mpc, straight_path(25.0), 45.0, environment=env)
    cte, cmds = run.cross_track_m, run.commands
    assert np.max(np.abs(cte[100:])) < 0.03  # offset-free after the disturbance observer settled
    assert_commands_within_limits(cmds)


def test_prediction_matches_the_simulated_motion():
    """The LTV prediction 1 s ahead lands near where the simulated boat actually goes."""
    c = MPCController(config=NO_TIME_LIMIT)
    path = circle_path()
    c.reset(path)
    from lotsen.sim import SimConfig, Simulator

    errs = []
    sim = Simulator(config=SimConfig(sensors=False), x0=[0, 0, 0, 0, 0, 0])
    ticks = list(itertools.islice(control_ticks(sim, c.update), 120))
    xs = [tick.x for tick in ticks]
    preds = [(tick.status.predicted_north_m[10], tick.status.predicted_east_m[10]) for tick in ticks]
    for k in range(40, 110):
        errs.append(math.hypot(preds[k][0] - xs[k + 10][0], preds[k][1] - xs[k + 10][1]))
    assert max(errs) < 0.05


def _failing_solve(kind: str):
    def solve(*args, **kwargs):
        if kind == "status":
            return SimpleNamespace(x=None, info=SimpleNamespace(status_val=osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
                                                                  status="maximum iterations reached"))
        return SimpleNamespace(x=np.full(200_000, np.nan)[:solve.nz],
                               info=SimpleNamespace(status_val=osqp.SolverStatus.OSQP_SOLVED, status="solved"))
    return solve


@pytest.mark.parametrize("kind", ["status", "nan"])
def test_solver_failure_never_reaches_the_actuators(monkeypatch, kind):
    cfg = MPCConfig(max_fallback_steps=4, time_limit_s=0.0)
    c = MPCController(config=cfg)
    path = straight_path(30.0)
    c.reset(path)
    from lotsen.sim import SimConfig, Simulator

    sim = Simulator(config=SimConfig(sensors=False), x0=[0, 0.2, 0, 0, 0, 0])
    ticks = control_ticks(sim, c.update)
    for _ in itertools.islice(ticks, 30):  # healthy start
        pass
    plan = c._plan.copy()
    solve = _failing_solve(kind)
    solve.nz = c.nz
    monkeypatch.setattr(c.solver, "solve", solve)
    statuses, cmds = [], []
    for tick in itertools.islice(ticks, 8):
        assert tick.command.is_finite()
        cmds.append(tick.command.as_tuple())
        statuses.append(tick.status.status)
    assert all(s.startswith("fallback_plan") for s in statuses[:4])
    assert all(s.startswith("safe_stop") for s in statuses[4:])
    assert cmds[-1] == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert c.failures == 8
    # the fallback plays the stored plan, shifted (within the rate limits of the actuators)
    expected = c.w_to_command(plan[1])
    assert cmds[0][0] == pytest.approx(expected[0], abs=1e-9)
    # recovery once the solver works again
    monkeypatch.undo()
    for tick in itertools.islice(ticks, 10):
        st = tick.status
    assert st.status == "ok"
    assert st.failures == 8


def test_non_finite_state_gives_a_safe_command():
    c = MPCController()
    c.reset(straight_path(10.0))
    from lotsen.messages import VesselState

    cmd, st = c.update(0.0, VesselState(stamp_s=0.0, north_m=math.nan, east_m=0.0, heading_rad=0.0,
                                        u_mps=0.0, v_mps=0.0, r_radps=0.0))
    assert cmd.is_finite()
    assert st.failures == 1 and st.status.startswith("safe_stop")


def test_sparsity_pattern_is_fixed_and_data_updated_in_place(mpc):
    """P and A keep the pattern of the setup; only the data arrays change."""
    c = MPCController(config=MPCConfig(horizon=20))
    c.reset(circle_path())
    from lotsen.messages import VesselState

    st = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.1, heading_rad=0.05, u_mps=0.4, v_mps=0.0, r_radps=0.0)
    Ax0 = c._Ax.copy()
    c.update(0.0, st)
    assert c._Ax.shape == Ax0.shape and not np.allclose(c._Ax, Ax0)
    # the identity parts (x0 row, x_{k+1} coefficients, bounds and rate rows) are untouched
    untouched = np.ones_like(Ax0, dtype=bool)
    untouched[c._a_dyn_pos.ravel()] = False
    untouched[c._a_lag_pos.ravel()] = False  # the ESC lag's thrust columns are rewritten with Bd as well
    untouched[c._a_sigma_pos] = False  # the propellers' directions in the reversal guard
    np.testing.assert_array_equal(c._Ax[untouched], Ax0[untouched])


def test_stabilises_the_open_loop_unstable_yaw_at_high_speed(mpc):
    """Above ~0.52 m/s the sway-yaw dynamics are unstable (model stability report); at 1.4 m/s the
    MPC converges from an offset and keeps the speed."""
    run = follow_path(mpc, straight_path(60.0, speed_mps=1.4), 40.0, x0=[0.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    cte, cmds, sim = run.cross_track_m, run.commands, run.sim
    assert np.max(np.abs(cte[-30:])) < 0.01
    assert sim.x[3] == pytest.approx(1.4, abs=0.05)
    assert_commands_within_limits(cmds)


def test_reversal_settings_are_validated():
    with pytest.raises(ValueError, match="reversal_cost_azimuth_per_N"):
        MPCConfig(reversal_cost_azimuth_per_N=-1.0)
    with pytest.raises(ValueError, match="reversal_dwell_s"):
        MPCConfig(reversal_dwell_s=math.nan)
    with pytest.raises(ValueError, match="reversal_band_rps"):
        MPCConfig(reversal_band_rps=6.0, reversal_hysteresis_rps=5.0)


def test_modelled_esc_speed_follows_the_simulated_propellers():
    """The achieved speeds the prediction starts from (the MPC's ESC model) are the simulator's."""
    c = MPCController(config=NO_TIME_LIMIT)
    c.reset(circle_path())
    from lotsen.sim import SimConfig, Simulator

    # ideal model: this checks the ESC model's implementation against the same equations
    sim = Simulator(c.model, config=SimConfig(sensors=False), x0=[0, 0, 0, 0, 0, 0])
    errs = []
    for _ in itertools.islice(control_ticks(sim, c.update), 60):
        errs.append(np.max(np.abs(np.array(sim.actuators.state[2:]) - c._n_achieved)))
    assert max(errs) < 0.5  # rev/s, of up to 100


def test_reversal_penalty_switches_off():
    """lambda = 0 and no ESC lag is the issue-5 QP: same decision vector length minus the slacks' effect."""
    off = MPCController(config=MPCConfig(reversal_cost_azimuth_per_N=0.0, reversal_cost_bow_per_N=0.0,
                                         esc_in_prediction=False, time_limit_s=0.0))
    assert off._esc_beta == 1.0
    on = MPCController(config=NO_TIME_LIMIT)
    assert 0.3 < on._esc_beta < 0.6
    run = follow_path(off, straight_path(10.0), 10.0)
    cte, cmds, statuses = run.cross_track_m, run.commands, run.statuses
    assert all(s.status == "ok" for s in statuses)


def test_thrust_authority_is_kept_at_zero_propeller_speed():
    """In q = n|n|/n_max^2 the thrust is linear, also at n = 0: the linearised input matrix of a
    propeller at rest matches finite differences of the RK4 step (before 2026-11-23 it was 0 there,
    so the bow thruster was never used and an azimuth that reached zero stayed there)."""
    from lotsen.control.mpc import _linearise_horizon
    from lotsen.model.dynamics import rk4_step

    c = MPCController(config=NO_TIME_LIMIT)
    mq = c.model.arrays.packed
    xb = np.array([[0.0, 0.0, 0.3, 0.5, 0.05, 0.1]] * 2)
    w0 = np.array([0.1, -0.2, 0.0, 0.3, 0.0])  # azimuth 1 and the bow thruster at rest
    Ad, Bd, cc = np.zeros((1, 6, 6)), np.zeros((1, 6, 5)), np.zeros((1, 6))
    _linearise_horizon(xb, w0[None, :], c.scale, mq, 0.1, 0.0, 0.0, 0.0, 5.0, 0.0, 0.0, Ad, Bd, cc)

    def step(w):
        q = w[2:] * c.scale[2:]
        n = np.sign(q) * np.sqrt(np.abs(q))
        return np.array(rk4_step(tuple(xb[0]), (w[0], w[1], *n), mq, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1)[0])

    for j in (2, 4):
        e = np.zeros(5)
        e[j] = 0.01
        fd = (step(w0 + e) - step(w0 - e)) / 0.02
        assert np.abs(Bd[0, 3:, j]).max() > 1e-3
        np.testing.assert_allclose(Bd[0, 3:, j], fd[3:], rtol=0.05, atol=2e-4)


def test_the_estimated_current_enters_the_prediction():
    """Observer off, a known 0.2 m/s beam current in VesselState.current_ne_mps: the 1 s prediction
    lands where the simulated boat goes (8 cm off without the current, measured), and tracks."""
    import dataclasses

    from lotsen.sim import SimConfig, SimulatedBoat, Simulator

    env = Environment(current_speed_mps=0.2, current_to_deg=90.0)
    errs_by, cte_by = {}, {}
    for use in (False, True):
        c = MPCController(config=MPCConfig(time_limit_s=0.0, disturbance_gain=0.0, current_in_prediction=use))
        c.reset(circle_path())
        # ideal model: this checks the prediction's current terms against the same equations
        sim = Simulator(SimulatedBoat.ideal_for(c.model), config=SimConfig(sensors=False, environment=env),
                        x0=[0, 0, 0, 0, 0, 0])
        # the current as the EKF estimates it, here perfect
        ticks = list(itertools.islice(control_ticks(
            sim, lambda t, s: c.update(t, dataclasses.replace(s, current_ne_mps=env.current_ne))), 120))
        preds = [(tick.status.predicted_north_m[10], tick.status.predicted_east_m[10]) for tick in ticks]
        xs = [tick.x for tick in ticks]
        cte = [tick.status.cross_track_error_m for tick in ticks]
        errs_by[use] = max(math.hypot(preds[k][0] - xs[k + 10][0], preds[k][1] - xs[k + 10][1]) for k in range(40, 110))
        cte_by[use] = rms(cte[50:])
    assert errs_by[True] < 0.01
    assert errs_by[False] > 5 * errs_by[True]
    assert cte_by[True] < 0.01 and cte_by[True] < cte_by[False]


def test_no_propeller_reversals_in_steady_tracking_on_the_ekf():
    """Figure eight in 0.1 m/s current + 3 m/s wind on the EKF, 60 s, on the lake boat: the reversal
    guard keeps the achieved propeller speeds to <= 0.1 sign changes per second (all three
    together; without a guard ~1.3 per second) and the tracking close. Measured seeds 0-2: 5
    reversals each (azimuth 1 once, azimuth 2 and the bow thruster twice, at the same places of the
    route: needed, not chattering; 40 s alone would hold all 5), 0.8-1.0 cm."""
    from lotsen.planning import plan_route
    from lotsen.planning.io import load_route
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
    from lotsen.sim.activity import propeller_reversals

    from pathlib import Path

    path = plan_route(load_route(Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight_loop.yaml"))
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    mc = MissionConfig(environment=env, seed=0, sensors=True, max_duration_s=60.0)
    follower = MPCController(config=NO_TIME_LIMIT)
    r = run_mission(path, follower, mc, estimator=make_sim_ekf(mc, path))
    assert r.n_achieved is not None and r.metrics["reversals_counted_on"] == "achieved speeds"
    span = float(r.t[-1] - r.t[0])
    assert sum(propeller_reversals(r.n_achieved)) / span <= 0.1
    assert r.metrics["reversals_per_s"] <= 0.1
    assert r.metrics["cross_track_rms_m"] < 0.015


@pytest.mark.parametrize("progress, iterations", [("time", 1), ("predicted", 1), ("time", 2)])
def test_time_reference_and_second_qp_iteration_track_a_curve(progress, iterations):
    """The bench's variants beside do-mpc (the time-parameterised reference, a second QP per step
    re-linearised along the first solution) are working controllers, not only benchmark settings."""
    c = MPCController(config=MPCConfig(time_limit_s=0.0, progress_reference=progress, qp_iterations=iterations))
    run = follow_path(c, circle_path(), 60.0)
    cte, cmds, statuses = run.cross_track_m, run.commands, run.statuses
    assert c.done and c.failures == 0
    assert rms(cte) < 0.03 and np.max(np.abs(cte)) < 0.08
    assert_commands_within_limits(cmds)


def test_reference_and_iteration_settings_are_validated():
    with pytest.raises(ValueError, match="progress_reference"):
        MPCConfig(progress_reference="space")
    with pytest.raises(ValueError, match="qp_iterations"):
        MPCConfig(qp_iterations=0)
    with pytest.raises(ValueError, match="reiterate_dw"):
        MPCConfig(reiterate_dw=-0.1)


def test_warm_up_compiles_every_signature_the_control_loop_uses():
    """The live stack warms the model and the MPC at start; a numba signature first met in the loop
    (e.g. a Path's read-only arrays, a float where the warm-up passed an int) compiles or loads for
    0.3 s at AUTO and trips the core's watchdog. After the warm-ups a mission on the EKF must add no
    compiled signature to the controller's, the path projection's or the model's functions."""
    numba = pytest.importorskip("numba")
    from pathlib import Path

    from lotsen.control import mpc as mpc_module
    from lotsen.model import VesselModel, dynamics
    from lotsen.model import polyline
    from lotsen.planning import plan_route
    from lotsen.planning.io import load_route
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission

    model = VesselModel()
    model.warm_up()
    follower = MPCController(model, config=NO_TIME_LIMIT)
    follower.warm_up()
    assert follower.path is None and follower.solve_times_ms == []
    jitted = {f"{m.__name__}.{n}": f for m in (mpc_module, polyline, dynamics) for n, f in vars(m).items()
              if isinstance(f, numba.core.registry.CPUDispatcher) and f.__module__ == m.__name__}
    assert "lotsen.model.polyline.project_window" in jitted
    before = {n: len(f.overloads) for n, f in jitted.items()}
    path = plan_route(load_route(Path(__file__).resolve().parents[2] / "examples" / "routes" / "figure_eight.yaml"))
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    cfg = MissionConfig(environment=env, sensors=True, max_duration_s=15.0)
    run_mission(path, follower, cfg, model=model, estimator=make_sim_ekf(cfg, path, model))
    assert {n: len(f.overloads) - before[n] for n, f in jitted.items() if len(f.overloads) != before[n]} == {}


@pytest.mark.parametrize("command", [(0.3, 0.3, 40.0, 40.0, 0.0), (0.3, 0.3, 75.0, 75.0, -40.0)])
def test_servo_and_esc_lags_make_the_prediction_match_the_simulator(command):
    """Issue 19: the prediction's input over a step is the step average of the servo ramp (at its
    slew limit) and of the ESC response, not the new set-point. One step after a full-rate angle
    step (and a thrust step), the model on that input predicts the simulator's velocities several
    times better than on the set-point."""
    from lotsen.model.dynamics import rk4_step
    from lotsen.sim import SimConfig, Simulator

    c = MPCController()
    mq = c.model.arrays.packed
    # ideal model: the prediction's lag rule against the very equations it implements
    sim = Simulator(c.model, config=SimConfig(sensors=False), x0=[0.0, 0.0, 0.0, 0.4, 0.0, 0.0])
    previous = (0.0, 0.0, 40.0, 40.0, 0.0)
    sim.command(previous)
    sim.advance(3.0)  # steady: servos at 0, propellers at 40 rev/s
    c._commit(previous)
    c._n_achieved = np.array(sim.actuators.state[2:])
    x = tuple(sim.x)
    effective = c._effective_command(command, previous)
    sim.command(command)
    sim.advance(c.config.dt_s)
    truth = np.array(sim.x[3:])
    on_set_point, _ = rk4_step(x, command, mq, 0.0, 0.0, 0.0, 0.0, 0.0, c.config.dt_s)
    on_effective, _ = rk4_step(x, effective, mq, 0.0, 0.0, 0.0, 0.0, 0.0, c.config.dt_s)
    err_set_point = np.linalg.norm(np.array(on_set_point[3:]) - truth)
    err_effective = np.linalg.norm(np.array(on_effective[3:]) - truth)
    assert err_effective < 0.25 * err_set_point
    assert 0.1 < effective[0] < 0.2  # a 0.3 rad step at 180 deg/s: the ramp takes ~95 % of the step


def test_adaptive_second_qp_runs_in_transients_not_in_steady_tracking():
    """The second QP per step (re-linearised along the first one's solution) runs while the plan
    moves by more than `reiterate_dw`: from rest 1 m off the path, and once tracking it hardly runs
    (the median step stays that of one QP). With the prices it was built with (cross-track 60, azimuth
    crossing 0.01 N^-1, dwell 2 s) it cuts the squared cross-track error of the approach: 18.8 vs 17.6
    m^2 s / 0.1 s (-6 %), 30 second QPs in 300 steps. With today's defaults (120 near the path, 0.05,
    4 s) it does not (20.9 vs 23.2): the reason the default stays one QP."""
    path = circle_path()
    x0 = one_metre_off_at_rest(path)
    costs, solves = {}, {}
    for iterations in (1, 2):
        c = MPCController(config=MPCConfig(time_limit_s=0.0, qp_iterations=iterations, **WEIGHTS_BEFORE_RETUNING))
        run = follow_path(c, path, 30.0, x0=x0)
        cte, cmds, _statuses = run.cross_track_m, run.commands, run.statuses
        assert c.failures == 0
        assert_commands_within_limits(cmds)
        costs[iterations] = float(np.sum(np.square(cte)))
        solves[iterations] = (c.qp_solves, len(c.solve_times_ms))
    qps, steps = solves[2]
    assert steps + 5 <= qps < 1.2 * steps  # second QPs in the approach, few once tracking
    assert solves[1][0] == solves[1][1]
    assert costs[2] < 0.97 * costs[1]
    c = MPCController(config=MPCConfig(time_limit_s=0.0, qp_iterations=2))  # today's defaults
    follow_path(c, path, 30.0, x0=x0)
    assert len(c.solve_times_ms) + 5 <= c.qp_solves < 1.2 * len(c.solve_times_ms)


def test_thrust_prices_are_in_newtons_whatever_the_model():
    """The input weights and the reversal guard's crossing cost are physical: a model that says a
    unit of q makes fewer newtons gets a proportionally smaller price per unit of q (the same
    price per newton), so a model with weaker thrusters does not make them dearer to use."""
    from dataclasses import replace as dc_replace

    strong = MPCController(config=NO_TIME_LIMIT)
    p = strong.model.params
    weak = MPCController(VesselModel(dc_replace(p, mu_az=0.75 * p.mu_az, mu_t=0.75 * p.mu_t)), config=NO_TIME_LIMIT)
    assert weak._R[2:] == pytest.approx(0.75 ** 2 * strong._R[2:])
    assert weak._crossing_cost_q == pytest.approx(0.75 * strong._crossing_cost_q)


def test_reversal_guard_holds_a_direction_and_prices_only_the_crossing():
    """The guard is a sign constraint: with no direction yet the bow thruster is free both ways; once
    it runs one way, thrust the other way beyond the band costs (more during the dwell), thrust its
    own way costs nothing extra."""
    c = MPCController(config=NO_TIME_LIMIT)
    c.reset(circle_path())
    assert c._sigma[2] == 0.0  # bow: no direction yet -> no constraint
    c._n_achieved = np.array([40.0, 40.0, -30.0])
    c._update_direction()
    assert list(c._sigma) == [1.0, 1.0, -1.0]
    assert c.reversals == 0
    c._n_achieved = np.array([40.0, 40.0, 30.0])
    c._update_direction()
    assert c.reversals == 1 and c._sigma[2] == 1.0
    c._crossing_costs()
    lam = c._q[c._ti(0):c._ti(0) + 3]
    assert lam[2] == pytest.approx(c.config.reversal_dwell_factor * c._crossing_cost_q[2])  # just reversed
    for _ in range(int(c.config.reversal_dwell_s / c.config.dt_s) + 1):
        c._update_direction()
    c._crossing_costs()
    assert c._q[c._ti(0) + 2] == pytest.approx(c._crossing_cost_q[2])
    c._n_achieved = np.array([40.0, 40.0, 2.0])  # within the hysteresis: the direction is kept
    c._update_direction()
    assert c._sigma[2] == 1.0 and c.reversals == 1


def test_an_idle_bow_thruster_loses_its_direction_and_is_free_both_ways_again():
    """Issue 46: the start sent the bow thruster one way, the leg needed the other; with the crossing
    price scaled by the sea it stayed idle and the azimuths made the yaw moment as a couple (one
    ahead, one astern near full speed for 37-53 s of the 6-DOF hull's figure eight at 0.5 m/s in
    Hs 3 cm, twice calm water's energy). Idle (inside the hysteresis) for bow_idle_release_s, it has no
    direction again; pushing, it keeps one; the azimuths are not touched."""
    c = MPCController(config=NO_TIME_LIMIT)
    c.reset(circle_path())
    c._n_achieved = np.array([40.0, 40.0, 30.0])
    c._update_direction()
    assert list(c._sigma) == [1.0, 1.0, 1.0]
    steps = int(round(c.config.bow_idle_release_s / c.config.dt_s))
    c._n_achieved = np.array([40.0, 40.0, 2.0])  # idle
    for _ in range(steps - 1):
        c._update_direction()
    assert c._sigma[2] == 1.0  # not yet
    for _ in range(2):
        c._update_direction()
    assert c._sigma[2] == 0.0 and c._direction[2] == 0.0 and list(c._sigma[:2]) == [1.0, 1.0]
    c._n_achieved = np.array([40.0, 40.0, -30.0])  # the other way: no reversal counted, direction set
    c._update_direction()
    assert c._sigma[2] == -1.0 and c.reversals == 0
    c._n_achieved = np.array([40.0, 40.0, -30.0])  # pushing: kept however long
    for _ in range(2 * steps):
        c._update_direction()
    assert c._sigma[2] == -1.0


def test_an_azimuth_left_astern_comes_back_ahead_and_shares_the_thrust():
    """A start or a turn can leave an azimuth's direction astern; on a straight line at 0.8 m/s it must
    come back ahead after `azimuth_astern_hold_s`, or (the default) after `azimuth_idle_release_s` of
    idling, and share the thrust (the same thrust from one propeller draws ~40 % more power). With
    both off it stays astern or idle: the trap (found on the survey, issue 48: azimuth 2 astern for a
    whole 240-s survey on the EKF)."""
    from dataclasses import replace as dc_replace

    from lotsen.sim import SimConfig, Simulator

    path = straight_path(30.0, speed_mps=0.8)

    def fly(hold_s: float, idle_s: float = math.inf) -> np.ndarray:
        c = MPCController(config=dc_replace(NO_TIME_LIMIT, azimuth_astern_hold_s=hold_s,
                                            azimuth_idle_release_s=idle_s))
        c.reset(path)
        c._direction[1] = -1.0          # as after a start that sent azimuth 2 astern
        c._update_direction()
        sim = Simulator(config=SimConfig(sensors=False), x0=[0.0, 0.0, 0.0, 0.8, 0.0, 0.0])
        n = [sim.actuators.state[2:4] for _ in control_ticks(sim, c.update, until_s=25.0)]
        return np.asarray(n)[-50:]      # the last 5 s

    back = fly(10.0)
    assert np.all(back[:, 1] > 5.0)                                    # azimuth 2 ahead again
    assert np.mean(back[:, 1]) > 0.7 * np.mean(back[:, 0])             # and sharing
    stuck = fly(math.inf)
    assert np.mean(stuck[:, 1]) < 0.3 * np.mean(stuck[:, 0])          # the trap, without the hold
    released = fly(math.inf, MPCConfig().azimuth_idle_release_s)      # the default: released when idle
    assert np.all(released[:, 1] > 5.0)
    assert np.mean(released[:, 1]) > 0.7 * np.mean(released[:, 0])


def _wave_motion(t: float) -> tuple[float, float, float]:
    """1 cm RMS north and east at 1 Hz: what the estimator separates out of a wind sea (sea level 1)."""
    w = 0.01 * math.sqrt(2.0) * math.sin(2.0 * math.pi * t)
    return (w, w, 0.0)


def test_in_a_sea_the_azimuth_couple_and_the_bow_thruster_cost_more_but_not_the_thrust_the_sea_needs():
    """Issue 46: in a sea the quadratic input cost (no power model: P ~ |n|^3) let the MPC buy
    millimetres of tracking with yaw couples and the bow thruster. With the sea level at 1 the
    azimuths' thrust is priced about the nominal plan's common mode (their difference: the couple, an
    uneven split) wave_azimuth_split_scale times dearer, the bow thrust wave_bow_cost_scale times;
    the common mode itself, the thrust the sea's added resistance asks, is not priced against the
    calm trim. In flat water the trim term is exactly the calm one."""
    path = straight_path(30.0)
    state = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.05, heading_rad=0.0, u_mps=0.4, v_mps=0.0, r_radps=0.0)
    calm, sea = MPCController(config=NO_TIME_LIMIT), MPCController(config=NO_TIME_LIMIT)
    for c in (calm, sea):
        c.reset(path)
    for k in range(200):
        calm.update(0.1 * k, replace(state, stamp_s=0.1 * k))
        sea.update(0.1 * k, replace(state, stamp_s=0.1 * k, wave_motion=_wave_motion(0.1 * k)))
    cfg = NO_TIME_LIMIT
    assert calm.sea_level == 0.0 and sea.sea_level == pytest.approx(1.0, abs=0.01)
    np.testing.assert_array_equal(calm._R, calm._R_calm)
    assert sea._R[2] == pytest.approx(cfg.wave_azimuth_split_scale * calm._R[2], rel=0.02)
    assert sea._R[4] == pytest.approx(cfg.wave_bow_cost_scale * calm._R[4], rel=0.02)
    # the azimuths' linear term: -R q_ref with q_ref the plan's common mode in a sea, the trim in calm
    base = sea._wi(0)
    q_ref_sea = -sea._q[base + 2:base + 5 * sea.N:5] / sea._R[2]
    np.testing.assert_allclose(q_ref_sea[1:], sea._q_common[1:], rtol=1e-9)  # (stage 0 holds the rate term)
    np.testing.assert_allclose(sea._q_common[1:], 0.5 * (sea._wb[1:, 2] + sea._wb[1:, 3]), rtol=0.15)
    q_ref_calm = -calm._q[base + 2:base + 5 * calm.N:5] / calm._R[2]
    np.testing.assert_allclose(q_ref_calm[1:], calm.q_trim(calm._ref[1:, 4]), rtol=1e-9)


def test_in_a_sea_an_azimuth_left_astern_comes_back_ahead_but_not_in_calm_water():
    """Issue 46: the reversal guard's crossing price grows with the sea, so an azimuth sent astern
    (at a start, in a turn) stayed there for 40-60 % of a mission while the other carried the thrust,
    and the figure eight drew 1.2-2x the energy. In a sea its direction comes back ahead after
    wave_azimuth_astern_hold_s; in flat water nothing changes (azimuth_astern_hold_s stays off; the
    idle release, azimuth_idle_release_s, is off here to see the hold alone, and acts in flat water only)."""
    from dataclasses import replace as dc_replace

    from lotsen.sim import SimConfig, Simulator

    path = straight_path(40.0, speed_mps=0.8)

    def fly(wavy: bool, hold_s: float, idle_s: float = math.inf) -> np.ndarray:
        c = MPCController(config=dc_replace(NO_TIME_LIMIT, wave_azimuth_astern_hold_s=hold_s,
                                            azimuth_idle_release_s=idle_s))
        c.reset(path)
        c._direction[1] = -1.0          # as after a start that sent azimuth 2 astern
        c._update_direction()

        def update(t: float, s: VesselState):  # type: ignore[no-untyped-def]
            return c.update(t, dc_replace(s, wave_motion=_wave_motion(t)) if wavy else s)

        sim = Simulator(config=SimConfig(sensors=False), x0=[0.0, 0.0, 0.0, 0.8, 0.0, 0.0])
        n = [sim.actuators.state[2:4] for _ in control_ticks(sim, update, until_s=25.0)]
        return np.asarray(n)[-50:]      # the last 5 s

    back = fly(True, 10.0)
    assert np.all(back[:, 1] > 5.0)                                    # azimuth 2 ahead again
    assert np.mean(back[:, 1]) > 0.7 * np.mean(back[:, 0])             # and sharing
    calm = fly(False, 10.0)
    assert np.mean(calm[:, 1]) < 0.3 * np.mean(calm[:, 0])             # flat water: as before (the trap)
    # the idle release (default 2 s) is for flat water: in a sea, the wave hold off, the trap stays
    sea_no_hold = fly(True, math.inf, MPCConfig().azimuth_idle_release_s)
    assert np.mean(sea_no_hold[:, 1]) < 0.3 * np.mean(sea_no_hold[:, 0])


def test_cross_track_weight_falls_from_near_to_far():
    from lotsen.control.mpc import cross_track_weight

    cfg = MPCConfig()
    assert cross_track_weight(cfg, 0.0) == cfg.q_cross_track
    assert cross_track_weight(cfg, -0.1) == cross_track_weight(cfg, 0.1)
    assert cfg.q_cross_track_far < cross_track_weight(cfg, 1.0) < 1.02 * cfg.q_cross_track_far
    assert cross_track_weight(MPCConfig(cross_track_far_m=0.0), 1.0) == cfg.q_cross_track
    with pytest.raises(ValueError, match="cross_track_far_m"):
        MPCConfig(cross_track_far_m=-0.1)


def test_approach_from_one_metre_off_does_not_overshoot():
    """From rest 1 m off the path: with the stiff near-path weight everywhere the boat ran at the
    path and overshot it by 0.82 m (the 2-s horizon sees the stop too late); the weight falling to
    q_cross_track_far away from the path brings it on with <= 4 cm overshoot (measured)."""
    path = circle_path()
    x0 = one_metre_off_at_rest(path)
    overshoot = {}
    for far_m in (0.1, 0.0):
        c = MPCController(config=MPCConfig(time_limit_s=0.0, cross_track_far_m=far_m))
        cte = np.asarray(follow_path(c, path, 30.0, x0=x0).cross_track_m)
        assert cte[0] > 0.9 and c.failures == 0
        overshoot[far_m] = -float(np.min(cte))
    assert overshoot[0.1] < 0.1, overshoot
    assert overshoot[0.0] > 0.3, overshoot  # the case is one where the schedule matters


def test_rate_penalties_grow_with_the_wave_motion_and_stay_in_calm_water():
    """MPCConfig.wave_*: flat water keeps the calm rate penalties; a sustained wave-frequency
    displacement in the estimate (1 cm RMS) scales the angles' to wave_rate_scale, the propellers' to
    wave_thrust_rate_scale and the reversal price to wave_reversal_scale, exactly as a controller set up
    with those penalties; the motion gone, they fall back."""
    path = straight_path(30.0)
    calm = MPCController(config=NO_TIME_LIMIT)
    calm.reset(path)
    P_calm = calm._Px[calm._p_in_pos].copy()
    state = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.05, heading_rad=0.0, u_mps=0.4, v_mps=0.0, r_radps=0.0)
    for k in range(40):
        calm.update(0.1 * k, state)
    assert calm.rate_scale == 1.0
    np.testing.assert_array_equal(calm._Px[calm._p_in_pos], P_calm)

    cfg = replace(NO_TIME_LIMIT, wave_rate_scale=5.0, wave_thrust_rate_scale=2.0, wave_reversal_scale=4.0)  # apart
    sea = MPCController(config=cfg)
    sea.reset(path)
    for k in range(200):  # 20 s, four time constants: 1 cm north and east, as a wave would swing the boat
        w = 0.01 * math.sqrt(2.0) * math.sin(2.0 * math.pi * 0.1 * k)
        sea.update(0.1 * k, replace(state, stamp_s=0.1 * k, wave_motion=(w, w, 0.0)))
    assert sea.rate_scale == pytest.approx(cfg.wave_rate_scale, rel=0.01)
    assert sea.sea_level == pytest.approx(1.0, abs=0.01)
    dear = MPCController(config=replace(cfg, s_alpha=cfg.s_alpha * cfg.wave_rate_scale,
                                        s_thrust=cfg.s_thrust * cfg.wave_thrust_rate_scale, wave_rate_scale=1.0,
                                        wave_thrust_rate_scale=1.0, wave_reversal_scale=1.0,
                                        r_thrust_azimuth_per_N2=cfg.r_thrust_azimuth_per_N2 * cfg.wave_azimuth_split_scale,
                                        r_thrust_bow_per_N2=cfg.r_thrust_bow_per_N2 * cfg.wave_bow_cost_scale,
                                        wave_azimuth_split_scale=1.0, wave_bow_cost_scale=1.0))
    dear.reset(path)
    np.testing.assert_allclose(sea._Px[sea._p_in_pos], dear._Px[dear._p_in_pos], rtol=1e-2)
    np.testing.assert_allclose(sea._S, dear._S, rtol=1e-2)
    dwell = np.where(sea._since_flip_s < cfg.reversal_dwell_s, cfg.reversal_dwell_factor, 1.0)
    np.testing.assert_allclose(sea._q[sea._ti(0):sea._ti(0) + 3],  # the reversal guard's crossing price
                               cfg.wave_reversal_scale * dwell * sea._crossing_cost_q, rtol=1e-2)
    for k in range(200, 500):  # six time constants
        sea.update(0.1 * k, replace(state, stamp_s=0.1 * k))
    assert sea.rate_scale == pytest.approx(1.0, abs=0.01)  # (re-set on a 1 % change)
    np.testing.assert_allclose(sea._R, calm._R, rtol=0.1)  # the thrust costs fall back alike


@pytest.mark.parametrize("heading_rms_deg, level", [(0.013, 0.0), (0.5, 1.0)])
def test_the_heading_wave_motion_alone_sets_the_sea_level(heading_rms_deg: float, level: float) -> None:
    """In Hs 3 cm the estimate's wave displacement (0.6-0.8 mm) stays within its dead band, the
    heading's wave motion (0.25-0.33 deg RMS) does not: it alone raises the sea level fully. The
    largest heading wave motion flat water gave (0.013 deg, the estimator's start included) leaves
    the calm weights exactly."""
    path = straight_path(30.0)
    c = MPCController(config=NO_TIME_LIMIT)
    c.reset(path)
    P_calm = c._Px[c._p_in_pos].copy()
    state = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.05, heading_rad=0.0, u_mps=0.4, v_mps=0.0, r_radps=0.0)
    amp = math.radians(heading_rms_deg) * math.sqrt(2.0)
    for k in range(200):  # four time constants; position wave motion 0.5 mm, within its dead band
        s = math.sin(2.0 * math.pi * 0.13 * k)
        c.update(0.1 * k, replace(state, stamp_s=0.1 * k, wave_motion=(0.0005 * s, 0.0005 * s, amp * s)))
    assert c.sea_level == pytest.approx(level, abs=0.02)
    if level == 0.0:
        assert c.rate_scale == 1.0
        np.testing.assert_array_equal(c._Px[c._p_in_pos], P_calm)
    else:
        assert c.rate_scale == pytest.approx(c.config.wave_rate_scale, rel=0.02)


@pytest.mark.parametrize("speed_mps", [0.4, 1.0])
def test_the_angles_sea_scale_is_per_newton_of_side_force(speed_mps: float) -> None:
    """Above wave_speed_ref_mps the angles' sea scale grows with k^2 and the crossing price with k,
    k the azimuths' trim thrust at the speed over that at the reference speed: the side force an angle
    change makes grows with the thrust (T d(alpha)). At or below it, the plain scales."""
    cfg = NO_TIME_LIMIT
    c = MPCController(config=cfg)
    c.reset(straight_path(30.0))
    state = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.05, heading_rad=0.0, u_mps=speed_mps, v_mps=0.0,
                        r_radps=0.0)
    for k in range(200):  # a full sea level: 1 cm of wave displacement
        w = 0.01 * math.sqrt(2.0) * math.sin(2.0 * math.pi * 0.1 * k)
        c.update(0.1 * k, replace(state, stamp_s=0.1 * k, wave_motion=(w, w, 0.0)))
    assert c.sea_level == pytest.approx(1.0, abs=0.01)
    k_thrust = max(1.0, float(c.q_trim(np.array(speed_mps)) / c.q_trim(np.array(cfg.wave_speed_ref_mps))))
    assert (k_thrust > 2.0) == (speed_mps > cfg.wave_speed_ref_mps)
    assert c.rate_scale == pytest.approx(cfg.wave_rate_scale * k_thrust ** 2, rel=0.02)
    assert c.reversal_scale == pytest.approx(cfg.wave_reversal_scale * k_thrust, rel=0.02)
    assert c.thrust_rate_scale == pytest.approx(cfg.wave_thrust_rate_scale, rel=0.02)


def test_the_crab_angle_heads_into_the_current_cross_component():
    """0.17 m/s along a path to the north in 0.2 m/s of current setting east: the water-relative
    velocity (0.17, -0.2) is 49.6 deg to port; a current along the path asks no crab; the angle is
    limited, and a following current as fast as the boat does not turn it round."""
    from lotsen.control.mpc import crab_angle

    assert math.degrees(crab_angle(0.0, 0.17, (0.0, 0.2))) == pytest.approx(-math.degrees(math.atan2(0.2, 0.17)))
    assert math.degrees(crab_angle(math.pi / 2, 0.17, (0.2, 0.0))) == pytest.approx(49.6, abs=0.1)  # east, current north
    assert crab_angle(0.0, 0.5, (0.3, 0.0)) == 0.0 and crab_angle(0.0, 0.5, (-0.3, 0.0)) == 0.0
    assert math.degrees(crab_angle(0.0, 0.17, (0.0, 0.2), math.radians(30.0))) == pytest.approx(-30.0)
    assert math.degrees(crab_angle(0.0, 0.2, (0.5, 0.05))) == pytest.approx(-45.0)  # along floored at 0.05 m/s


def _held(mpc: MPCController, seconds: float, heading_rad: float = 0.0, u_mps: float = 0.0,
          current_ne: tuple[float, float] = (0.0, 0.25), t0: float = 0.0, east_m: float = 0.0) -> list[str]:
    """Statuses of `seconds` of updates on one held state (the boat 4 m along the path, east_m off it)."""
    out = []
    for k in range(round(seconds / 0.1)):
        state = VesselState(stamp_s=t0 + 0.1 * k, north_m=4.0, east_m=east_m, heading_rad=heading_rad,
                            u_mps=u_mps, v_mps=0.0, r_radps=0.0, current_ne_mps=current_ne)
        out.append(mpc.update(t0 + 0.1 * k, state)[1].status)
    return out


def test_a_boat_stalled_in_a_beam_current_turns_into_it_before_it_goes_on():
    """The crab alignment (MPCConfig.align_*): at rest on a path to the north planned at 0.17 m/s in
    a 0.25 m/s current setting east, after align_stall_s the heading's reference is the crab angle
    (56 deg to port) and the plan turns the bow to port; within align_done_deg of it the alignment ends."""
    c = MPCController(config=NO_TIME_LIMIT)
    c.reset(straight_path(20.0, speed_mps=0.17))
    statuses = _held(c, 2.9)
    assert set(statuses) == {"ok"}
    plan_before = c._xb[-1, 2]
    statuses = _held(c, 0.5, t0=2.9)
    assert statuses[-1] == "aligning"
    assert c._xb[-1, 2] < plan_before - 0.2  # the 2-s plan turns to port, into the current
    crab = -math.degrees(math.atan2(0.25, 0.17))  # -55.8
    assert _held(c, 1.0, heading_rad=math.radians(crab + 20.0), t0=3.4)[-1] == "aligning"
    assert _held(c, 0.2, heading_rad=math.radians(crab + 5.0), t0=4.4) == ["ok", "ok"]
    # a time limit ends it too
    c.reset(straight_path(20.0, speed_mps=0.17))
    statuses = _held(c, 3.0 + c.config.align_max_s + 0.5)
    assert statuses[-1] == "ok" and statuses.count("aligning") == pytest.approx(c.config.align_max_s / 0.1, abs=2)


@pytest.mark.parametrize("case", ["light current", "under way", "joining", "off"])
def test_no_crab_alignment_in_a_light_current_under_way_joining_or_switched_off(case):
    """0.05 m/s across asks 16 deg at 0.17 m/s (below align_min_crab_deg); a boat making more than half
    the reference speed is not stalled; one 2 m off the path is joining it (align_max_cross_track_m);
    align_min_crab_deg = inf switches it off."""
    config = replace(NO_TIME_LIMIT, align_min_crab_deg=math.inf) if case == "off" else NO_TIME_LIMIT
    c = MPCController(config=config)
    c.reset(straight_path(20.0, speed_mps=0.17))
    kwargs = {"light current": dict(current_ne=(0.0, 0.05)), "under way": dict(u_mps=0.09),
              "joining": dict(east_m=2.0), "off": {}}[case]
    assert set(_held(c, 6.0, **kwargs)) == {"ok"}


def test_crab_alignment_settings_are_validated():
    for bad in (dict(align_min_crab_deg=0.0), dict(max_crab_deg=90.0), dict(align_stall_s=0.0),
                dict(align_stall_fraction=1.0), dict(align_q_heading=-1.0), dict(align_done_deg=0.0),
                dict(align_max_cross_track_m=0.0)):
        with pytest.raises(ValueError, match="align|crab"):
            MPCConfig(**bad)
