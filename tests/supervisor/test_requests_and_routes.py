"""Operator requests against the modes' capability predicates, alerts, routes received as
PlannedRoute (planned once, checked, read back), progress and ETA."""

import math
from dataclasses import replace

from lotsen.messages import OperatorCommand, PlannedRoute, RouteMessage, Topic
from lotsen.planning import plan_route
from lotsen.planning.exchange import planned_route_message, route_id
from lotsen.planning.io import load_route, route_from_dict, route_to_dict
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection
from lotsen.stack.launch import build_stack
from lotsen.stack.stack import example_route


def make(route=None, esc_arm_time_s=1.0):
    cfg = LaunchConfig(route=route, nodes=NodesSection(fusion="truth", controller="los"),
                       sim=SimSection(initial_state=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0), esc_arm_time_s=esc_arm_time_s),
                       extra={"failsafes": {"prearm_skip": ["pilot_link"]}})  # no page here
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    seen = {Topic.ALERT: [], Topic.PROGRESS: [], Topic.ACTIVE_ROUTE: [], Topic.PATH: []}
    for topic, box in seen.items():
        stack.bus.subscribe(topic, box.append)
    return stack, stack.nodes["supervisor"], seen


def op(stack, action):
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=stack.executor.clock.now(), action=action))


def status(stack):
    return stack.bus.latest[Topic.SUPERVISOR]


def test_arm_waits_for_the_escs_and_every_thrusting_mode_needs_it():
    stack, sup, seen = make(example_route("figure_eight"), esc_arm_time_s=2.0)
    stack.executor.run_until(0.5)
    op(stack, "arm")
    assert not sup.armed
    assert seen[Topic.ALERT][-1].code == "refused:arm" and "ESCs" in seen[Topic.ALERT][-1].text
    assert any(b.startswith("arm: the ESCs are not armed") for b in status(stack).blocked_actions)
    op(stack, "auto")
    assert sup.mode.name == "MANUAL" and seen[Topic.ALERT][-1].code == "refused:auto"
    assert "arm first" in seen[Topic.ALERT][-1].text
    stack.executor.run_until(2.5)
    assert status(stack).escs_armed and "arm" in status(stack).available_actions
    op(stack, "arm")
    assert sup.armed and status(stack).armed
    assert "auto" in status(stack).available_actions
    op(stack, "auto")
    stack.executor.run_for(3.0)
    assert sup.mode.name == "AUTO"
    op(stack, "disarm")  # always possible: thrusters neutral at once
    stack.executor.run_for(0.3)
    assert sup.mode.name == "MANUAL" and not sup.armed
    assert stack.bus.latest[Topic.SHIP_COMMAND].as_tuple() == (0.0,) * 5


def test_estop_disarms_and_buttons_follow_the_mode():
    stack, sup, seen = make(example_route("figure_eight"))
    stack.executor.run_until(1.5)
    op(stack, "arm")
    op(stack, "estop")
    stack.executor.run_for(0.2)
    s = status(stack)
    assert s.mode == "ESTOP" and not s.armed
    assert set(s.available_actions) == {"estop", "reset_estop", "rtk_start", "rtk_stop", "logging_on", "logging_off"}
    assert any(b == "auto: emergency stop is latched; reset it first" for b in s.blocked_actions)
    assert seen[Topic.ALERT][-1].severity == "critical"


def test_a_planned_route_is_accepted_read_back_and_followed_with_progress():
    stack, sup, seen = make()
    stack.executor.run_until(1.5)
    route = load_route(example_route("figure_eight"))
    msg = planned_route_message(route, plan_route(route), stamp_s=1.5, source="web")
    stack.bus.publish(Topic.ROUTE, msg)
    back = seen[Topic.ACTIVE_ROUTE][-1]
    assert back.route_id == msg.route_id == route_id(back.route) == status(stack).route_id
    assert back.route == route_to_dict(route)
    assert len(seen[Topic.PATH][-1].north_m) <= sup.config.path_message_points + 1
    op(stack, "arm")
    op(stack, "auto")
    stack.executor.run_for(30.0)
    p = seen[Topic.PROGRESS][-1]
    assert p.mode == "AUTO" and p.route_id == msg.route_id
    assert 0.0 < p.progress_m < p.path_length_m and math.isclose(p.remaining_m, p.path_length_m - p.progress_m,
                                                                   abs_tol=1e-3)
    assert 0 <= p.next_node < len(route.nodes) and 0.0 < p.distance_to_next_node_m < p.path_length_m
    assert 0.0 < p.eta_s < 2.0 * p.remaining_m / 0.3  # at the planned 0.5 m/s, not absurd
    etas = [q.eta_s for q in seen[Topic.PROGRESS][-10:]]
    assert etas == sorted(etas, reverse=True)  # counts down


