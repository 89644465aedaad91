"""The lake model of identification: current, wind with drag coefficients and a per-interval gust
factor, against the float model and finite differences; the verdict on lake records."""

import math

import numpy as np
import pytest

from lotsen.model import DEFAULT_PARAMETERS, Environment, geometry_tuple, vessel_rhs
from lotsen.model.environment import apparent_wind_force, wind_drag_coefficients, wind_force


def test_apparent_wind_force_is_the_angle_form_of_wind_force():
    rng = np.random.default_rng(1)
    for _ in range(50):
        psi, u, v = rng.uniform(-3, 3), rng.uniform(-1, 1), rng.uniform(-0.5, 0.5)
        W, frm = rng.uniform(0.5, 6), rng.uniform(0, 360)
        env = Environment(wind_speed_mps=W, wind_from_deg=frm)
        b = math.radians(frm)
        ref = wind_force(psi, u, v, env)
        # the reference written out with angles (Fossen 2021, sec. 10.1)
        uw, vw = -W * math.cos(b - psi), -W * math.sin(b - psi)
        urw, vrw = u - uw, v - vw
        g, q = math.atan2(vrw, urw), 0.5 * 1.225 * (urw ** 2 + vrw ** 2)
        angles = (-0.6 * math.cos(g) * 0.05 * q, -0.8 * math.sin(g) * 0.15 * q, -0.1 * math.sin(2 * g) * 0.15 * 0.99 * q)
        assert np.allclose(ref, angles, rtol=1e-5, atol=1e-8)
        assert np.allclose(apparent_wind_force(psi, u, v, -W * math.cos(b), -W * math.sin(b),
                                               *wind_drag_coefficients()), angles, rtol=1e-5, atol=1e-8)


def test_lake_step_matches_the_float_model_and_finite_differences():
    import casadi as ca

    from lotsen.sysid.sensitivity import _build_step_functions

    geom = geometry_tuple()
    step, step_sens = _build_step_functions(geom, False, lake=True)
    theta = np.array(DEFAULT_PARAMETERS.with_updates(X_uuu=-1.5).to_vector())  # the optional cubic term on
    env = np.array([0.05, -0.07, 2.0, -3.0, *wind_drag_coefficients(), 0.012])  # k_Nv: a moment arm too
    th = np.concatenate([theta, env])
    x = np.array([1.0, 2.0, 0.4, 0.6, 0.05, 0.1, 1.2, 0.15])  # gust factors 1.2 along, 0.15 across
    wn, we = 1.2 * 2.0 + 0.15 * 3.0, 1.2 * -3.0 + 0.15 * 2.0  # g w + h (-w_E, w_N)
    u_held = np.array([0.1, 0.1, 60.0, 55.0, 20.0])
    u = np.concatenate([u_held, np.zeros(5)])  # the input's line over the step: held
    h = 0.01
    x1 = np.array(step(x, u, th, h, 0.0, np.zeros(8))).ravel()
    # the float model: current through vessel_rhs, wind through apparent_wind_force with g * w
    tau = apparent_wind_force(x[2], x[3], x[4], wn, we, *env[4:])

    def f(xx):
        return np.array(vessel_rhs(xx, u_held, theta, current_ne=(env[0], env[1]), tau_ext=tau))

    # one RK4 step with the wind force re-evaluated at the stages
    def rhs(xx):
        t = apparent_wind_force(xx[2], xx[3], xx[4], wn, we, *env[4:])
        return np.array(vessel_rhs(xx, u_held, theta, current_ne=(env[0], env[1]), tau_ext=t))

    x6 = x[:6]
    k1 = rhs(x6)
    k2 = rhs(x6 + h / 2 * k1)
    k3 = rhs(x6 + h / 2 * k2)
    k4 = rhs(x6 + h * k3)
    ref = x6 + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.allclose(x1[:6], ref, rtol=1e-10, atol=1e-12)
    assert x1[6] == 1.2 and x1[7] == 0.15 and np.all(np.isfinite(f(x6)))
    # sensitivities of 50 steps against central differences, for state, gust factor and environment
    S = np.zeros((8, 8 + len(th)))
    xs = x.copy()
    xs_, S_ = xs, S
    for _ in range(50):
        a, b = step_sens(xs_, S_, u, th, h, 0.0, np.zeros(8))
        xs_, S_ = np.array(a).ravel(), np.array(b)
    # S starts at zero here (reset 0), so compare d x_50 / d theta with differences of the simulation
    def sim(thv, x0):
        xx = x0.copy()
        for _ in range(50):
            xx = np.array(step(xx, u, thv, h, 0.0, np.zeros(8))).ravel()
        return xx

    nt = len(theta)  # the environment's entries follow the vessel's (ENV_NAMES)
    for j in (*range(nt, nt + 8), 5, 11, nt - 1):
        d = 1e-6 * max(abs(th[j]), 1e-3)
        tp, tm = th.copy(), th.copy()
        tp[j] += d
        tm[j] -= d
        fd = (sim(tp, x) - sim(tm, x)) / (2 * d)
        assert np.allclose(S_[:, 8 + j], fd, rtol=1e-4, atol=1e-8), j
    # the gust factors as states: d x / d g, d x / d h
    a, b = step_sens(x, np.zeros((8, 8 + len(th))), u, th, h, 1.0, x)  # reset: S = [I, 0]
    xs_, S_ = np.array(a).ravel(), np.array(b)
    for _ in range(49):
        a, b = step_sens(xs_, S_, u, th, h, 0.0, np.zeros(8))
        xs_, S_ = np.array(a).ravel(), np.array(b)
    for q in (6, 7):
        xp, xm = x.copy(), x.copy()
        xp[q] += 1e-6
        xm[q] -= 1e-6
        fd = (sim(th, xp) - sim(th, xm)) / 2e-6
        assert np.allclose(S_[:, q], fd, rtol=1e-4, atol=1e-8), q
    assert ca is not None


