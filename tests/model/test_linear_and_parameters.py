import json

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.model import (
    DEFAULT_PARAMETERS, VesselModel, VesselParameters, condition_16d, linearise, linearise_straight,
    parameter_table_markdown, stability_report, straight_trim,
)


def test_condition_16d_is_the_seed_formula():
    p = DEFAULT_PARAMETERS
    m = VesselModel()
    for U0 in (0.0, 0.4, 1.2):
        expected = (p.Y_v - p.Y_uv * abs(U0)) * p.N_r - (p.m11 * U0 + p.Y_r) * (p.N_v - (p.m11 - p.m22) * U0)
        assert condition_16d(m, U0) == pytest.approx(expected)


def test_stability_report_of_the_defaults():
    rep = stability_report(VesselModel())
    assert rep.U_max == pytest.approx(1.7354, abs=1e-3)
    c = rep.conditions
    assert c["16a X_u > 0"] and c["16b Y_v > 0"] and c["16c N_r > 0"] and c["16d at U0 = 0"]
    assert not rep.stable_for_all_speeds  # the Munk moment destabilises the default hull at speed
    # consistency: the linear model is unstable exactly when 16d fails
    for U, ev in zip((0.0, rep.U_max), rep.eigenvalues.values()):
        assert (max(e.real for e in ev) < 0) == (condition_16d(VesselModel(), U) > 0)
    assert any("FAILS" in line for line in rep.lines())


def test_a_stable_hull_is_reported_stable():
    p = DEFAULT_PARAMETERS.with_updates(N_v=-20.0, N_r=8.0)  # a large skeg: restoring yaw moment
    rep = stability_report(VesselModel(p))
    assert rep.stable_for_all_speeds


def test_seed_linearisation_equals_the_full_jacobian_without_housing_force():
    model = VesselModel(DEFAULT_PARAMETERS.with_updates(C_N=0.0))
    U0 = 0.6
    x0, u0 = straight_trim(model, U0)
    assert model.f(0, x0, u0)[3:] == pytest.approx(np.zeros(3), abs=1e-12)  # trim is an equilibrium
    A, _ = linearise(model, x0, u0)
    lin = linearise_straight(model, U0)
    assert np.allclose(A[4:, 4:], -np.linalg.solve(lin.M, lin.N))
    assert A[3, 3] == pytest.approx(lin.surge_pole)


def test_parameters_round_trip_and_errors():
    d = DEFAULT_PARAMETERS.to_dict()
    assert list(d) == list(VesselParameters.names())
    assert VesselParameters.from_dict(json.loads(json.dumps({**d, "std": {}}))) == DEFAULT_PARAMETERS
    with pytest.raises(ConfigError, match="unknown parameter 'm44'"):
        VesselParameters.from_dict({"m44": 1.0})
    with pytest.raises(ConfigError, match="X_u: expected a number, got 'fast'"):
        VesselParameters.from_dict({"X_u": "fast"})
    with pytest.raises(ConfigError, match=r"X_u: 1e-320 is a denormal number"):
        VesselParameters.from_dict({"X_u": 1e-320})
    with pytest.raises(ConfigError, match="not a finite number"):
        VesselParameters(m11=float("nan"))
    assert DEFAULT_PARAMETERS.physical_violations() == []
    assert "X_u = -1 must be > 0" in " ".join(DEFAULT_PARAMETERS.with_updates(X_u=-1.0).physical_violations())
    assert "| m11 | 14 | kg |" in parameter_table_markdown()
