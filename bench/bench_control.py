"""Control benchmark (issue 5): MPC vs pure pursuit vs LOS (and LQ) on the example routes, calm and
with 0.1 m/s current + 3 m/s wind; MPC step time; the same optimal-control problem solved by
do-mpc (CasADi + IPOPT, nonlinear multiple shooting) for the speed ratio and closed-loop cost gap.

    python bench/run.py control        (harness)    or    python bench/bench_control.py [--quick]

Targets: MPC median step <= 1 ms at horizon >= 20; >= 20x faster than do-mpc; cross-track RMS
<= 5 cm calm and <= 15 cm with current + wind at 0.5 m/s; >= 2x better than pure pursuit.

Issue 14 item 3 / issue 19: AUTO soak on the closed figure eight (looped), 0.1 m/s current + 3 m/s
wind, EKF in the loop, supervisor with its failsafes: 10 runs x 10 min without any failsafe
(quick: 2 runs x 2 min); propeller reversals per 10 s beside the MPC without the reversal
penalty and ESC lag (the issue-5 design) on the same seeds.
"""

from __future__ import annotations

import math
import statistics
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path as FilePath

import numpy as np

ROOT = FilePath(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from lotsen.control import ControlConfig, MPCConfig, MPCController, PathReference, make_path_follower  # noqa: E402
from lotsen.model import Environment, VesselModel, symbolic_rhs  # noqa: E402
from lotsen.planning import plan_route  # noqa: E402
from lotsen.planning.io import load_route  # noqa: E402
from lotsen.harness.mission import MissionConfig, run_mission  # noqa: E402
from lotsen.sim import SimConfig, Simulator  # noqa: E402

ROUTES = ("figure_eight", "harbour_approach")
DISTURBED = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
TARGET_CTE_CALM_M = 0.05
TARGET_CTE_DIST_M = 0.15
TARGET_STEP_MS = 1.0
TARGET_SPEEDUP = 20.0


def _path(name: str):
    return plan_route(load_route(ROOT / "examples" / "routes" / f"{name}.yaml"))


def tracking_rows(quick: bool) -> list[dict]:
    rows: list[dict] = []
    routes = ROUTES[:1] if quick else ROUTES
    controllers = ("mpc", "pursuit", "los") if quick else ("mpc", "pursuit", "los", "lq")
    for route in routes:
        path = _path(route)
        for env_name, env in (("calm", Environment()), ("current 0.1 + wind 3", DISTURBED)):
            res = {}
            for c in controllers:
                follower = make_path_follower(ControlConfig(controller=c))
                r = run_mission(path, follower, MissionConfig(environment=env, hold_s=5.0))
                res[c] = r.metrics
            pp = res["pursuit"]["cross_track_rms_m"]
            for c in controllers:
                m = res[c]
                target = TARGET_CTE_CALM_M if env_name == "calm" else TARGET_CTE_DIST_M
                row = {
                    "table": "tracking", "route": route, "environment": env_name, "controller": c,
                    "completed": m["completed"],
                    "cross_track_rms_cm": round(m["cross_track_rms_m"] * 100, 2),
                    "cross_track_max_cm": round(m["cross_track_max_m"] * 100, 2),
                    "heading_error_rms_deg": round(m["heading_error_rms_deg"], 2),
                    "speed_error_rms_mps": round(m["speed_error_rms_mps"], 4),
                    "pursuit_over_this": round(pp / max(m["cross_track_rms_m"], 1e-6), 1),
                    "hold_error_final_cm": round(m.get("hold_position_error_final_m", float("nan")) * 100, 1),
                    "duration_s": m["duration_s"],
                }
                if c == "mpc":
                    row["target"] = f"RMS <= {target * 100:.0f} cm, >= 2x better than pursuit"
                    row["pass"] = bool(m["completed"] and m["cross_track_rms_m"] <= target
                                       and row["pursuit_over_this"] >= 2.0)
                    row["solve_median_ms"] = m["solve_time_median_ms"]
                    row["solve_max_ms"] = m["solve_time_max_ms"]
                rows.append(row)
    return rows


def timing_rows(quick: bool) -> list[dict]:
    """MPC step time (linearisation + QP update + OSQP solve) on the figure eight, per horizon."""
    rows = []
    path = _path("figure_eight")
    horizons = (20,) if quick else (20, 30, 40)
    for N in horizons:
        c = MPCController(config=MPCConfig(horizon=N))
        c.reset(path)
        sim = Simulator(config=SimConfig(sensors=False, environment=DISTURBED),
                        x0=[path.north_m[0], path.east_m[0], path.heading_rad[0], 0, 0, 0])
        steps = 300 if quick else 900
        for _ in range(steps):
            cmd, _st = c.update(sim.t, sim.truth())
            sim.command(cmd)
            sim.advance(0.1)
        t = np.array(c.solve_times_ms[5:])  # after warm-up (JIT load, first factorisation)
        # issue 5 asks for one horizon >= 20 within 1 ms, issue 19 for N = 40; N = 30 is shown for scale
        target = {20: f"median <= {TARGET_STEP_MS} ms at N >= 20 (issue 5)",
                  40: f"median <= {TARGET_STEP_MS} ms at N = 40 (issue 19)"}.get(N, "(info)")
        rows.append({"table": "mpc step time", "horizon": N, "steps": len(t),
                     "median_ms": round(float(np.median(t)), 3), "p95_ms": round(float(np.percentile(t, 95)), 3),
                     "max_ms": round(float(t.max()), 3), "failures": c.failures,
                     "qp_per_step": round(c.qp_solves / steps, 3),
                     "target": target, "pass": bool(np.median(t) <= TARGET_STEP_MS) if N in (20, 40) else None})
    rows.append(_step_time_vs_issue5(path, 300 if quick else 900))
    return rows


def _step_time_vs_issue5(path, steps: int) -> dict:
    """The cost of the reversal slacks and the ESC lag: the default MPC and the issue-5 configuration
    (no penalty, no lag) stepped alternately in the same run on the same states (load-robust ratio)."""
    x0 = [path.north_m[0], path.east_m[0], path.heading_rad[0], 0, 0, 0]
    sims, ctrls = [], []
    for cfg in (MPCConfig(), UNPENALISED):
        c = MPCController(config=cfg)
        c.reset(path)
        ctrls.append(c)
        sims.append(Simulator(config=SimConfig(sensors=False, environment=DISTURBED), x0=x0))
    for _ in range(steps):
        for c, sim in zip(ctrls, sims):
            cmd, _st = c.update(sim.t, sim.truth())
            sim.command(cmd)
            sim.advance(0.1)
    med = [float(np.median(c.solve_times_ms[5:])) for c in ctrls]
    return {"table": "mpc step time", "horizon": 20, "steps": steps,
            "median_ms": round(med[0], 3), "issue5_config_median_ms": round(med[1], 3),
            "ratio_to_issue5": round(med[0] / med[1], 2), "reversals": ctrls[0].reversals,
            "issue5_config_reversals": ctrls[1].reversals, "target": "(info: same-run comparison)", "pass": None}


# ----------------------------------------------------------------------------------------------
# do-mpc peer: the same OCP (model, cost of eq. 43, bounds and rate bounds of eq. 44, horizon, dt)
# ----------------------------------------------------------------------------------------------
def _build_dompc(cfg: MPCConfig, model: VesselModel, limits):
    warnings.filterwarnings("ignore")
    import casadi as ca
    import do_mpc

    N, dt = cfg.horizon, cfg.dt_s
    scale = [1.0, 1.0, limits.n_az_max_rps ** 2, limits.n_az_max_rps ** 2, limits.n_bow_max_rps ** 2]
    m = do_mpc.model.Model("discrete")
    x = m.set_variable("_x", "x", shape=(6, 1))
    wp = m.set_variable("_x", "wp", shape=(5, 1))  # previous input (rate bounds)
    w = m.set_variable("_u", "w", shape=(5, 1))
    weights = MPCController(model, limits, cfg)  # our QP's input weights and crossing costs in q units
    lam = [float(v) for v in weights._crossing_cost_q]
    band = [cfg.reversal_band_rps ** 2 / s for s in (limits.n_az_max_rps ** 2,) * 2]
    penalised = cfg.azimuth_ahead_only and lam[0] > 0.0
    if penalised:  # the azimuths' sign constraint of our QP: t >= astern part beyond the band (the bow's
        # direction state starts at "none" and changes at run time: not part of this fixed OCP)
        t = m.set_variable("_u", "t", shape=(2, 1))
    ref = m.set_variable("_tvp", "ref", shape=(7, 1))  # pn, pe, ph, pv, pk, U, q_trim
    f = symbolic_rhs(ca)
    theta = list(model.theta)

    def n_of(q, s):  # n = sign(q) sqrt(|q| s), smoothed at 0 for IPOPT
        return q * math.sqrt(s) / (q * q + 1e-8) ** 0.25

    u_act = [w[0], w[1], n_of(w[2], scale[2]), n_of(w[3], scale[3]), n_of(w[4], scale[4])]

    def rhs(xx):
        return ca.vertcat(*f(ca.vertsplit(xx), u_act, theta, model.geom))

    k1 = rhs(x)
    k2 = rhs(x + dt / 2 * k1)
    k3 = rhs(x + dt / 2 * k2)
    k4 = rhs(x + dt * k3)
    m.set_rhs("x", x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4))
    m.set_rhs("wp", w)
    m.setup()
    pn, pe, ph, pv, pk, U, qt = [ref[i] for i in range(7)]
    e = -ca.sin(ph) * (x[0] - pn) + ca.cos(ph) * (x[1] - pe)
    y = [e, x[2] + x[4] / U - ph, x[2] - ph, x[3] - pv, x[5] - pv * pk]
    Q = [cfg.q_cross_track, cfg.q_course, cfg.q_heading, cfg.q_speed, cfg.q_yaw_rate]
    stage = sum(Q[i] * y[i] ** 2 for i in range(5))
    R = [float(v) for v in weights._R]
    wref = [0, 0, qt, qt, 0]
    # the OSQP QP minimises 1/2 z'Pz + q'z with P = C'QC: the same objective up to the factor 1/2
    inp = sum(R[i] * (w[i] - wref[i]) ** 2 for i in range(5))
    if penalised:  # OSQP's lambda' t + mu/2 t't, times 2 like the quadratic terms above
        inp += sum(2.0 * lam[j] * t[j] + cfg.reversal_quadratic * t[j] ** 2 for j in range(2))
    mpc = do_mpc.controller.MPC(m)
    mpc.set_param(n_horizon=N, t_step=dt, store_full_solution=False,
                  nlpsol_opts={"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes"})
    mpc.set_objective(lterm=stage + inp, mterm=cfg.terminal_factor * stage)
    mpc.set_rterm(w=np.array([cfg.s_alpha, cfg.s_alpha, cfg.s_thrust, cfg.s_thrust, cfg.s_thrust]))
    lim = np.array([limits.alpha_max_rad, limits.alpha_max_rad, 1.0, 1.0, 1.0])
    mpc.bounds["lower", "_u", "w"] = -lim
    mpc.bounds["upper", "_u", "w"] = lim
    dn = limits.n_rate_max_rps2 * dt
    dw = np.array([limits.alpha_rate_max_radps * dt] * 2 + [min(1.0, 2 * dn / limits.n_az_max_rps)] * 2
                  + [min(1.0, 2 * dn / limits.n_bow_max_rps)])
    mpc.set_nl_cons("rate_up", w - wp, ub=dw)
    mpc.set_nl_cons("rate_down", wp - w, ub=dw)
    if penalised:
        mpc.bounds["lower", "_u", "t"] = np.zeros(2)
        mpc.set_nl_cons("astern", ca.vertcat(-(t[0] + w[2]) - band[0], -(t[1] + w[3]) - band[1]), ub=np.zeros(2))
    tvp = mpc.get_tvp_template()
    holder: dict = {"ref": np.zeros((N + 1, 7))}

    def tvp_fun(t_now):
        for k in range(N + 1):
            tvp["_tvp", k, "ref"] = holder["ref"][k]
        return tvp

    mpc.set_tvp_fun(tvp_fun)
    mpc.setup()
    return mpc, holder