def _identify_cli(lake, tmp_path, *extra):
    from lotsen.cli.identify import main_standalone
    from lotsen.sysid.data import save_csv

    data, out = tmp_path / "lake.csv", tmp_path / "p.json"
    save_csv(lake.run.record, data)
    rc = main_standalone(["identify", str(data), "--out", str(out), "--holdout", "0", *extra])
    return rc, out


def test_a_short_lake_record_is_refused_not_answered(tmp_path, capsys):
    """60 s in current and gusty wind: too little to separate boat, current and wind; exit 1, refused."""
    import json

    from lotsen.harness.identification import lake_run

    lake = lake_run(7, duration_s=60.0, current_mps=0.08, wind_mps=4.0)
    rc, out = _identify_cli(lake, tmp_path, "--lake")
    err = capsys.readouterr().err
    assert rc == 1 and "REFUSED" in err
    assert json.loads(out.read_text())["verdict"] == "refused"


def test_lake_record_without_bow_thruster_is_refused(tmp_path, capsys):
    from lotsen.harness.identification import lake_run
    from lotsen.sysid.experiment import parse_experiment

    exp = parse_experiment({"name": "no_bow", "area": {"size_m": [400, 400]}, "pieces": [
        {"type": "prbs", "duration_s": 90, "bit_s": 1.5, "seed": 3, "base": {"n_rps": 55},
         "amplitude": {"alpha_deg": 25, "n1_rps": 25, "n2_rps": 25}}]}, "no_bow")
    lake = lake_run(8, current_mps=0.05, wind_mps=2.0, experiment=exp)
    rc, out = _identify_cli(lake, tmp_path, "--lake")
    err = capsys.readouterr().err
    assert rc == 2 and "mu_t" in err and "Traceback" not in err  # unidentifiable: nothing written


@pytest.mark.slow
@pytest.mark.parametrize("lake_flag", [True, False])
def test_done_when_lake_record_is_answered_within_bounds_or_refused(tmp_path, capsys, lake_flag):
    """The issue's case (10 min, 0.08 m/s current, 4 m/s gusty wind): never exit 0 with a wrong answer,
    with or without the lake model."""
    import json

    from lotsen.harness.identification import lake_run
    from lotsen.sysid.judge import CORE_PARAMETERS

    lake = lake_run(2500, current_mps=0.08, wind_mps=4.0)
    rc, out = _identify_cli(lake, tmp_path, *(["--lake"] if lake_flag else []))
    if rc != 0:
        err = capsys.readouterr().err
        # refused with the file marked (exit 1), or (an unidentifiable direction) an error, nothing written
        assert (rc == 1 and "REFUSED" in err) or (rc == 2 and "error:" in err)
        assert not out.exists() or json.loads(out.read_text())["verdict"] == "refused"
        return
    d = json.loads(out.read_text())
    assert d["verdict"] in ("ok", "weak") and len(d["identification"]["weakly_determined"]) <= 4
    for n, s in d["std"].items():
        t = getattr(lake.boat, n)
        assert abs(d[n] - t) <= 3 * s, n
        bound = 0.05 if n in CORE_PARAMETERS else (None if n in d["identification"]["weakly_determined"] else 0.15)
        if bound is not None:
            assert abs(d[n] - t) <= bound * abs(t), n


def _result(values: dict, std: dict, converged: bool = True):
    from lotsen.sysid.estimate import Identifiability, IdentificationResult
    from lotsen.sysid.multiple import MultipleShootingResult

    names = tuple(values)
    params = DEFAULT_PARAMETERS.with_updates(**values)
    cov = np.diag([std[n] ** 2 for n in names])
    ident = Identifiability(np.ones(len(names)), [], False, {}, [], 1.0)
    details = MultipleShootingResult(np.zeros((1, 6)), np.zeros(1), {}, 0.0, 1, 1, 1)
    return IdentificationResult(params, dict(std), {}, names, cov, np.linalg.inv(cov), np.zeros((1, 6)), 0.0, 10,
                                1.0, 5, converged, ident, method="multiple", details=details)


def test_two_gust_models_are_averaged_with_their_difference_in_the_intervals():
    """Equal weights: the mean, covariance (P1 + P2)/2 + (d/2)(d/2)^T. A coefficient the second gust
    model moves by d gets sigma sqrt(sigma^2 + d^2/4), one it leaves alone keeps its sigma; the same
    estimate twice is itself; converged only if both are."""
    from lotsen.sysid.multiple import average_over_model_choice

    first = _result({"Y_v": -10.0, "N_r": -1.0}, {"Y_v": 0.3, "N_r": 0.02})
    second = _result({"Y_v": -10.8, "N_r": -1.0}, {"Y_v": 0.3, "N_r": 0.02}, converged=False)
    res = average_over_model_choice(first, second)
    assert res.params.Y_v == pytest.approx(-10.4) and res.params.N_r == pytest.approx(-1.0)
    assert res.std["Y_v"] == pytest.approx(0.5) and res.std["N_r"] == pytest.approx(0.02)
    assert res.details.gust_interval_shift == pytest.approx({"Y_v": -0.8 / 0.3, "N_r": 0.0})
    assert not res.converged and average_over_model_choice(first, first).converged
    assert np.all(np.linalg.eigvalsh(res.covariance) > 0)
    same = average_over_model_choice(first, first)
    assert same.std == pytest.approx(first.std) and same.params == first.params
    # the other coefficients (held) are untouched
    assert res.params.m11 == first.params.m11
