"""The operator reviews a magnetometer fit: it is used at once, `mag_reject` brings back the
calibration in use before it, `mag_accept` keeps it; the fit carries its raw samples for the plot."""

from __future__ import annotations

from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection
from lotsen.stack.launch import build_stack

from .test_supervisor import ROUTE, op, run


def _stack():
    cfg = LaunchConfig(route=ROUTE, nodes=NodesSection(fusion="ekf", controller="los"),
                       sim=SimSection(initial_state=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0)),
                       extra={"failsafes": {"prearm_skip": ["pilot_link"]}})
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    stack.executor.run_until(3.0)
    op(stack, "arm")
    run(stack, 0.2)
    return stack, stack.nodes["supervisor"]


def _fusion(stack):
    return next(n for n in stack.nodes.values() if hasattr(n, "_before_review"))


def test_a_fit_is_used_then_rejected_or_accepted_by_the_operator():
    stack, sup = _stack()
    assert sup.armed
    results = []
    stack.bus.subscribe(Topic.MAG_CALIBRATION, results.append)
    fusion = _fusion(stack)
    factory = fusion.calibration
    assert "mag_accept: no magnetometer fit" in " ".join(sup.why_not(a) and f"{a}: {sup.why_not(a)}"
                                                         for a in ("mag_accept",))
    op(stack, "calibrate_mag")
    run(stack, 80.0)
    fit = results[-1]
    assert fit.ok and fit.decision == "" and 50 <= len(fit.samples) <= 200
    assert fusion.calibration is not factory and fusion.calibration.center == fit.center  # in use at once
    assert sup.why_not("mag_reject") == "" and sup.heading_calibration.startswith("the turn manoeuvre")
    op(stack, "mag_reject")
    run(stack, 0.2)
    assert results[-1].decision == "rejected" and fusion.calibration is factory
    assert sup.why_not("mag_accept") != "" and not sup.heading_calibration.startswith("the turn manoeuvre")
    op(stack, "calibrate_mag")
    run(stack, 80.0)
    op(stack, "mag_accept")
    run(stack, 0.2)
    assert results[-1].decision == "accepted" and fusion.calibration.center == results[-1].center
    assert sup.heading_calibration.startswith("the turn manoeuvre") and sup.mag_review is None
