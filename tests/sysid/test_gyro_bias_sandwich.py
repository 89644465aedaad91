"""The yaw-rate output's offset estimated with the parameters, and the sandwich covariance for
correlated residuals (lotsen.sysid.multiple), on the independent simulator's records."""

import dataclasses

import numpy as np

from independent_sim import DEFAULTS, NAMES, generate, perturbed
from lotsen.model import VesselParameters
from lotsen.sysid.estimate import SolverOptions, parameter_scale
from lotsen.sysid.multiple import (
    MultipleShootingProblem, _fisher_from, estimate_multiple_shooting, sandwich_information,
)

START = VesselParameters.from_vector([DEFAULTS[n] for n in NAMES])


def _record(seed: int, bias: float, boat_seed: int | None = None):  # type: ignore[no-untyped-def]
    params = perturbed(np.random.default_rng(seed if boat_seed is None else boat_seed))
    g = generate(60.0, seed=seed, style="aligned", params=params)
    Y = g.record.outputs.copy()
    Y[:, g.record.output_names.index("r")] += bias
    return g, dataclasses.replace(g.record, outputs=Y)


def test_a_constant_gyro_offset_is_estimated_and_leaves_the_coefficients_as_without_it():
    g, rec = _record(103, 0.04)  # 13 x the gyro noise, as a bias "calibrated" on a drifting boat
    plain = estimate_multiple_shooting([g.record], START, {"m11": 14.0})
    res = estimate_multiple_shooting([rec], START, {"m11": 14.0}, SolverOptions(gyro_bias=True))
    assert res.converged
    b, sb = float(res.details.gyro_bias[0]), float(res.details.gyro_bias_std[0])
    assert abs(b - 0.04) <= max(3 * sb, 1e-4) and sb < 0.003
    for n in res.free_names:
        assert abs(getattr(res.params, n) - g.params[n]) <= 3 * res.std[n], n
        assert abs(getattr(res.params, n) - getattr(plain.params, n)) <= 0.5 * plain.std[n], n
    # unmodelled, the offset costs the yaw rate's information: the fit discounts r (its noise
    # re-estimated ~13x) and the yaw coefficients' intervals widen
    blind = estimate_multiple_shooting([rec], START, {"m11": 14.0})
    assert blind.std["m33"] > 1.3 * res.std["m33"]


def test_one_offset_per_record():
    _, a = _record(104, 0.03)
    _, b = _record(105, -0.02, boat_seed=104)  # two experiments on one boat
    res = estimate_multiple_shooting([a, b], START, {"m11": 14.0}, SolverOptions(gyro_bias=True))
    assert res.converged
    assert np.allclose(res.details.gyro_bias, [0.03, -0.02], atol=3 * res.details.gyro_bias_std.max())
    assert res.details.gyro_bias_std.max() < 0.002


def test_sandwich_reduces_to_the_fisher_information_for_white_residuals():
    g, _ = _record(106, 0.0)
    res = estimate_multiple_shooting([g.record], START, {"m11": 14.0})
    prob = MultipleShootingProblem([g.record], SolverOptions(noise_std=res.details.noise_std))
    theta = np.array(res.params.to_vector())
    free = np.arange(1, len(NAMES))
    tscale = parameter_scale(theta)
    lin = prob.linearise(theta, res.details.nodes, free, tscale, True)
    blocks = prob.normal_blocks(lin)
    F = _fisher_from(prob, lin, blocks)
    Fs = sandwich_information(prob, lin, blocks, F)
    ratio = np.sqrt(np.diag(np.linalg.inv(Fs)) / np.diag(np.linalg.inv(F)))
    assert 0.7 < float(np.median(ratio)) < 1.3 and ratio.max() < 1.8, ratio


def test_a_walking_gyro_offset_is_followed_block_by_block():
    # a MEMS gyro's bias wanders over a record (temperature): here a ramp of 0.012 rad/s over 120 s,
    # 4 x the gyro noise at its end; one offset per 30-s block follows it
    params = perturbed(np.random.default_rng(107))
    g = generate(120.0, seed=107, style="aligned", params=params)
    t = g.record.t - g.record.t[0]
    Y = g.record.outputs.copy()
    Y[:, g.record.output_names.index("r")] += 0.012 * t / 120.0
    rec = dataclasses.replace(g.record, outputs=Y)
    res = estimate_multiple_shooting([rec], START, {"m11": 14.0},
                                     SolverOptions(gyro_bias=True, gyro_offset_block_s=30.0))
    assert res.converged
    b, sb = res.details.gyro_bias, res.details.gyro_bias_std
    assert len(b) == 4
    assert np.allclose(b, 0.012 * (np.arange(4) + 0.5) / 4, atol=3 * sb.max() + 0.001), b
    for n in res.free_names:
        assert abs(getattr(res.params, n) - g.params[n]) <= 3 * res.std[n], n
    # one offset for the whole record leaves the walk in the yaw rate's residuals: its noise is
    # re-estimated larger and the yaw coefficients' intervals widen
    one = estimate_multiple_shooting([rec], START, {"m11": 14.0},
                                     SolverOptions(gyro_bias=True, gyro_offset_block_s=0.0))
    assert len(one.details.gyro_bias) == 1
    assert one.details.noise_std["r"] > 1.2 * res.details.noise_std["r"]
    assert one.std["m33"] > res.std["m33"]
