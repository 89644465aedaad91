"""The lab loop's designed experiment on hull B (the catamaran, not built like lotsen's model): the
estimator must stay consistent where the model is wrong at speed (docs/fusion.md, "The model's
velocity error"). In-process, as `lotsen experiment run designed.yaml --physics` flies it against
`hull_server.py --hull b` (bench_hull_b.py, table 3)."""

import sys
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from hull_b_plant import run_experiment  # noqa: E402

from lotsen.sysid.experiment import load_experiment  # noqa: E402


def test_designed_experiment_on_hull_b_keeps_the_estimate_on_the_fixes():
    """Both propellers at 100 rev/s through turns at 1.5-2 m/s: the model's sway in the turn is 0.25 m/s
    off hull B's. Before GNSS velocity's covariance matching the EKF booked it as a 0.2-0.3 m/s current,
    left the fixes by 0.38 m and the supervisor held at 22.0 s (failsafe estimator, GNSS inconsistent).
    Now no estimator fault and the position within 4 cm until hull B itself leaves the design's 30 x 30 m
    area at 25.1 s (the design was checked on the model, which turns tighter: not the estimator's)."""
    node, errors = run_experiment(load_experiment(HERE / "designed_60s_30x30.yaml"), seed=0)
    assert "estimator" not in node.aborted, node.aborted
    assert node.rows and node.rows[-1][0] >= 22.5, f"ended at {node.rows[-1][0] if node.rows else 0:.1f} s: {node.aborted}"
    worst = max(e for t, e in errors if t >= 2.0)
    assert worst < 0.1, f"the estimate left the hull by {worst:.3f} m"