def _stage_cost(cfg: MPCConfig, ref: PathReference, x, s, w, w_prev, q_trim, ours) -> np.ndarray:
    """Realised closed-loop cost with the OCP's weights (true projection on the path): [the OCP's
    stage cost with the reversal penalties (its L1 terms, scaled like do-mpc's objective), the
    same without them (tracking and input effort only)]."""
    s, cte, hdg = ref.project(x[0], x[1], s)
    _, _, _, k, v = ref.sample(np.array([s]))
    he = (x[2] - hdg + math.pi) % (2 * math.pi) - math.pi
    U = max(float(v[0]), cfg.min_speed_course_mps)
    y = [cte, he + x[4] / U, he, x[3] - v[0], x[5] - v[0] * k[0]]
    Q = [cfg.q_cross_track, cfg.q_course, cfg.q_heading, cfg.q_speed, cfg.q_yaw_rate]
    R = ours._R
    S = np.array([cfg.s_alpha, cfg.s_alpha, cfg.s_thrust, cfg.s_thrust, cfg.s_thrust])
    wref = np.array([0, 0, q_trim, q_trim, 0])
    band = cfg.reversal_band_rps ** 2 / ours.scale[2:4]
    t = np.maximum(0.0, -w[2:4] - band) if cfg.azimuth_ahead_only else np.zeros(2)  # astern beyond the band
    lam = ours._crossing_cost_q[:2]
    tracking = float(sum(Q[i] * float(y[i]) ** 2 for i in range(5)) + R @ (w - wref) ** 2 + S @ (w - w_prev) ** 2)
    return np.array([tracking + 2.0 * lam @ t + cfg.reversal_quadratic * float(t @ t) * float(lam.any()), tracking])


