"""Shared fixtures: one short simulated run (sensors on) reused by the estimation and CLI tests."""

import sys
from pathlib import Path

import pytest

from lotsen.sysid.experiment import parse_experiment

# the independent simulator (tests/sysid/independent_sim.py) is imported by name (--import-mode=importlib)
sys.path.insert(0, str(Path(__file__).parent))

SHORT_EXPERIMENT = {
    "name": "short_prbs",
    "area": {"size_m": [60, 60]},
    "pieces": [
        {"type": "prbs", "duration_s": 36, "bit_s": 1.5, "seed": 3, "base": {"n_rps": 55},
         "amplitude": {"alpha_deg": 25, "nt_rps": 60, "n1_rps": 25, "n2_rps": 25}},
    ],
}


@pytest.fixture(scope="session")
def short_experiment():
    return parse_experiment(SHORT_EXPERIMENT, "short")


@pytest.fixture(scope="session")
def short_run(short_experiment):
    from lotsen.harness.identification import run_on_simulator

    return run_on_simulator(short_experiment, seed=5, keep_truth=True)