def test_routes_that_are_not_planned_or_leave_the_area_are_refused():
    stack, sup, seen = make()
    stack.executor.run_until(0.5)
    route = load_route(example_route("figure_eight"))
    stack.bus.publish(Topic.ROUTE, RouteMessage(stamp_s=0.5, route=route_to_dict(route)))
    assert sup.path is None and seen[Topic.ALERT][-1].code == "refused:route"
    assert "PlannedRoute" in seen[Topic.ALERT][-1].text
    msg = planned_route_message(route, plan_route(route))
    shifted: PlannedRoute = replace(msg, east_m=tuple(e + 25.0 for e in msg.east_m))  # 25 m east: outside
    stack.bus.publish(Topic.ROUTE, shifted)
    assert sup.path is None and "leaves the navigable area" in seen[Topic.ALERT][-1].text
    broken = replace(msg, s_m=tuple(reversed(msg.s_m)))
    stack.bus.publish(Topic.ROUTE, broken)
    assert sup.path is None and "strictly increasing" in seen[Topic.ALERT][-1].text
    assert sup.counters["routes_refused"] == 2


def test_the_configured_area_is_the_boats_own_whatever_area_the_route_declares():
    """issue 41 item 4: the page cleared the area and a typo (north 500 for 50) planned a 998 m
    route that the boat accepted. With an area in the launch config the boat refuses any path
    leaving it, with or without an area of the route's own, or with a wider one; a route inside
    it without an area is accepted, and the geofence and the return keep to the configured area."""
    stack, sup, seen = make(example_route("figure_eight"))  # area 40 m x 40 m
    stack.executor.run_until(0.5)
    held = sup.route_id
    assert sup.fence is not None and held
    base = {"harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0}}
    typo = {**base, "nodes": [{"north": 500.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5}]}
    wide = {**typo, "area": [[-10, -10], [600, -10], [600, 60], [-10, 60]]}
    for r in (typo, wide):
        route = route_from_dict(r)
        stack.bus.publish(Topic.ROUTE, planned_route_message(route, plan_route(route), stamp_s=0.5, source="web"))
        alert = seen[Topic.ALERT][-1]
        assert alert.code == "refused:route" and "leaves the navigable area of the boat" in alert.text, alert.text
        assert sup.route_id == held  # the boat keeps the route it held
    inside = route_from_dict({**base, "nodes": [{"north": 30.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5}]})
    msg = planned_route_message(inside, plan_route(inside), stamp_s=0.6, source="web")
    stack.bus.publish(Topic.ROUTE, msg)
    assert sup.route_id == msg.route_id and sup.route.area is None
    assert sup.return_route().area == sup.fence.area  # the return is planned inside the configured area
    # the geofence acts on the configured area although the route has none
    sup.inputs.state = replace(stack.bus.latest[Topic.STATE], north_m=60.0, east_m=20.0)
    assert sup.geofence.check(sup.inputs, 1.0)[0]


def test_each_request_is_answered_once_and_a_resent_one_is_not_done_twice():
    """issue 41 item 2: the page resends an unconfirmed e-stop (or mode change) with the same id
    until the boat answers; the boat acts on an id once and answers every copy."""
    stack, sup, seen = make(example_route("figure_eight"))
    acks = []
    stack.bus.subscribe(Topic.OPERATOR_ACK, acks.append)
    stack.executor.run_until(1.5)

    def request(action, rid):
        stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=stack.executor.clock.now(), action=action,
                                                          source="web", request_id=rid))
        return acks[-1]

    a = request("arm", "p-1")
    assert a.accepted and a.request_id == "p-1" and a.armed and sup.armed
    a = request("auto", "p-2")
    assert a.accepted and a.mode == "AUTO"
    stack.executor.run_for(5.0)
    progress = sup.follower.progress_m
    assert progress > 0.5
    again = request("auto", "p-2")  # the same press resent: answered, not restarted from the start
    assert again.accepted and again.mode == "AUTO" and sup.follower.progress_m >= progress
    r = request("reset_estop", "p-3")
    assert not r.accepted and r.reason == "no emergency stop to reset"
    e = request("estop", "p-4")
    assert e.accepted and e.mode == "ESTOP" and not e.armed
    n = len([x for x in seen[Topic.ALERT] if x.code == "estop"])
    assert request("estop", "p-4").accepted and len([x for x in seen[Topic.ALERT] if x.code == "estop"]) == n
    op(stack, "manual")  # no request id: no answer (harnesses, older pages)
    assert acks[-1].request_id == "p-4"