# The OCPs of the comparison (calm water, 30 cm start offset; observer, ESC lag and servo slew off in
# ours, because do-mpc models none of them): "ahead" = our default design (the azimuths' astern thrust
# and the bow thrust L1-costed, issue 19); "reversible" = the issue-5 OCP without those costs. Our
# variants per OCP:
# (progress_reference, qp_iterations). "time" is the OCP do-mpc solves; "predicted" is our default
# reference (progress of the predicted positions); qp_iterations = 1 is plain RTI (the default), 2 adds
# a second QP in transients (`reiterate_dw`).
_DEFAULT = MPCConfig()
DOMPC_CASES = (
    ("ahead", (("predicted", _DEFAULT.qp_iterations), ("time", _DEFAULT.qp_iterations), ("time", 2))),
    ("reversible", (("time", _DEFAULT.qp_iterations), ("time", 2))),
)


def _dompc_closed_loop(cfg: MPCConfig, path, x0, steps: int, ours: MPCController) -> tuple[np.ndarray, float, int]:
    """do-mpc (IPOPT on the nonlinear multiple-shooting NLP) in closed loop: costs (`_stage_cost`),
    median ms, failures."""
    from lotsen.model import DEFAULT_LIMITS

    model = VesselModel()
    mpc, holder = _build_dompc(cfg, model, DEFAULT_LIMITS)
    ref = PathReference(path, cfg.min_speed_ref_mps)
    sim = Simulator(model, DEFAULT_LIMITS, SimConfig(sensors=False), x0)
    J, s, w_prev = np.zeros(2), 0.0, np.zeros(5)
    times = []
    N = cfg.horizon
    fails = 0
    for i in range(steps):
        x = np.array(sim.x)
        s, _cte, _h = ref.project(x[0], x[1], s)
        _, _, _, _, v0 = ref.sample(np.array([s]))
        sk = s + np.arange(N + 1) * max(float(v0[0]), cfg.min_speed_ref_mps) * cfg.dt_s
        pn, pe, ph, pk, pv = ref.sample(sk)
        ph = ph + 2 * math.pi * np.round((x[2] - ph[0]) / (2 * math.pi))
        qtr = ours.q_trim(pv)
        holder["ref"] = np.stack([pn, pe, ph, pv, pk, np.maximum(pv, cfg.min_speed_course_mps), qtr], axis=1)
        xa = np.concatenate([x, w_prev])
        if i == 0:
            mpc.x0 = xa
            mpc.u0 = np.concatenate([w_prev, np.zeros(mpc.model.n_u - 5)])  # (and the reversal slacks)
            mpc.set_initial_guess()
        t0 = time.perf_counter()
        w = np.asarray(mpc.make_step(xa)).ravel()[:5]
        times.append((time.perf_counter() - t0) * 1e3)
        if not mpc.solver_stats.get("success", True):
            fails += 1
        J += _stage_cost(cfg, ref, sim.x, s, w, w_prev, float(ours.q_trim(np.array(pv[0]))), ours)
        w_prev = w
        sim.command(ours.w_to_command(w))
        sim.advance(cfg.dt_s)
    return J, statistics.median(times[2:]), fails


