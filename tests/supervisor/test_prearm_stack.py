"""Pre-arm checks in the supervisor on the simulated stack (EKF on the simulated sensors):
refusals list every failing check (alert, log, the page's blocked reason), the expert override
starts anyway and says so, and the default simulation passes its own checks."""

from types import SimpleNamespace

from lotsen.messages import BatteryStatus, GnssFixType, LinkStatus, OperatorCommand, Topic
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection, WebSection
from lotsen.stack.launch import build_stack
from lotsen.stack.parts import heading_calibration
from lotsen.stack.stack import example_route


def make(failsafes=None, fix_type=None, t0=3.0):
    cfg = LaunchConfig(route=example_route("figure_eight"), nodes=NodesSection(fusion="ekf", controller="los"),
                       sim=SimSection(initial_state=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0)), web=WebSection(enabled=False),
                       extra={"failsafes": failsafes if failsafes is not None else {"prearm_skip": ["pilot_link"]}})
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    seen = {Topic.ALERT: [], Topic.LOG: []}
    for topic, box in seen.items():
        stack.bus.subscribe(topic, box.append)
    if fix_type is not None:
        stack.simulator.set_gnss_fix_type(fix_type)
    stack.executor.run_until(t0)  # the EKF converged, the ESCs armed
    return stack, stack.nodes["supervisor"], seen


def op(stack, action):
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=stack.executor.clock.now(), action=action))
    stack.executor.run_for(0.2)


def refusals(seen, action):
    return [a.text for a in seen[Topic.ALERT] if a.code == f"refused:{action}"]


def blocked(stack, action):
    s = stack.bus.latest[Topic.SUPERVISOR]
    return next((b for b in s.blocked_actions if b.startswith(f"{action}:")), "")


def test_the_default_simulation_passes_its_own_checks():
    stack, sup, seen = make()
    assert sup.prearm_failures("auto") == []
    op(stack, "arm")
    op(stack, "auto")
    assert sup.mode.name == "AUTO" and not refusals(seen, "auto")


def test_auto_on_a_poor_fix_is_refused_with_the_reasons():
    stack, sup, seen = make(fix_type=GnssFixType.FIX_3D)
    op(stack, "arm")
    assert sup.armed  # arm does not need a fix (driving by hand, calibrating)
    op(stack, "auto")
    assert sup.mode.name == "MANUAL"
    text = refusals(seen, "auto")[-1]
    assert "position accuracy 1.4 m is worse than the route's corridor needs (1 m" in text
    assert "GNSS fix FIX_3D, AUTO needs RTK_FLOAT or better" in text
    logged = [e for e in seen[Topic.LOG] if e.data.get("refused") == "auto"][-1]
    assert logged.data["prearm_failed"] == ["position", "gnss"] and "position accuracy" in logged.text
    assert "position accuracy 1.4 m" in blocked(stack, "auto")  # the page's AUTO button says why


def test_auto_with_an_uncalibrated_heading_source_is_refused_until_calibrated():
    stack, sup, seen = make()
    sup.heading_calibration = ""  # as on the boat without nodes.mag_calibration_file
    op(stack, "arm")
    op(stack, "auto")
    assert sup.mode.name == "MANUAL"
    assert "heading: magnetometer not calibrated" in refusals(seen, "auto")[-1]
    op(stack, "calibrate_mag")
    stack.executor.run_for(80.0)  # one slow turn, then the fit
    assert sup.mode.name == "HOLD" and sup.heading_calibration.startswith("the turn manoeuvre")
    op(stack, "auto")
    assert sup.mode.name == "AUTO", refusals(seen, "auto")[-1:]


def test_every_failing_check_is_listed_together():
    stack, sup, seen = make(failsafes={}, fix_type=GnssFixType.FIX_3D)
    sup.heading_calibration = ""
    op(stack, "arm")
    op(stack, "auto")
    text = refusals(seen, "auto")[-1]
    for part in ("position accuracy", "GNSS fix FIX_3D", "magnetometer not calibrated", "no pilot link or RC"):
        assert part in text, text


def test_pilot_link_or_rc_is_needed_for_auto():
    stack, sup, seen = make(failsafes={})
    op(stack, "arm")
    op(stack, "auto")
    assert sup.mode.name == "MANUAL" and "no pilot link or RC" in refusals(seen, "auto")[-1]
    t = stack.executor.clock.now()
    stack.bus.publish(Topic.LINK, LinkStatus(stamp_s=t, pilot_connected=True, last_heard_s=t))
    op(stack, "auto")
    assert sup.mode.name == "AUTO"


def test_arm_is_refused_below_the_return_reserve():
    stack, sup, seen = make()
    stack.bus.publish(Topic.BATTERY, BatteryStatus(stamp_s=stack.executor.clock.now(), voltage_v=11.2,
                                                   remaining_frac=0.18))
    op_now = OperatorCommand(stamp_s=stack.executor.clock.now(), action="arm")
    stack.bus.publish(Topic.OPERATOR, op_now)  # before the simulated battery's next reading
    assert not sup.armed
    assert refusals(seen, "arm")[-1] == "arm refused: battery 18 % is below the return reserve 25 %"


def test_the_expert_override_starts_anyway_and_is_logged():
    stack, sup, seen = make(failsafes={"prearm_skip": ["pilot_link"], "prearm_override": True},
                            fix_type=GnssFixType.FIX_3D)
    op(stack, "arm")
    op(stack, "auto")
    assert sup.mode.name == "AUTO"
    over = [e for e in seen[Topic.LOG] if "pre-arm checks overridden for auto" in e.text]
    assert over and over[0].level == "warning" and over[0].data["prearm_overridden"] == ["position", "gnss"]
    assert "prearm_override" in over[0].text and "position accuracy 1.4 m" in over[0].text
    assert any(a.code == "prearm_override:auto" for a in seen[Topic.ALERT])


def test_the_override_does_not_start_without_a_route():
    stack, sup, seen = make(failsafes={"prearm_override": True})
    sup.set_route(None, None)
    op(stack, "arm")
    op(stack, "auto")
    assert sup.mode.name == "MANUAL" and refusals(seen, "auto")[-1] == "auto refused: no route loaded"


def test_where_the_heading_calibration_comes_from():
    def stack(fusion="ekf", file=None, simulator=None):
        return SimpleNamespace(config=SimpleNamespace(nodes=SimpleNamespace(fusion=fusion, mag_calibration_file=file)),
                               simulator=simulator)
    assert heading_calibration(stack()) == ""  # hardware without a calibration file
    assert "mag.json" in heading_calibration(stack(file="mag.json"))
    assert "factory" in heading_calibration(stack(simulator=object()))
    assert heading_calibration(stack(fusion="truth", simulator=object())) != ""
