import numpy as np

from lotsen.model import DEFAULT_PARAMETERS
from lotsen.sysid.blackbox import fit_narx, narx_fit
from lotsen.sysid.validate import fit_percent, inputs_at_outputs, residual_analysis, simulate_fit


def test_fit_percent_extremes():
    y = np.sin(np.linspace(0, 6, 50))
    assert fit_percent(y, y) == 100.0
    assert abs(fit_percent(y, np.full_like(y, y.mean()))) < 1e-9
    yn = y.copy()
    yn[3] = np.nan
    assert np.isfinite(fit_percent(yn, y))
    # heading: a 2 pi jump between measurement and prediction is no error
    assert fit_percent(np.array([3.1, -3.1, -3.0]), np.array([3.1, 3.1832, 3.2832]), True) > 99.0


def test_true_model_fits_and_residuals_are_white(short_run):
    fit = simulate_fit(DEFAULT_PARAMETERS, [short_run.record], window_s=10.0)
    assert min(fit.fit_percent.values()) > 90.0
    ra = residual_analysis(fit, inputs_at_outputs([short_run.record], 10.0))
    # north/east residuals are GNSS white noise with the true model
    assert ra.whiteness_fraction_outside["north"] < 0.3
    # a wrong model leaves structure and a worse fit
    bad = simulate_fit(DEFAULT_PARAMETERS.with_updates(N_r=6.0, mu_t=0.0008), [short_run.record], 10.0)
    assert bad.fit_percent["r"] < fit.fit_percent["r"] - 5


def test_narx_black_box_fits_but_worse_than_true_grey_box(short_run):
    rec = short_run.record
    est, val = rec.slice(0, 24), rec.slice(24, 40)
    bb = narx_fit(fit_narx([est]), [val], 10.0)
    grey = simulate_fit(DEFAULT_PARAMETERS, [val], 10.0)
    assert bb.fit_percent["psi"] > 50.0
    assert grey.fit_percent["r"] >= bb.fit_percent["r"]