def dompc_rows(quick: bool) -> list[dict]:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import do_mpc  # noqa: F401
    except Exception as exc:  # pragma: no cover
        return [{"table": "do-mpc peer", "note": f"do-mpc not available: {exc}"}]
    from lotsen.model import DEFAULT_LIMITS

    path = _path("figure_eight")
    model = VesselModel()
    steps = 40 if quick else 100
    x0 = [path.north_m[0], path.east_m[0] + 0.3, path.heading_rad[0], 0.3, 0, 0]  # 30 cm off, moving
    rows = []
    for ocp, variants in DOMPC_CASES:
        # a fixed cross-track weight (no schedule with the distance to the path): the OCP do-mpc solves
        cfg = MPCConfig(disturbance_gain=0.0, esc_in_prediction=False, servo_in_prediction=False,
                        cross_track_far_m=0.0)
        if ocp == "reversible":
            cfg = replace(cfg, reversal_cost_azimuth_per_N=0.0, reversal_cost_bow_per_N=0.0)
        ref = PathReference(path, cfg.min_speed_ref_mps)
        results = {}
        for progress, iterations in variants:
            ours = MPCController(model, DEFAULT_LIMITS, replace(cfg, progress_reference=progress,
                                                                qp_iterations=iterations))
            ours.reset(path)
            sim = Simulator(model, DEFAULT_LIMITS, SimConfig(sensors=False), x0)
            J, w_prev = np.zeros(2), np.zeros(5)
            for _ in range(steps):
                cmd, st = ours.update(sim.t, sim.truth())
                w = ours.command_to_w(cmd.as_tuple())
                J += _stage_cost(cfg, ref, sim.x, st.progress_m, w, w_prev,
                                 float(ours.q_trim(np.array(st.speed_ref_mps))), ours)
                w_prev = w
                sim.command(cmd)
                sim.advance(cfg.dt_s)
            results[(progress, iterations)] = (J, np.median(ours.solve_times_ms[2:]), ours.failures)
        J_peer, t_peer, f_peer = _dompc_closed_loop(cfg, path, x0, steps, ours)
        for progress, iterations in variants:
            J_ours, t_ours, f_ours = results[(progress, iterations)]
            speedup = t_peer / t_ours
            gap, gap_tracking = 100.0 * (J_ours - J_peer) / J_peer
            same = progress == "time"
            rows.append({
                "table": "do-mpc peer (same OCP, figure eight, 30 cm start offset, calm)",
                "ocp": ocp + (" (default design)" if ocp == "ahead" else " (issue-5 OCP)"),
                "progress_reference": progress + (" (the OCP do-mpc solves)" if same else " (default; do-mpc: time)"),
                "qp_iterations": iterations,
                "horizon": cfg.horizon, "closed_loop_steps": steps,
                "lotsen_median_ms": round(float(t_ours), 3), "dompc_median_ms": round(float(t_peer), 2),
                "speedup": round(float(speedup), 1),
                "lotsen_closed_loop_cost": round(float(J_ours[0]), 3),
                "dompc_closed_loop_cost": round(float(J_peer[0]), 3),
                "cost_gap_pct": round(float(gap), 2),
                # the same without the reversal penalties: where the L1 terms differ, how each tracks
                "tracking_cost_gap_pct": round(float(gap_tracking), 2),
                "failures_lotsen": f_ours, "failures_dompc": f_peer,
                "target": f">= {TARGET_SPEEDUP:.0f}x faster" + ("; cost gap <= 3 % (issue 19, whole objective)"
                                                                 if same and ocp == "ahead"
                                                                 and iterations == _DEFAULT.qp_iterations else ""),
                "pass": bool(speedup >= TARGET_SPEEDUP and (gap <= 3.0 or not same or ocp != "ahead"
                                                            or iterations != _DEFAULT.qp_iterations)),
            })
    return rows


