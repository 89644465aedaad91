import math

import numpy as np
import pytest

from lotsen.control.allocation import AllocationConfig, ThrustAllocator, rate_limit
from lotsen.model import DEFAULT_LIMITS, VesselGeometry, VesselModel


@pytest.fixture(scope="module")
def model() -> VesselModel:
    return VesselModel()


@pytest.fixture(scope="module")
def allocator(model: VesselModel) -> ThrustAllocator:
    return ThrustAllocator(model)


def within_limits(cmd, limits=DEFAULT_LIMITS) -> bool:
    a1, a2, n1, n2, nt = cmd
    eps = 1e-9
    return (abs(a1) <= limits.alpha_max_rad + eps and abs(a2) <= limits.alpha_max_rad + eps
            and abs(n1) <= limits.n_az_max_rps + eps and abs(n2) <= limits.n_az_max_rps + eps
            and abs(nt) <= limits.n_bow_max_rps + eps)


@pytest.mark.parametrize("tau", [(5.0, 0.0, 0.0), (-3.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, -1.5, 0.0),
                                 (0.0, 0.0, 0.5), (0.0, 0.0, -0.8), (1.0, 1.0, 0.3), (2.0, -0.7, -0.4)])
def test_feasible_force_is_reproduced_by_the_model(allocator, model, tau):
    res = allocator.allocate(tau)
    assert within_limits(res.command)
    assert not res.saturated
    # the full model at rest (housing force zero without flow) produces the requested force
    np.testing.assert_allclose(model.tau((0.0, 0.0, 0.0), res.command), tau, atol=2e-3)


def test_pure_sway_uses_the_bow_thruster(allocator):
    res = allocator.allocate((0.0, 2.0, 0.0))
    assert res.command[4] > 10.0  # bow thruster pushes to starboard


def test_saturation_stays_within_limits_and_points_the_right_way(allocator, model):
    res = allocator.allocate((50.0, 10.0, 5.0))
    assert res.saturated
    assert within_limits(res.command)
    achieved = model.tau((0.0, 0.0, 0.0), res.command)
    # yaw has priority over sway over surge: the moment comes close to its maximum
    assert achieved[2] > 2.5 and achieved[1] > 0.0 and achieved[0] >= 0.0


def test_saturation_gives_up_speed_before_yaw(allocator, model):
    """Full-ahead plus a feasible moment: the moment is kept, the surge force gives way."""
    res = allocator.allocate((50.0, 0.0, 1.0))
    assert res.saturated and within_limits(res.command)
    achieved = model.tau((0.0, 0.0, 0.0), res.command)
    assert achieved[2] == pytest.approx(1.0, abs=0.02)
    assert achieved[1] == pytest.approx(0.0, abs=0.05)
    assert achieved[0] > 15.0


def test_non_finite_request_gives_zero_force(allocator, model):
    res = allocator.allocate((math.nan, 1.0, 0.0))
    np.testing.assert_allclose(model.tau((0.0, 0.0, 0.0), res.command), 0.0, atol=1e-3)


def test_weaker_reverse_thrust_needs_faster_reverse_propellers():
    geom = VesselGeometry(reverse_thrust_ratio=0.5)
    m = VesselModel(geometry=geom)
    alloc = ThrustAllocator(m)
    res = alloc.allocate((-2.0, 0.0, 0.0))
    assert res.command[2] < 0 and res.command[3] < 0
    np.testing.assert_allclose(m.tau((0.0, 0.0, 0.0), res.command), (-2.0, 0.0, 0.0), atol=2e-3)
    sym = ThrustAllocator(VesselModel()).allocate((-2.0, 0.0, 0.0))
    assert abs(res.command[2]) == pytest.approx(abs(sym.command[2]) * math.sqrt(2.0), rel=1e-2)


def test_housing_correction_reduces_the_force_error_at_speed(model):
    nu = (1.0, 0.0, 0.0)
    tau = np.array([3.0, 0.3, -0.3])
    plain = ThrustAllocator(model, config=AllocationConfig(housing_correction=False)).allocate(tau, nu=nu)
    corrected = ThrustAllocator(model).allocate(tau, nu=nu)
    err_plain = np.linalg.norm(model.tau(nu, plain.command) - tau)
    err_corr = np.linalg.norm(model.tau(nu, corrected.command) - tau)
    assert err_corr < err_plain


def test_rate_limit_respects_slew_and_ramp():
    lim = DEFAULT_LIMITS
    prev = (0.0, 0.0, 0.0, 0.0, 0.0)
    cmd = rate_limit(prev, (1.0, -1.0, 100.0, -100.0, 80.0), 0.1, lim)
    assert cmd[0] == pytest.approx(lim.alpha_rate_max_radps * 0.1)
    assert cmd[1] == pytest.approx(-lim.alpha_rate_max_radps * 0.1)
    assert cmd[2] == pytest.approx(lim.n_rate_max_rps2 * 0.1)
    assert rate_limit(None, (2.0, 0.0, 500.0, 0.0, 0.0), 0.1, lim)[:3] == (lim.alpha_max_rad, 0.0, lim.n_az_max_rps)


def test_a_price_on_reversing_an_azimuth_stops_the_hold_from_chattering(model):
    """A hold asks small forces in every direction: with only the relative hysteresis an azimuth's
    direction changed at most steps (1.6-3.6 propeller reversals a second in a calm hold). With
    switch_force_N a reversal has to save 1/2 w F^2 of cost; the forces asked are still produced."""
    rng = np.random.default_rng(3)
    taus = [np.array([0.3, 0.3, 0.08]) * rng.standard_normal(3) for _ in range(300)]

    def run(switch_force_N: float) -> tuple[int, float]:
        a = ThrustAllocator(model, DEFAULT_LIMITS, AllocationConfig(weight_slack=(1.0e6, 1.0e6, 1.0e7),
                                                                    switch_force_N=switch_force_N))
        flips, err, signs = 0, 0.0, None
        for tau in taus:
            res = a.allocate(tau)
            if signs is not None:
                flips += sum(x != y for x, y in zip(res.signs, signs))
            signs = res.signs
            err = max(err, float(np.max(np.abs(res.tau_achieved - tau))))
        return flips, err

    free, free_err = run(0.0)
    priced, priced_err = run(1.5)
    assert free > 60 and priced < free / 4, (free, priced)
    assert free_err < 1e-3 and priced_err < 1e-3
