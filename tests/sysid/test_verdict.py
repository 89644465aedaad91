"""The verdict on an identification result (lotsen.sysid.judge.physical_verdict) and the loaders that honour it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
from lotsen.stack.stack import load_parameters
from lotsen.sysid.judge import MAX_WEAK
from lotsen.sysid.judge import physical_verdict as judge

WHITE = {"north": np.full(40, 0.1), "east": np.full(40, 0.15)}
DRIVEN = {"north": np.full(40, 0.9), "east": np.full(40, 0.95)}


def test_a_good_fit_is_ok_and_weak_coefficients_are_named():
    assert judge(True, 9, [], {"m22": 0.01, "N_r": 0.02}, WHITE).verdict == "ok"
    v = judge(True, 9, [], {"m22": 0.01, "Y_rv": 0.12, "kappa": 0.09}, WHITE)
    assert v.verdict == "weak" and v.weakly_determined == ["Y_rv", "kappa"]


def test_a_core_coefficient_must_be_determined_to_its_promised_5_percent():
    """The core eight are promised within 5 %: a 2.5 % sigma is the most that promise tolerates; a
    3.3 % sigma on Y_v (a random boat's battery; its estimate was 6.5 % off) refuses, and says why."""
    core = ("Y_v", "N_r")
    assert judge(True, 9, [], {"Y_v": 0.024, "N_r": 0.005}, WHITE, core=core).verdict == "ok"
    v = judge(True, 9, [], {"Y_v": 0.033, "N_r": 0.005, "kappa": 0.03}, WHITE, core=core)
    assert v.verdict == "refused" and v.weakly_determined == [], v
    assert any("Y_v +-3.3 %" in r and "within 5 %" in r for r in v.reasons), v.reasons


@pytest.mark.parametrize("kwargs, words", [
    (dict(converged=False), "did not converge in 60 iterations"),
    (dict(at_bounds=["N_vv", "kappa"]), "N_vv, kappa ended at the physical bound"),
    (dict(residual_autocorr=DRIVEN), "does not explain the track"),
    (dict(relative_sigma={f"p{i}": 0.1 for i in range(MAX_WEAK + 1)}), "weakly determined"),
])
def test_what_makes_numbers_untrustworthy_refuses_them_with_the_reason(kwargs, words):
    args = dict(converged=True, iterations=60, at_bounds=[], relative_sigma={"m22": 0.01}, residual_autocorr=WHITE)
    v = judge(**{**args, **kwargs})
    assert v.verdict == "refused" and any(words in r for r in v.reasons), v.reasons


def test_loaders_refuse_a_refused_file_and_skip_identification_extras(tmp_path):
    p = tmp_path / "p.json"
    coeffs = DEFAULT_PARAMETERS.to_dict()
    p.write_text(json.dumps({**coeffs, "std": {"m22": 0.1}, "verdict": "weak",
                             "identification": {"reasons": [], "track_autocorr_1s": 0.2}}))
    assert load_parameters(str(p)) == DEFAULT_PARAMETERS
    p.write_text(json.dumps({**coeffs, "verdict": "refused", "identification": {"reasons": ["N_vv at its bound"]}}))
    with pytest.raises(ConfigError, match="identification refused these coefficients .N_vv at its bound"):
        load_parameters(str(p))
    with pytest.raises(ConfigError, match="unknown parameter 'm_22'"):  # a misspelt coefficient is still an error
        VesselParameters.from_dict({"m_22": 24.0})