SOAK_RUNS, SOAK_S = 10, 600.0
SOAK_QUICK_RUNS, SOAK_QUICK_S = 2, 120.0
MAX_REVERSALS_PER_10S = 1.0
UNPENALISED = MPCConfig(reversal_cost_azimuth_per_N=0.0, reversal_cost_bow_per_N=0.0, esc_in_prediction=False,
                        servo_in_prediction=False, azimuth_ahead_only=False, current_in_prediction=False,
                        qp_iterations=1)


def _looped_figure_eight(min_length_m: float):
    """figure_eight_loop.yaml with its nodes repeated until the route is at least min_length_m long
    (the route ends where it starts, so AUTO runs the figure eight again and again)."""
    import dataclasses

    route = load_route(ROOT / "examples" / "routes" / "figure_eight_loop.yaml")
    path = plan_route(route)
    laps = max(1, math.ceil(min_length_m / path.length_m))
    return plan_route(dataclasses.replace(route, nodes=route.nodes * laps)) if laps > 1 else path


def _reversals_per_propeller_per_10s(u: np.ndarray, t: np.ndarray, threshold_rps: float = 5.0) -> list[float]:
    """Sign changes of each commanded propeller speed (azimuth 1, azimuth 2, bow) per 10 s
    (|n| <= threshold keeps the direction)."""
    span = float(t[-1] - t[0]) if t.size > 1 else 1.0
    out = []
    for j in (2, 3, 4):
        n, d = 0, 0
        for v in u[:, j]:
            s = 1 if v > threshold_rps else (-1 if v < -threshold_rps else 0)
            if s and d == -s:
                n += 1
            if s:
                d = s
        out.append(10.0 * n / span)
    return out


