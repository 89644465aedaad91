"""The EKF's innovation gates in closed form equal scipy's chi-square quantiles."""

import pytest

from lotsen.fusion.ekf import chi2_quantile

chi2 = pytest.importorskip("scipy.stats").chi2


@pytest.mark.parametrize("p", [0.5, 0.9, 0.99, 0.997, 0.9999, 1 - 1e-9])
@pytest.mark.parametrize("dof", [1, 2])
def test_closed_form_gate_equals_scipy(p, dof):
    assert chi2_quantile(p, dof) == pytest.approx(float(chi2.ppf(p, dof)), rel=1e-9)


def test_other_degrees_of_freedom_are_refused():
    with pytest.raises(ValueError):
        chi2_quantile(0.99, 3)
