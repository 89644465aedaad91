"""Experiments through the runtime on the boat's drivers (here their emulated twins)."""

from dataclasses import replace

import numpy as np

from lotsen.cli.experiment import run_on_stack
from lotsen.runtime.config import LaunchConfig, LoggingSection
from lotsen.sysid.data import load_csv, save_csv
from lotsen.sysid.experiment import parse_experiment


def _config(tmp_path):
    return replace(LaunchConfig(mode="hardware", logging=LoggingSection(enabled=True, directory=str(tmp_path))),
                   extra={"emulated": True})


def test_speed_steps_on_the_emulated_boat(tmp_path):
    exp = parse_experiment({"name": "steps", "area": {"size_m": [60, 60]},
                                "pieces": [{"type": "steps", "step_duration_s": 4,
                                            "levels": [{"n_rps": 40}, {"n_rps": 70}]}]})
    node = run_on_stack(exp, _config(tmp_path), realtime=False)
    assert node.done and not node.aborted
    rec = node.record()
    assert 150 <= len(rec.t) <= 165  # 8 s at 20 Hz
    assert rec.outputs[-1, 0] > 2.0  # moved north
    # propeller speeds are the tachometers' (the PI loop reaches the commanded 70 rev/s)
    assert abs(np.median(rec.inputs[-20:, 2]) - 70) < 5
    save_csv(rec, tmp_path / "run.csv")
    back = load_csv(tmp_path / "run.csv")
    assert back.output_names == ("north", "east", "psi", "r", "u", "v")
    assert list(tmp_path.glob("*.mcap")), "the run is also in its MCAP log"


def test_leaving_the_area_aborts_to_neutral(tmp_path):
    exp = parse_experiment({"name": "too_far", "area": {"size_m": [6, 6]},
                                "pieces": [{"type": "constant", "duration_s": 30, "n_rps": 80}]})
    node = run_on_stack(exp, _config(tmp_path), realtime=False)
    assert node.done and "left the experiment area" in node.aborted
    assert node.record().t[-1] < 25.0


def test_unknown_keys_in_an_experiment_are_named():
    import pytest

    from lotsen.errors import ConfigError

    with pytest.raises(ConfigError, match=r"piece 1 \(constant\): unknown key\(s\) 'u'"):
        parse_experiment({"name": "x", "pieces": [{"type": "constant", "duration_s": 3, "u": {"n_rps": 8}}]})
    with pytest.raises(ConfigError, match=r"unknown key\(s\) 'pices'"):
        parse_experiment({"name": "x", "pices": [], "pieces": [{"type": "constant", "duration_s": 3}]})
    with pytest.raises(ConfigError, match=r"area.size_m\[0\] = 'big' is not a finite number"):
        parse_experiment({"name": "x", "area": {"size_m": ["big", 3]}, "pieces": [{"type": "constant", "duration_s": 3}]})