def _reversals_per_10s(u: np.ndarray, t: np.ndarray, threshold_rps: float = 5.0) -> float:
    """Sign changes of the commanded propeller speeds, all three propellers summed (the bow tunnel
    thruster runs both ways by design; its sign changes are counted too, and reported per propeller)."""
    return float(sum(_reversals_per_propeller_per_10s(u, t, threshold_rps)))


def soak_rows(quick: bool) -> list[dict]:
    """AUTO on the looped figure eight in current + wind with the EKF and the failsafes: zero
    failsafes over runs x minutes (issue 14 item 3), reversals per 10 s (issue 19)."""
    from lotsen.harness.mission import make_sim_ekf

    runs, dur = (SOAK_QUICK_RUNS, SOAK_QUICK_S) if quick else (SOAK_RUNS, SOAK_S)
    path = _looped_figure_eight(0.5 * dur + 20.0)  # still following the route when the time is up
    rows: list[dict] = []
    total_fs, total_rev, total_t = 0, 0.0, 0.0
    for seed in range(runs):
        row: dict = {"table": "auto soak (figure eight loop, current 0.1 + wind 3, EKF)", "seed": seed}
        for name, cfg in (("", MPCConfig()), ("unpenalised_", UNPENALISED)):
            if name and seed >= (1 if quick else 3):  # the comparison on the first seeds only
                continue
            mc = MissionConfig(environment=DISTURBED, seed=seed, sensors=True, max_duration_s=dur)
            follower = make_path_follower(ControlConfig(mpc=cfg))
            r = run_mission(path, follower, mc, estimator=make_sim_ekf(mc, path))
            m = r.metrics
            rev = _reversals_per_10s(r.u, r.t)
            per = _reversals_per_propeller_per_10s(r.u, r.t)
            row[f"{name}minutes"] = round(float(r.t[-1]) / 60.0, 2)
            row[f"{name}reversals_az1_az2_bow_per_10s"] = "/".join(f"{p:.2f}" for p in per)
            row[f"{name}stayed_in_auto"] = r.reason == "timeout"
            row[f"{name}failsafes"] = ",".join(m["failsafes_triggered"]) or "none"
            row[f"{name}reversals_per_10s"] = round(rev, 2)
            row[f"{name}cross_track_rms_cm"] = round(m["cross_track_rms_m"] * 100, 2)
            row[f"{name}solve_median_ms"] = m["solve_time_median_ms"]
            row[f"{name}qp_per_step"] = round(follower.qp_solves / max(len(follower.solve_times_ms), 1), 3)
            # OSQP's wall-clock time limit (20 ms) makes these load-dependent: on a loaded machine a burst
            # of overruns can trip the controller failsafe (that is not a thruster failsafe)
            row[f"{name}solver_failures"] = m["failures"]
            if not name:
                total_fs += len(m["failsafes_triggered"]) + (0 if r.reason == "timeout" else 1)
                total_rev += rev * float(r.t[-1])
                total_t += float(r.t[-1])
        rows.append(row)
    rows.append({"table": "auto soak summary", "runs": runs, "minutes_each": dur / 60.0,
                 "failsafes_or_aborts": total_fs, "reversals_per_10s": round(total_rev / max(total_t, 1e-9), 2),
                 "target": f"0 failsafes in {runs} x {dur / 60:.0f} min (issue 14)"
                           + (" (quick form; the bar is 10 x 10 min)" if quick else ""),
                 "pass": bool(total_fs == 0),
                 # issue 19: <= 1 per 10 s, all three propellers summed (docs/control.md, 2026-11-23)
                 "issue19_reversal_target_met": bool(total_rev / max(total_t, 1e-9) <= MAX_REVERSALS_PER_10S)})
    return rows


