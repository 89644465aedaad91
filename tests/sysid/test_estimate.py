import numpy as np
import pytest

from lotsen.model import DEFAULT_PARAMETERS
from lotsen.model.parameters import OPTIONAL_TERMS
from lotsen.sysid.data import IdRecord, Segment
from lotsen.sysid.estimate import (
    NAMES, IdentifiabilityError, SolverOptions, build_problem, estimate, fisher_information, identifiability,
)
from lotsen.sysid.kernels import WindowSimulator

TRUE = DEFAULT_PARAMETERS


def test_sensitivities_match_finite_differences():
    rng = np.random.default_rng(0)
    t = np.arange(24) * 0.125
    U = np.column_stack([rng.uniform(-0.5, 0.5, 24), rng.uniform(-0.5, 0.5, 24), rng.uniform(30, 90, 24),
                         rng.uniform(30, 90, 24), rng.uniform(-60, 60, 24)])
    seg = Segment(t, U, np.zeros((24, 4)), ("north", "east", "psi", "r"))
    sim = WindowSimulator([seg], h_max=0.0625)
    th = np.array(TRUE.to_vector())
    x0 = np.array([[1.0, 2.0, 0.3, 0.8, 0.05, 0.1]])
    X, S = sim.simulate_sens(th, x0)
    for j in (0, 5, 11, 14, 15, 16):  # m11, Y_v, N_r, kappa, C_N, mu_az
        d = 1e-6 * max(abs(th[j]), 1e-3)
        tp = th.copy()
        tp[j] += d
        fd = (sim.simulate(tp, x0) - X) / d
        assert np.allclose(S[:, :, 6 + j], fd, rtol=1e-3, atol=1e-6 * np.abs(fd).max() + 1e-9), NAMES[j]
    xp = x0.copy()
    xp[0, 3] += 1e-6
    assert np.allclose(S[:, :, 3], (sim.simulate(th, xp) - X) / 1e-6, rtol=1e-3, atol=1e-6)


def test_free_scale_is_refused():
    rec = IdRecord(np.arange(20) * 0.1, np.zeros((20, 5)), np.zeros((20, 4)))
    with pytest.raises(IdentifiabilityError, match="--fix m11"):
        estimate([rec], fixed={"kappa": 0.02})


def test_scale_direction_is_detected_as_unidentifiable(short_run):
    prob = build_problem([short_run.record], window_s=10.0)
    x0s = np.array([[*w.outputs[0, :3], 0.5, 0.0, 0.0] for w in prob.windows])
    names = [n for n in NAMES if n not in OPTIONAL_TERMS]  # the seed's 18, all free: singular
    F = fisher_information(prob, TRUE.to_vector(), x0s, names)
    th = np.array([getattr(TRUE, n) for n in names])
    Fr = F * th[:, None] * th[None, :]
    rel_std = np.full(len(names), np.inf)
    ident = identifiability(Fr, names, rel_std)
    assert ident.unidentifiable
    first = ident.directions[0]
    assert first.startswith("UNIDENTIFIABLE") and "common scale" in first and "m11" in first
    assert sum(d.startswith("UNIDENTIFIABLE") for d in ident.directions) == 1


def test_recovers_parameters_from_noisy_simulated_run(short_run):
    """36 s of PRBS on the simulator with sensor noise: the well-excited parameters within 5 %
    and every estimate within 4 sigma of the truth (the poorly determined ones fixed at truth
    here, as docs/sysid.md recommends)."""
    known = {"m11": 14.0, "Y_r": TRUE.Y_r, "Y_rv": TRUE.Y_rv, "N_v": TRUE.N_v, "N_vv": TRUE.N_vv,
             "kappa": TRUE.kappa}
    rng = np.random.default_rng(2)
    start = TRUE.with_updates(**{n: v * rng.uniform(0.8, 1.2) for n, v in TRUE.to_dict().items() if n not in known})
    res = estimate([short_run.record], start, fixed=known, options=SolverOptions(window_s=10.0))
    assert res.converged and 0.7 < res.noise_factor < 1.5
    for n in res.free_names:
        true, est, s = getattr(TRUE, n), getattr(res.params, n), res.std[n]
        assert abs(est - true) <= 4 * s + 1e-12, (n, est, true, s)
        if 1.96 * s / abs(true) < 0.03:  # well determined by this record
            assert abs(est - true) / abs(true) < 0.05, (n, est, true)
    good = [n for n in res.free_names if 1.96 * res.std[n] / abs(getattr(TRUE, n)) < 0.03]
    assert {"m22", "m33", "N_r", "mu_az", "mu_t"} <= set(good)
