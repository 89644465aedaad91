"""RC semantics in the supervisor: takeover above every mode, the e-stop switch latches, a lost
RC link while the RC has control -> neutral within 0.5 s (docs/failsafes.md)."""

from lotsen.messages import Alert, OperatorCommand, RcOverride, ThrustCommand, Topic
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection
from lotsen.stack.launch import build_stack
from lotsen.stack.stack import example_route

DRIVE = ThrustCommand(stamp_s=0.0, n1_rps=30.0, n2_rps=30.0, source="rc")


class Transmitter:
    """What the RC driver publishes: `msg` every 0.05 s while `on` (None: nothing)."""

    def __init__(self, stack):
        self.stack = stack
        self.msg: RcOverride | None = RcOverride(stamp_s=0.0, active=False)
        stack.executor.add_timer(0.05, self._tick)

    def _tick(self):
        if self.msg is not None:
            self.stack.bus.publish(Topic.RC, self.msg)

    def set(self, active=False, estop=False, link="ok", command=None):
        self.msg = RcOverride(stamp_s=self.stack.executor.clock.now(), active=active, estop=estop, link=link,
                              command=command if link == "ok" else None)


def make():
    cfg = LaunchConfig(route=example_route("figure_eight"), nodes=NodesSection(fusion="truth", controller="los"),
                       sim=SimSection(initial_state=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0)))
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    cmds, alerts = [], []
    stack.bus.subscribe(Topic.SHIP_COMMAND, lambda c: cmds.append((stack.executor.clock.now(), c)))
    stack.bus.subscribe(Topic.ALERT, alerts.append)
    tx = Transmitter(stack)
    stack.executor.run_until(1.2)
    op(stack, "arm")
    op(stack, "auto")
    stack.executor.run_for(2.0)
    sup = stack.nodes["supervisor"]
    assert sup.mode.name == "AUTO" and "rc_lost" not in sup.failsafes.active
    return stack, sup, tx, cmds, alerts


def op(stack, action):
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=stack.executor.clock.now(), action=action))


def first_neutral_after(cmds, t0):
    """When the thrusters went neutral after t0 and stayed so (None: never)."""
    later = [(t, c) for t, c in cmds if t >= t0]
    for i, (t, c) in enumerate(later):
        if all(cc.as_tuple() == (0.0,) * 5 for _, cc in later[i:]):
            return t
    return None


def test_takeover_wins_and_only_its_switch_gives_control_back():
    stack, sup, tx, cmds, _ = make()
    tx.set(active=True, command=DRIVE)
    stack.executor.run_for(0.3)
    assert sup.mode.name == "RC" and cmds[-1][1].n1_rps == 30.0
    for action in ("auto", "hold", "manual"):
        op(stack, action)
    stack.executor.run_for(0.3)
    assert sup.mode.name == "RC"
    tx.set(active=False)
    stack.executor.run_for(0.3)
    assert sup.mode.name == "HOLD" and "RC override released" in sup.reason


def test_estop_switch_latches_until_the_takeover_switch_is_cycled_or_reset():
    stack, sup, tx, cmds, alerts = make()
    t0 = stack.executor.clock.now()
    tx.set(estop=True)
    stack.executor.run_for(0.5)
    assert sup.mode.name == "ESTOP" and not sup.armed
    assert first_neutral_after(cmds, t0) - t0 <= 0.2
    assert any(a.code == "estop" and "RC transmitter" in a.text and a.severity == "critical" for a in alerts)
    tx.set(estop=False)
    stack.executor.run_for(0.5)
    assert sup.mode.name == "ESTOP"  # latched: the switch going back does not release it
    op(stack, "reset_estop")
    stack.executor.run_for(0.3)
    assert sup.mode.name == "MANUAL"
    tx.set(estop=True)  # the switch wins over a web reset while it is on
    stack.executor.run_for(0.2)
    op(stack, "reset_estop")
    stack.executor.run_for(0.3)
    assert sup.mode.name == "ESTOP"
    # the e-stop switch also wins over the takeover switch; after it, taking over needs the
    # takeover switch to go on again (it was on all along: no edge, no RC)
    tx.set(active=True, estop=True)
    stack.executor.run_for(0.3)
    tx.set(active=True, command=DRIVE)
    stack.executor.run_for(0.5)
    assert sup.mode.name == "ESTOP"
    tx.set(active=False)
    stack.executor.run_for(0.2)
    tx.set(active=True, command=DRIVE)
    stack.executor.run_for(0.3)
    assert sup.mode.name == "RC" and cmds[-1][1].n1_rps == 30.0  # the pilot drives the disarmed boat


def test_rc_link_lost_or_failsafe_while_rc_drives_gives_neutral_within_half_a_second():
    for link in ("lost", "failsafe", None):  # None: the driver itself went silent
        stack, sup, tx, cmds, alerts = make()
        tx.set(active=True, command=DRIVE)
        stack.executor.run_for(1.0)
        assert cmds[-1][1].n1_rps == 30.0
        t0 = stack.executor.clock.now()
        if link is None:
            tx.msg = None
        else:
            tx.set(active=False, estop=True, link=link)  # switches read in failsafe: not believed
        stack.executor.run_for(2.0)
        t_neutral = first_neutral_after(cmds, t0)
        assert t_neutral is not None and t_neutral - t0 <= 0.5, (link, t_neutral)
        assert sup.mode.name == "RC", link  # no autonomy resumes, no e-stop from failsafe values
        assert "rc_lost" in sup.failsafes.active and any(a.code == "failsafe:rc_lost" for a in alerts)
        # the link returns with the takeover switch off: released as usual
        tx.set(active=False)
        stack.executor.run_for(0.3)
        assert sup.mode.name == "HOLD", link


def test_rc_link_lost_outside_rc_mode_is_reported_and_auto_goes_on():
    stack, sup, tx, cmds, alerts = make()
    tx.set(link="lost")
    stack.executor.run_for(2.0)
    assert sup.mode.name == "AUTO" and "rc_lost" in sup.failsafes.active
    status = stack.bus.latest[Topic.SUPERVISOR]
    assert any(w.startswith("rc_lost") for w in status.warnings)
    tx.set()
    stack.executor.run_for(1.0)
    assert "rc_lost" not in sup.failsafes.active
    assert any(isinstance(a, Alert) and a.code == "failsafe:rc_lost" and not a.active for a in alerts)