# the issue-14 design, for issue 19's "beside the current design": the MPC before the issue-19 changes
# (reversal penalty 0.2 on either direction, bow 1.0 / 0.5, no current in the prediction), the station
# keeper without the current feedforward and weathervaning, and the path arriving at cruise speed
# (in today's terms: the azimuths' crossing cost 0.2 per unit q = 0.018 per N; its bow price on use
# in both directions has no equivalent any more, the bow gets its use-price's quadratic 0.5 / (2.56 N)^2)
ISSUE14_MPC = MPCConfig(reversal_cost_azimuth_per_N=0.018, reversal_cost_bow_per_N=0.4, r_thrust_bow_per_N2=0.076,
                        azimuth_ahead_only=False, current_in_prediction=False, servo_in_prediction=False,
                        qp_iterations=1)


def mission_rows(quick: bool) -> list[dict]:
    """Issue 19's "done when": `lotsen mission figure_eight.yaml --sim --current 0.1,90 --wind 3,45` on
    the EKF (cross-track RMS <= 1.5 cm, hold error after the 10 s hold <= 5 cm), this design beside the
    issue-14 design on the same seeds; reversals per 10 s while following."""
    from lotsen.control import StationKeepingConfig, make_station_keeper
    from lotsen.planning import PlannerConfig
    from lotsen.harness.mission import make_sim_ekf

    route = load_route(ROOT / "examples" / "routes" / "figure_eight.yaml")
    designs = {
        "issue 19 (this)": (PlannerConfig(), ControlConfig()),
        "issue 14": (PlannerConfig(stop_at_end=False),
                     ControlConfig(mpc=ISSUE14_MPC, station_keeping=StationKeepingConfig(
                         weathervane="off", current_feedforward=False))),
    }
    env = Environment(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    rows: list[dict] = []
    for seed in ((0,) if quick else (0, 1, 2)):
        for name, (planner, control) in designs.items():
            model = VesselModel()
            path = plan_route(route, planner)
            cfg = MissionConfig(environment=env, seed=seed, sensors=True)
            res = run_mission(path, make_path_follower(control, model), cfg, model=model,
                              station_keeper=make_station_keeper(control, model), estimator=make_sim_ekf(cfg, path, model))
            follow = res.mode == "follow"
            # no hold phase when the route was not finished (the run ran out of time): no hold figure
            cte, hold = res.metrics["cross_track_rms_m"], res.metrics.get("hold_position_error_final_m", math.nan)
            rows.append({"table": "issue 19 mission (figure eight, EKF, current 0.1 + wind 3)", "design": name,
                         "seed": seed, "completed": res.completed, "cross_track_rms_cm": round(100 * cte, 2),
                         "hold_error_final_cm": None if math.isnan(hold) else round(100 * hold, 1),
                         "reversals_per_10s": round(_reversals_per_10s(res.u[follow], res.t[follow]), 2),
                         "solve_median_ms": res.metrics["solve_time_median_ms"],
                         "target": "cross-track <= 1.5 cm, hold <= 5 cm",
                         "pass": bool(res.completed and cte <= 0.015 and hold <= 0.05),
                         **({"role": "peer"} if name == "issue 14" else {})})  # the design it replaced
    return rows


def run(quick: bool = False) -> list[dict]:
    rows = timing_rows(quick)
    rows += mission_rows(quick)
    rows += soak_rows(quick)
    rows += dompc_rows(quick)
    rows += tracking_rows(quick)
    return rows


if __name__ == "__main__":
    import json

    t0 = time.perf_counter()
    out = run(quick="--quick" in sys.argv)
    for r in out:
        print(json.dumps(r))
    print(f"# {time.perf_counter() - t0:.1f} s")
