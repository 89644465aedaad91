"""Experiments through the runtime on the boat's drivers (here their emulated twins)."""

from dataclasses import replace

import numpy as np
import pytest

from lotsen.stack.experiment import run_on_stack
from lotsen.runtime.config import LaunchConfig, LoggingSection
from lotsen.sysid.data import load_csv, save_csv
from lotsen.sysid.experiment import parse_experiment


def _config(tmp_path):
    return replace(LaunchConfig(mode="hardware", logging=LoggingSection(enabled=True, directory=str(tmp_path))),
                   extra={"emulated": True})


@pytest.fixture(scope="module")
def steps_run(tmp_path_factory):
    """8 s of speed steps on the emulated boat, recorded to MCAP: (node, log directory)."""
    d = tmp_path_factory.mktemp("steps")
    exp = parse_experiment({"name": "steps", "area": {"size_m": [60, 60]},
                                "pieces": [{"type": "steps", "step_duration_s": 4,
                                            "levels": [{"n_rps": 40}, {"n_rps": 70}]}]})
    return run_on_stack(exp, _config(d), realtime=False), d


def test_speed_steps_on_the_emulated_boat(steps_run, tmp_path):
    node, logdir = steps_run
    assert node.done and not node.aborted
    rec = node.record()
    assert 150 <= len(rec.t) <= 165  # 8 s at 20 Hz
    assert rec.outputs[-1, 0] > 2.0  # moved north
    # propeller speeds are the tachometers' (the PI loop reaches the commanded 70 rev/s)
    assert abs(np.median(rec.inputs[-20:, 2]) - 70) < 5
    save_csv(rec, tmp_path / "run.csv")
    back = load_csv(tmp_path / "run.csv")
    assert back.output_names == ("north", "east", "psi", "r", "u", "v")
    assert list(logdir.glob("*.mcap")), "the run is also in its MCAP log"


def test_run_log_to_asynchronous_record_export_and_identify(steps_run, tmp_path, capsys):
    """`lotsen export RUN.mcap` and `lotsen identify RUN.mcap` share one path (issue 16)."""
    import json

    from lotsen.logs.export import sysid_record
    from lotsen.cli.main import main
    from lotsen.logs.reader import LogReader
    from lotsen.messages import Topic
    from lotsen.model import DEFAULT_PARAMETERS

    node, logdir = steps_run
    (log,) = logdir.glob("*.mcap")
    rec = sysid_record(log)
    assert rec.output_names == ("north", "east", "psi", "r") and "outputs raw" in rec.source
    has_u, has_y = np.isfinite(rec.inputs).any(axis=1), np.isfinite(rec.outputs).any(axis=1)
    assert not (has_u & has_y).any() and has_u.any() and has_y.any()  # each row: inputs or outputs
    # inputs: the achieved values (tachometers), one row per actuator message, at its own stamp
    act = [m for t, m in LogReader(log).messages([Topic.ACTUATORS])]
    assert has_u.sum() == len(act)
    assert np.allclose(np.sort(rec.t[has_u]), np.sort([m.stamp_s for m in act]))
    assert abs(np.nanmax(rec.inputs[:, 2]) - max(m.n1_rps for m in act)) < 1e-9
    # outputs: GNSS positions (relative to the first fix), IMU yaw rate, the estimate's heading
    n_gnss = sum(1 for _, m in LogReader(log).messages([Topic.GNSS]) if m.usable)
    assert np.isfinite(rec.outputs[:, 0]).sum() == n_gnss and np.nanmax(rec.outputs[:, 0]) > 2.0

    assert main(["export", str(log), "--out", str(tmp_path / "x")]) == 0
    exported = tmp_path / "x" / "sysid.csv"
    # achieved values are readings at their stamps: the file says so before the header
    assert exported.read_text().splitlines()[:2] == [  # the IMU's samples too: the record's sea state
        "# inputs: sample", "t,alpha1,alpha2,n1,n2,nt,north,east,psi,r,imu_ax,imu_ay,imu_az,imu_p,imu_q,imu_r"]
    free = ("X_uu", "mu_az")
    fix = [a for n in DEFAULT_PARAMETERS.names() if n not in free
           for a in ("--fix", f"{n}={getattr(DEFAULT_PARAMETERS, n)}")]
    outs, codes = [], []
    for src in (log, exported):
        out = tmp_path / f"{src.suffix[1:]}.json"
        # a short steps record on the lake boat, the rest fixed at the defaults: the verdict may refuse
        # (X_uu at +-2.7 %, above the core rule's 2.5 %); the file is written either way
        codes.append(main(["identify", str(src), "--out", str(out), "--holdout", "0", *fix]))
        outs.append(json.loads(out.read_text()))
    capsys.readouterr()
    assert codes[0] in (0, 1) and codes[0] == codes[1], codes
    a, b = outs
    assert a["verdict"] == b["verdict"]
    # the same record, whichever file it came from: the CSV keeps the stamps exactly and the values to 10
    # significant digits (5e-11 relative), which moved X_uu 3e-10 relative (and mu_az 1e-10); the bar
    # leaves 30 times that. (With the stamps at 10 digits too, streams stamped 1e-17 s apart were merged
    # into one row: 0.3-1.2 ppm apart, over the old bar of 1e-6 in some runs.)
    for n in free:
        assert np.isfinite(a[n]) and abs(a[n] - b[n]) <= 1e-8 * abs(a[n]) and 0 < a["std"][n] < 0.1 * abs(a[n])


def test_leaving_the_area_aborts_to_neutral(tmp_path):
    """`--no-return` (keep_inside=False): the area's edge ends the run (with the return, the boat is
    turned back first: tests/stack/test_experiment_supervised.py)."""
    exp = parse_experiment({"name": "too_far", "area": {"size_m": [6, 6]},
                                "pieces": [{"type": "constant", "duration_s": 30, "n_rps": 80}]})
    node = run_on_stack(exp, _config(tmp_path), realtime=False, keep_inside=False)
    assert node.done and "left the experiment area" in node.aborted
    assert "larger --margin" in node.aborted  # and says what to do
    assert node.record().t[-1] < 25.0


def test_unknown_keys_in_an_experiment_are_named():
    import pytest

    from lotsen.errors import ConfigError

    with pytest.raises(ConfigError, match=r"piece 1 \(constant\): unknown key\(s\) 'u'"):
        parse_experiment({"name": "x", "pieces": [{"type": "constant", "duration_s": 3, "u": {"n_rps": 8}}]})
    with pytest.raises(ConfigError, match=r"unknown key\(s\) 'pices'"):
        parse_experiment({"name": "x", "pices": [], "pieces": [{"type": "constant", "duration_s": 3}]})
    with pytest.raises(ConfigError, match=r"area.size_m\[0\]: expected a number, got 'big' \(allowed: 2 to 4000 m\)"):
        parse_experiment({"name": "x", "area": {"size_m": ["big", 3]}, "pieces": [{"type": "constant", "duration_s": 3}]})