def deferred_checks(stack):
    """The route checks held back as on the boat, where they run on a thread beside the loop: `finish(i)`
    completes the i-th waiting one (its result reaches the supervisor as the loop would hand it over)."""
    jobs = []
    stack.executor.run_in_background = lambda work, done: jobs.append((work, done))

    def finish(i: int = 0) -> None:
        work, done = jobs.pop(i)
        try:
            result, error = work(), None
        except Exception as exc:  # noqa: BLE001 - as the executor does
            result, error = None, exc
        done(result, error)
    return jobs, finish


def test_a_route_arriving_in_auto_is_checked_while_the_boat_flies_the_one_it_holds_then_switched_whole():
    """The check of a received route (a survey's: 0.2 s) runs beside the control loop: meanwhile the boat
    keeps the route it held (AUTO goes on, every tick commands), AUTO is refused with the reason, and
    when the check is done route, path, id and corridor change together (then HOLD: a new route while
    moving). Of two uploads only the later counts, whichever check ends first; a bad one is refused
    with its reason and the boat keeps its route."""
    stack, sup, seen = make(example_route("figure_eight"))
    jobs, finish = deferred_checks(stack)
    stack.executor.run_until(1.5)
    op(stack, "arm")
    op(stack, "auto")
    stack.executor.run_for(2.0)
    held, path = sup.route_id, sup.path
    assert sup.mode.name == "AUTO" and held

    base = {"harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0}}
    first = route_from_dict({**base, "nodes": [{"north": 30.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5}]})
    second = route_from_dict({**base, "nodes": [{"north": 20.0, "east": 30.0, "heading_deg": 90.0, "speed_mps": 0.5}]})
    m1, m2 = (planned_route_message(r, plan_route(r), stamp_s=3.5, source="web") for r in (first, second))
    stack.bus.publish(Topic.ROUTE, m1)
    stack.bus.publish(Topic.ROUTE, m2)
    commands = []
    stack.bus.subscribe(Topic.SHIP_COMMAND, commands.append)
    stack.executor.run_for(1.0)
    assert len(jobs) == 2 and sup.mode.name == "AUTO" and sup.route_id == held and sup.path is path
    assert len(commands) >= 9  # the loop went on flying the route it holds
    assert "auto: route " + m2.route_id + " is still being checked" in status(stack).blocked_actions
    finish(1)  # the later upload's check ends first: switched to it, whole
    assert sup.route_id == m2.route_id and sup.route.nodes == second.nodes and len(sup.path) == len(m2.s_m)
    assert sup._corridor[:2] == (sup.route, sup.path)  # its corridor came with it, computed off the loop
    assert sup.mode.name == "HOLD" and sup.reason == "new route received while moving"
    assert seen[Topic.ACTIVE_ROUTE][-1].route_id == m2.route_id
    finish(0)  # the earlier one, done later: superseded, changes nothing
    assert sup.route_id == m2.route_id and not sup.route_checking

    bad = replace(m1, east_m=tuple(e + 25.0 for e in m1.east_m))  # leaves the area
    stack.bus.publish(Topic.ROUTE, bad)
    op(stack, "auto")
    assert seen[Topic.ALERT][-1].code == "refused:auto" and "still being checked" in seen[Topic.ALERT][-1].text
    finish()
    assert seen[Topic.ALERT][-1].code == "refused:route" and "leaves the navigable area" in seen[Topic.ALERT][-1].text
    assert sup.route_id == m2.route_id and not sup.route_checking
    op(stack, "auto")
    assert sup.mode.name == "AUTO" and sup.active_path is sup.path
