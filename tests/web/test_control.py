"""Control-message handling without sockets: validation, authorisation, rate limits, the pilot
seat, and a hypothesis fuzz test (no input crashes the handler or publishes anything unexpected)."""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
import yaml
from hypothesis import strategies as st

from lotsen.messages import OPERATOR_ACTIONS, LinkStatus, ManualCommand, OperatorCommand, PlannedRoute, Topic
from lotsen.planning.exchange import route_id
from lotsen.web.auth import MAX_AUTH_FAILURES, AuthGuard, PilotSeat, token_matches
from lotsen.web.control import ControlHandler
from lotsen.web.planning_api import import_route, locate_error, operator_text, plan_for_display
from lotsen.web.ratelimit import TokenBucket
from lotsen.web.validation import VIEWER_MAX_MESSAGE_CHARS, ValidationError, parse_message

TOKEN = "correct horse battery staple"  # the handler itself does not check strength (options do)
ROUTE = {"harbour": {"north": 0.0, "east": 0.0, "heading_deg": 0.0},
         "nodes": [{"north": 12.0, "east": 0.0, "heading_deg": 0.0, "speed_mps": 0.5},
                   {"north": 20.0, "east": 8.0, "heading_deg": 90.0, "speed_mps": 0.5}]}


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


async def _inline(fn, *args):
    return fn(*args)


def make(link_timeout_s: float = 1.0):
    clock = FakeClock()
    published: list[tuple[str, object]] = []
    notified: list[tuple[object, dict]] = []
    seat = PilotSeat(TOKEN, link_timeout_s, clock)
    h = ControlHandler(seat, lambda t, m: published.append((t, m)), clock, run_blocking=_inline,
                       notify=lambda s, m: notified.append((s, m)), auth_guard=AuthGuard(clock))
    return h, clock, published, notified


def send(h, session, msg) -> list[dict]:
    raw = msg if isinstance(msg, str) else json.dumps(msg)
    return asyncio.run(h.handle(session, raw))


def pilot(h, address: str = "10.0.0.1"):
    s = h.open_session(address)
    assert send(h, s, {"type": "auth", "token": TOKEN})[0]["type"] == "auth_ok"
    return s


def code(replies: list[dict]) -> str:
    assert len(replies) == 1 and replies[0]["type"] == "error", replies
    return replies[0]["code"]


# -- refusals -----------------------------------------------------------------------------------
def test_control_without_token_is_refused_and_publishes_nothing():
    h, _, published, _ = make()
    viewer = h.open_session()
    for msg in ({"type": "command", "action": "auto"}, {"type": "manual", "surge": 0.5, "sway": 0, "yaw": 0},
                {"type": "route", "route": ROUTE}, {"type": "plan", "route": ROUTE}, {"type": "release"},
                {"type": "tiles_preload", "south": 1, "north": 2, "west": 1, "east": 2, "zoom_min": 1, "zoom_max": 2},
                {"type": "tiles_cancel"}):
        r = send(h, viewer, msg)
        assert code(r) == "not_pilot" and "pilot token" in r[0]["error"]
    assert published == []


def test_a_viewer_may_stop_the_boat_only_when_the_config_allows_it():
    """extra.web.viewer_may_estop: the emergency stop (and nothing else) opens to every page."""
    h, _, published, _ = make()
    viewer = h.open_session()
    assert code(send(h, viewer, {"type": "command", "action": "estop"})) == "not_pilot"
    assert published == []
    h.viewer_may_estop = True
    reply = send(h, viewer, {"type": "command", "action": "estop", "request": "page-7"})[0]
    assert reply == {"type": "ack", "id": None, "action": "estop", "request": "page-7"}
    assert [(t, m.action, m.request_id) for t, m in published] == [(Topic.OPERATOR, "estop", "page-7")]
    for action in ("auto", "reset_estop", "arm"):
        assert code(send(h, viewer, {"type": "command", "action": action})) == "not_pilot"
    assert code(send(h, viewer, {"type": "manual", "surge": 0.5, "sway": 0, "yaw": 0})) == "not_pilot"
    assert len(published) == 1


def test_wrong_token_is_refused_and_repeated_guessing_closes_the_connection():
    h, _, published, _ = make()
    s = h.open_session()
    for i in range(MAX_AUTH_FAILURES):
        assert code(send(h, s, {"type": "auth", "token": f"guess{i}"})) == "bad_token"
    assert s.close_requested
    assert code(send(h, s, {"type": "command", "action": "auto"})) == "not_pilot"
    assert published == []


def test_second_pilot_is_refused_while_the_first_is_connected_and_heard():
    h, clock, _, _ = make(link_timeout_s=1.0)
    first = pilot(h)
    second = h.open_session()
    clock.t += 0.5
    r = send(h, second, {"type": "auth", "token": TOKEN})
    assert code(r) == "pilot_busy" and "another pilot" in r[0]["error"]
    r = send(h, second, {"type": "auth", "token": TOKEN, "takeover": True})
    assert code(r) == "pilot_busy"  # takeover only from a silent pilot
    assert h.seat.is_pilot(first) and not h.seat.is_pilot(second)


def test_release_and_takeover_of_a_silent_pilot():
    h, clock, published, notified = make(link_timeout_s=1.0)
    first = pilot(h)
    second = h.open_session()
    clock.t += 2.0  # first pilot silent for longer than the link timeout
    r = send(h, second, {"type": "auth", "token": TOKEN})
    assert code(r) == "pilot_busy" and "Take over" in r[0]["error"]
    assert send(h, second, {"type": "auth", "token": TOKEN, "takeover": True})[0]["type"] == "auth_ok"
    assert notified and notified[0][0] is first and notified[0][1]["pilot"] is False
    assert isinstance(published[-1][1], ManualCommand) and published[-1][1].surge == 0.0
    assert code(send(h, first, {"type": "command", "action": "auto"})) == "not_pilot"
    # the new pilot releases; now anyone with the token may take the seat at once
    assert send(h, second, {"type": "release"})[0]["pilot"] is False
    assert send(h, first, {"type": "auth", "token": TOKEN})[0]["type"] == "auth_ok"


@pytest.mark.parametrize("msg, expected", [
    ({"type": "manual", "surge": 0.1, "sway": 0, "yaw": 0, "boost": 1}, "unknown_field"),
    ({"type": "command", "action": "auto", "force": True}, "unknown_field"),
    ({"type": "manual", "surge": 1.5, "sway": 0, "yaw": 0}, "out_of_range"),
    ({"type": "manual", "surge": 0, "sway": -1.01, "yaw": 0}, "out_of_range"),
    ({"type": "command", "action": "self_destruct"}, "out_of_range"),
    ({"type": "manual", "surge": "0.5", "sway": 0, "yaw": 0}, "wrong_type"),
    ({"type": "manual", "surge": True, "sway": 0, "yaw": 0}, "wrong_type"),
    ({"type": "command", "action": 3}, "wrong_type"),
    ({"type": "manual", "surge": 0, "sway": 0}, "missing_field"),
    ({"type": "fly"}, "unknown_type"),
    ({"surge": 1}, "missing_field"),
    ('{"type": "manual", "surge": NaN, "sway": 0, "yaw": 0}', "bad_json"),
    ("not json", "bad_json"),
    ("[1, 2]", "bad_json"),
])
def test_invalid_messages_from_the_pilot_are_refused_with_a_clear_error(msg, expected):
    h, _, published, _ = make()
    s = pilot(h)
    published.clear()
    r = send(h, s, msg)
    assert code(r) == expected
    assert r[0]["error"]  # a message a person can read
    assert published == []


def test_error_messages_name_the_field():
    with pytest.raises(ValidationError, match=r"manual\.surge: 1\.5 outside \[-1, 1\]"):
        parse_message(json.dumps({"type": "manual", "surge": 1.5, "sway": 0, "yaw": 0}))
    with pytest.raises(ValidationError, match="unknown field 'boost'"):
        parse_message(json.dumps({"type": "manual", "surge": 0, "sway": 0, "yaw": 0, "boost": 1}))


def test_rate_limit_manual_30_per_s_and_others_5_per_s():
    h, clock, published, _ = make()
    s = pilot(h)
    published.clear()
    manual = {"type": "manual", "surge": 0.2, "sway": 0.0, "yaw": 0.0}
    replies = [send(h, s, manual) for _ in range(40)]  # all within the same instant
    assert sum(1 for _, m in published if isinstance(m, ManualCommand)) == 30
    assert [r for r in replies if r] == [[{**replies[30][0]}]] and replies[30][0]["code"] == "rate_limited"
    clock.t += 1.0  # the bucket refills
    assert send(h, s, manual) == []
    published.clear()
    results = [send(h, s, {"type": "command", "action": "hold"}) for _ in range(15)]
    assert sum(1 for r in results if r and r[0]["type"] == "ack") == 10  # burst of 10, then 5/s
    assert any(r and r[0].get("code") == "rate_limited" for r in results)


def test_valid_pilot_messages_publish_the_bus_messages():
    h, clock, published, _ = make()
    s = pilot(h)
    published.clear()
    for action in OPERATOR_ACTIONS:
        clock.t += 0.5
        reply, = send(h, s, {"type": "command", "action": action, "id": 7})
        assert {k: reply[k] for k in ("type", "id", "action")} == {"type": "ack", "id": 7, "action": action}
    assert [m.action for _, m in published] == list(OPERATOR_ACTIONS)
    ids = [m.request_id for _, m in published]  # a request id of the server's own when the page gave none
    assert len(set(ids)) == len(ids) and all(i.startswith("web-") for i in ids)
    assert all(t == Topic.OPERATOR and isinstance(m, OperatorCommand) for t, m in published)
    published.clear()
    send(h, s, {"type": "manual", "surge": 1, "sway": -0.5, "yaw": 0.25})
    (t, m), = published
    assert t == Topic.MANUAL and (m.surge, m.sway, m.yaw) == (1.0, -0.5, 0.25) and m.stamp_s == clock.t
    published.clear()
    r = send(h, s, {"type": "route", "route": ROUTE})
    assert r[0]["type"] == "route_ok" and r[0]["length_m"] > 20
    (t, m), = published
    assert t == Topic.ROUTE and isinstance(m, PlannedRoute) and m.route["nodes"][1]["east"] == 8.0


def test_upload_plans_once_and_publishes_that_plan_with_its_route_id():
    """The displayed result and the published PlannedRoute come from the same plan; the id is
    the content id the boat's read-back will carry."""
    h, clock, published, _ = make()
    s = pilot(h)
    published.clear()
    calls = []

    async def counting(fn, *args):
        calls.append(fn.__name__)
        return fn(*args)

    h.run_blocking = counting
    r = send(h, s, {"type": "route", "route": ROUTE})[0]
    assert calls == ["plan_for_upload"]  # planned once, in the worker
    (t, m), = published
    assert r["route_id"] == m.route_id == route_id(r["route"]) and m.stamp_s == clock.t
    assert math.isclose(m.s_m[-1], r["length_m"], abs_tol=0.01)
    assert r["path"]["n"][-1] == pytest.approx(m.north_m[-1], abs=1e-3) and len(m.node_s_m) == 3
    assert r["start_ramp"]["time_s"] == pytest.approx(0.5 / 0.2)  # harbour start at the acceleration limit
    assert h.last_upload["route_id"] == m.route_id


def test_a_route_the_planner_cannot_plan_is_not_published():
    h, _, published, _ = make()
    s = pilot(h)
    published.clear()
    bad = json.loads(json.dumps(ROUTE))
    bad["nodes"][1]["speed_mps"] = -1
    r = send(h, s, {"type": "route", "route": bad})
    assert code(r) == "route_invalid" and "node 2 speed: -1 is negative" in r[0]["error"]  # 1-based, no code
    assert r[0]["errors"][0]["kind"] == "node" and r[0]["errors"][0]["index"] == 1
    assert r[0]["errors"][0]["field"] == "speed_mps"  # the cell the page marks
    assert published == []


def test_pilot_socket_closing_publishes_a_zero_manual_command_and_frees_the_seat():
    h, _, published, _ = make()
    s = pilot(h)
    send(h, s, {"type": "manual", "surge": 0.8, "sway": 0, "yaw": 0})
    published.clear()
    h.close_session(s)
    (t, m), = published
    assert t == Topic.MANUAL and (m.surge, m.sway, m.yaw) == (0.0, 0.0, 0.0)
    assert h.seat.holder is None
    h.close_session(h.open_session())  # a viewer leaving publishes nothing
    assert len(published) == 1


def test_link_status_and_a_silent_driving_pilot_is_zeroed_once():
    h, clock, published, _ = make(link_timeout_s=1.0)
    viewer = h.open_session()
    s = pilot(h)
    send(h, s, {"type": "manual", "surge": 0.8, "sway": 0, "yaw": 0})
    published.clear()
    status = h.link_tick()
    assert isinstance(status, LinkStatus) and status.pilot_connected and status.viewers == 1
    assert status.last_heard_s == clock.t
    clock.t += 1.5
    h.link_tick()
    h.link_tick()
    zeros = [m for t, m in published if t == Topic.MANUAL]
    assert len(zeros) == 1 and zeros[0].surge == 0.0
    # a silent pilot (frozen tab, half-open link) is reported as not connected to the supervisor
    links = [m for t, m in published if t == Topic.LINK]
    assert links[0].pilot_connected and not links[-1].pilot_connected
    send(h, s, {"type": "ping"})  # heard again
    assert h.link_tick().pilot_connected and viewer is not None


def test_token_comparison_is_exact():
    assert token_matches("abc", "abc")
    assert not token_matches("abd", "abc") and not token_matches("", "abc") and not token_matches("abcd", "abc")
    assert not token_matches("äbc", "abc")


def test_token_bucket_refills_at_its_rate():
    clock = FakeClock()
    b = TokenBucket(5.0, 10.0, clock)
    assert sum(b.take() for _ in range(20)) == 10
    clock.t += 0.4
    assert sum(b.take() for _ in range(20)) == 2


# -- planning for display ------------------------------------------------------------------------
def test_plan_for_display_returns_a_thinned_path_or_errors_tied_to_nodes():
    res = plan_for_display(ROUTE)
    assert res["ok"] and res["length_m"] > 20 and len(res["path"]["n"]) < 300
    assert res["path"]["n"][0] == 0.0 and abs(res["path"]["e"][-1] - 8.0) < 1e-6
    tight = json.loads(json.dumps(ROUTE))
    tight["nodes"][1].update(north=13.0, east=1.0, heading_deg=180.0)
    res = plan_for_display(tight)
    assert not res["ok"] and res["errors"][0]["kind"] == "node" and res["errors"][0]["index"] == 1
    assert "the leg from node 1 to node 2" in res["errors"][0]["message"]
    fast = json.loads(json.dumps(ROUTE))
    fast["nodes"][0]["speed_mps"] = 2.3
    err = plan_for_display(fast)["errors"][0]
    assert err["message"] == "node 1: speed 2.3 m/s exceeds the boat's 1.5 m/s"
    assert (err["kind"], err["index"], err["field"]) == ("node", 0, "speed_mps")


def test_operator_text_counts_nodes_from_one_and_speaks_no_code():
    assert operator_text("segment 3 (nodes[2] -> nodes[3]): too sharp") == "the leg from node 3 to node 4: too sharp"
    assert operator_text("segment 0 (harbour -> nodes[0]): blocked") == "the leg from harbour to node 1: blocked"
    assert operator_text("nodes[3] (north 50) is inside obstacles[0]") == "node 4 (north 50) is inside obstacle 1"
    assert operator_text("nodes[0].heading_deg: expected a number") == "node 1 bearing: expected a number"


def test_detours_are_reported_with_where_and_how_long():
    route = yaml.safe_load((Path(__file__).parents[2] / "examples/routes/square_with_obstacle.yaml").read_text())
    res = plan_for_display(route)
    assert res["ok"] and len(res["detours"]) == 1
    d = res["detours"][0]
    assert d["leg"] == "the leg from node 1 to node 2" and 0 < d["s0"] < d["s1"] <= res["length_m"]
    assert d["length_m"] >= d["straight_m"] > 0


@pytest.mark.parametrize("message, located", [
    ("segment 0 (harbour -> nodes[0]): every candidate ...", {"kind": "node", "index": 0}),
    ("segment 3 (nodes[2] -> nodes[3]): a heading change", {"kind": "node", "index": 3}),
    ("nodes[3] (north 50, east 35) is outside the navigable area", {"kind": "node", "index": 3}),
    ("harbour.north: expected a number, got 'x'", {"kind": "harbour"}),
    ("obstacles[0]: polygon is self-intersecting", {"kind": "obstacle", "index": 0}),
    ("area: a polygon needs at least 3 vertices, got 2", {"kind": "area"}),
    ("route: missing key(s) ['harbour']", {"kind": "harbour"}),
])
def test_errors_are_located_on_the_element_they_name(message, located):
    assert locate_error(message) == located


# -- fuzz ------------------------------------------------------------------------------------------
_json_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**12, 10**12),
                          st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=20))
_json = st.recursive(_json_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)), max_leaves=12)
_field_names = st.sampled_from(["type", "id", "token", "takeover", "action", "surge", "sway", "yaw",
                                "route", "format", "text", "t", "extra"])
_types = st.sampled_from(["auth", "release", "ping", "command", "manual", "plan", "route", "export",
                          "import", "nope"])


HOSTILE = [
    '{"type": "plan", "route": {"harbour": {"north": 1' + "0" * 400 + ', "east": 0, "heading_deg": 0}, "nodes": []}}',
    '{"type": "route", "route": {"harbour": {"north": 1e400, "east": 0, "heading_deg": 0}, "nodes": []}}',
    '{"type": "plan", "route": ' + "[" * 5000 + "]" * 5000 + "}",
    "[" * 5000,
    '{"type": "import", "format": "yaml", "text": "' + "x" * 300_000 + '"}',
    '{"type": "auth", "token": "' + "y" * 100_000 + '"}',
    '{"type": "manual", "surge": 1' + "0" * 5000 + ', "sway": 0, "yaw": 0}',
]


@st.composite
def _messages(draw):
    kind = draw(st.integers(0, 3))
    if kind == 0:
        return draw(st.one_of(st.text(max_size=80), st.sampled_from(HOSTILE)))  # arbitrary or hostile text
    if kind == 1:
        return json.dumps(draw(_json))  # arbitrary JSON
    msg = {"type": draw(_types)}
    for name in draw(st.lists(_field_names, max_size=5)):
        msg[name] = draw(st.one_of(_json, st.sampled_from(list(OPERATOR_ACTIONS)), st.just(TOKEN),
                                   st.floats(-2, 2), st.just(ROUTE)))
    if kind == 3:  # mostly-valid messages: exercise the accepting paths too
        msg.update(draw(st.sampled_from([
            {"type": "manual", "surge": 0.3, "sway": 0.0, "yaw": -0.2},
            {"type": "command", "action": "hold"}, {"type": "ping", "t": 1.0},
            {"type": "auth", "token": TOKEN}, {"type": "plan", "route": {"harbour": 1, "nodes": []}}])))
    return json.dumps(msg, allow_nan=True)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(frames=st.lists(st.tuples(st.booleans(), _messages()), min_size=1, max_size=8))
def test_fuzz_no_input_crashes_the_handler_or_publishes_anything_unexpected(frames):
    h, clock, published, _ = make()
    viewer = h.open_session()
    pilot_s = pilot(h)
    published.clear()
    for as_pilot, raw in frames:
        clock.t += 0.01
        session = pilot_s if as_pilot else viewer
        n_before = len(published)
        was_pilot = h.seat.is_pilot(session)
        replies = asyncio.run(h.handle(session, raw))
        assert isinstance(replies, list) and all(isinstance(r, dict) and "type" in r for r in replies)
        json.dumps(replies, allow_nan=False)  # every reply is sendable
        new = published[n_before:]
        if not was_pilot:  # a viewer can never cause a bus message (it may become pilot though)
            assert new == [] or all(isinstance(m, ManualCommand) and m.surge == 0 for _, m in new)
        for topic, m in new:
            assert (topic, type(m)) in {(Topic.MANUAL, ManualCommand), (Topic.OPERATOR, OperatorCommand),
                                        (Topic.ROUTE, PlannedRoute)}
            if isinstance(m, ManualCommand):
                assert all(-1 <= v <= 1 and math.isfinite(v) for v in (m.surge, m.sway, m.yaw))
            if isinstance(m, OperatorCommand):
                assert m.action in OPERATOR_ACTIONS


# -- hostile input (issue 14) and viewers' rights (issue 15) ----------------------------------------
@pytest.mark.parametrize("raw, expected_code, expected_text", [
    ('{"type": "plan", "route": {"harbour": {"north": 1' + "0" * 400 + ', "east": 0, "heading_deg": 0}, "nodes": []}}',
     "out_of_range", "plan.route.harbour.north: integer of 401 digits is out of range"),
    ('{"type": "plan", "route": {"harbour": {"north": 1e400, "east": 0, "heading_deg": 0}, "nodes": []}}',
     "out_of_range", "plan.route.harbour.north: number out of range"),
    ('{"type": "plan", "route": ' + "[" * 5000 + "]" * 5000 + "}", "too_large", "nested more than 16 levels"),
    ('{"type": "plan", "route": ' + "[" * 30 + "]" * 30 + "}", "too_large", "nested more than 16 levels"),
    ('{"type": "manual", "surge": 1' + "0" * 5000 + ', "sway": 0, "yaw": 0}', "bad_json", "4300 digits"),
    ('{"type": "plan", "route": {"harbour": {"north": 0, "east": 0, "heading_deg": 0}, "nodes": '
     '[{"north": 50000, "east": 0, "heading_deg": 0, "speed_mps": 0.5}]}}', "out_of_range",
     "plan.route.nodes[0].north: 50000 m outside [-2000, 2000]"),
    ('{"type": "import", "format": "yaml", "text": "' + "x" * 500_000 + '"}', "too_large", "at most 409600"),
])
def test_hostile_json_gets_a_clear_error_never_an_exception(raw, expected_code, expected_text):
    h, _, published, _ = make()
    s = pilot(h)
    published.clear()
    r = send(h, s, raw)
    assert code(r) == expected_code and expected_text in r[0]["error"], r
    assert published == []


def test_a_viewer_may_convert_routes_but_not_plan_and_sends_small_messages_only():
    h, _, published, _ = make()
    viewer = h.open_session("10.0.0.9")
    r = send(h, viewer, {"type": "export", "format": "yaml", "route": ROUTE})
    assert r[0]["type"] == "export_result" and "harbour" in r[0]["text"]
    r = send(h, viewer, {"type": "import", "format": "yaml", "text": r[0]["text"]})
    assert r[0]["type"] == "import_result" and r[0]["route"]["nodes"][1]["east"] == 8.0
    assert code(send(h, viewer, {"type": "plan", "route": ROUTE})) == "not_pilot"
    big = {"type": "import", "format": "yaml", "text": "a: " + "x" * VIEWER_MAX_MESSAGE_CHARS}
    r = send(h, viewer, big)
    assert code(r) == "too_large" and "for a viewer" in r[0]["error"]
    s = pilot(h)  # the pilot may send the same
    assert code(send(h, s, big)) == "invalid"  # parsed, then refused by the route loader
    assert published == []


def test_viewers_convert_one_at_a_time_in_all():
    h, _, _, _ = make()
    v1, v2 = h.open_session("10.0.0.8"), h.open_session("10.0.0.9")
    gate = asyncio.Event()

    async def slow(fn, *args):
        await gate.wait()
        return fn(*args)

    h.run_blocking = slow

    async def scenario():
        _, job1 = h.receive(v1, json.dumps({"type": "export", "format": "yaml", "route": ROUTE}))
        task = asyncio.ensure_future(job1)
        await asyncio.sleep(0)
        replies, job2 = h.receive(v2, json.dumps({"type": "export", "format": "yaml", "route": ROUTE}))
        gate.set()
        return replies, job2, await task

    replies, job2, first = asyncio.run(scenario())
    assert job2 is None and code(replies) == "busy" and first[0]["type"] == "export_result"
    assert h.viewer_jobs == 0


def test_yaml_aliases_are_refused_on_import():
    bomb = "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
    with pytest.raises(Exception, match="aliases .* are not allowed"):
        import_route(bomb, "yaml")


def test_token_attempts_are_limited_per_address_across_connections():
    h, clock, _, _ = make()
    replies = []
    for i in range(8):  # a new connection for every guess from the same address
        replies.append(send(h, h.open_session("192.0.2.7"), {"type": "auth", "token": f"guess{i}"})[0]["code"])
    assert replies[:5] == ["bad_token"] * 5 and set(replies[5:]) == {"rate_limited"}
    # the pilot at another address is not affected
    s = h.open_session("10.0.0.1")
    assert send(h, s, {"type": "auth", "token": TOKEN})[0]["type"] == "auth_ok"
    clock.t += 2.0  # one more attempt every 2 s
    assert send(h, h.open_session("192.0.2.7"), {"type": "auth", "token": "x"})[0]["code"] == "bad_token"


def test_the_right_token_is_never_throttled_by_reconnections():
    """A pilot reloading the page (or a Wi-Fi that drops) reconnects with the right token many
    times: only wrong tokens use the address's budget."""
    h, _, _, _ = make()
    for _ in range(12):
        s = h.open_session("192.0.2.9")
        assert send(h, s, {"type": "auth", "token": TOKEN})[0]["type"] == "auth_ok"
        h.close_session(s)


def test_the_right_token_gets_the_seat_after_a_neighbour_spent_the_addresss_guessing_budget():
    """issue 41 item 10: a stranger behind the same address (one hotspot, one NAT) spent the
    budget: its wrong tokens are refused `rate_limited` and close their connection at once, the
    pilot's right one is taken at once."""
    h, _, _, _ = make()
    for i in range(8):
        s = h.open_session("192.0.2.7")
        reply = send(h, s, {"type": "auth", "token": f"guess{i}"})[0]
        if i >= 5:
            assert reply["code"] == "rate_limited" and s.close_requested  # one guess per handshake
    pilot_session = h.open_session("192.0.2.7")
    assert send(h, pilot_session, {"type": "auth", "token": TOKEN})[0]["type"] == "auth_ok"


def test_a_replaced_credential_takes_the_seat_from_the_pilot_seated_with_the_old_one():
    """`lotsen pair --new` on the boat while a page is the pilot: the page loses the seat (told
    why) and the old credential no longer authenticates; the new one does."""
    clock = FakeClock()
    current = [TOKEN]
    notified: list[tuple[object, dict]] = []
    published: list = []
    h = ControlHandler(PilotSeat(lambda: current[0], 1.0, clock), lambda t, m: published.append((t, m)), clock,
                       run_blocking=_inline, notify=lambda s, m: notified.append((s, m)), auth_guard=AuthGuard(clock))
    s = pilot(h)
    h.link_tick()
    assert h.seat.is_pilot(s) and not notified
    current[0] = "a brand new credential of the boat"
    h.link_tick()
    assert not h.seat.is_pilot(s) and notified[-1][1]["revoked"] is True
    assert code(send(h, h.open_session(), {"type": "auth", "token": TOKEN})) == "bad_token"
    assert send(h, h.open_session("10.0.0.2"), {"type": "auth", "token": current[0]})[0]["type"] == "auth_ok"


def test_large_frames_are_charged_before_decoding():
    h, _, _, _ = make()
    viewer = h.open_session()
    big = json.dumps({"type": "export", "format": "yaml", "route": {**ROUTE, "pad": "x" * 4000}})
    codes = [send(h, viewer, big) for _ in range(14)]
    assert sum(1 for r in codes if r and r[0].get("code") == "rate_limited") == 1  # then dropped silently
    assert sum(1 for r in codes if not r) >= 3


def test_the_harbour_start_is_a_short_ramp_not_a_slow_leg():
    """Issue 17: 'leaving the harbour at 0.15 m/s, a 100 m leg planned at 660 s'. The plan
    leaves the harbour from rest at the acceleration limit and then holds the node speed; the
    page shows the ramp (start_ramp) so the first slow metres are explained."""
    route = {"harbour": {"north": 0, "east": 0, "heading_deg": 0},
             "nodes": [{"north": 100, "east": 0, "heading_deg": 0, "speed_mps": 0.5}]}
    res = plan_for_display(route)
    ramp = res["start_ramp"]
    assert ramp["speed_mps"] == 0.5 and ramp["distance_m"] < 1.0 and ramp["time_s"] < 5.0
    assert res["duration_s"] < 100 / 0.5 + 2 * ramp["time_s"] + 1.0  # about 200 s, not 660
    v, s = res["path"]["v"], res["path"]["s"]
    assert min(x for x, d in zip(v, s) if 2.0 < d < 98.0) >= 0.49


# -- the parameter sheet -------------------------------------------------------------------------
def test_the_pilot_may_lower_the_planner_speed_limit_and_the_next_plan_uses_it():
    h, _, published, _ = make()
    seen = []
    h.broadcast = seen.append
    viewer = h.open_session("10.0.0.9")
    assert code(send(h, viewer, {"type": "params", "name": "planner.speed_max_mps", "value": 1.0})) == "not_pilot"
    s = pilot(h)
    r = send(h, s, {"type": "params", "name": "planner.speed_max_mps", "value": 2.3})
    assert code(r) == "invalid"
    assert r[0]["error"] == ("top speed of planned routes: 2.3 m/s exceeds 1.5 m/s, the launch config's value "
                             "(a pilot may lower it, not raise it)")
    r = send(h, s, {"type": "params", "name": "planner.clearance_m", "value": -1})
    assert code(r) == "invalid" and "a pilot may raise it, not lower it" in r[0]["error"]
    assert code(send(h, s, {"type": "params", "name": "planner.mystery", "value": 1})) == "out_of_range"
    assert send(h, s, {"type": "params", "name": "planner.speed_max_mps", "value": 0.4})[0]["type"] == "params_ok"
    assert h.planner_config.speed_max_mps == 0.4 and seen[-1]["planner"]["speed_max_mps"]["value"] == 0.4
    assert seen[-1]["planner"]["speed_max_mps"]["launch"] == 1.5 and seen[-1]["changes"][-1]["to"] == 0.4
    res = send(h, s, {"type": "plan", "route": ROUTE})[0]
    assert not res["ok"] and res["errors"][0]["message"] == "node 1: speed 0.5 m/s exceeds the boat's 0.4 m/s"
    assert published == [] or all(t != Topic.ROUTE for t, _ in published)


def test_predict_flies_the_drafted_route_on_the_model_in_use_in_the_estimated_current():
    """The page's Predict: the pilot's drafted route planned and flown on the model in use (simulated
    time) in the current the estimator reports now; a viewer may not ask (it is the planner's time)."""
    from lotsen.model import VesselModel
    from lotsen.planning import PlannerConfig
    from lotsen.stack.page_prediction import EstimatedConditions, PagePredictor

    h, _, published, _ = make()
    model = VesselModel()
    h.predict = PagePredictor(model.params, model.geometry, "default coefficients", "mpc", PlannerConfig())
    h.estimated_current = lambda: EstimatedConditions((0.0, 0.15))
    s = pilot(h)
    reply = send(h, s, {"type": "predict", "route": ROUTE})[0]
    assert reply["type"] == "predict_result" and reply["ok"] and reply["reached_end"], reply
    assert reply["current_ne_mps"] == [0.0, 0.15] and reply["model"] == "default coefficients"
    assert 0.8 < reply["duration_s"] / reply["planned_duration_s"] < 1.2 and reply["energy_J"] > 0
    assert published == []                                     # a prediction moves nothing
    bad = send(h, s, {"type": "predict", "route": {**ROUTE, "nodes": ROUTE["nodes"][:1] + [{"north": 1e6}]}})[0]
    assert bad["type"] in ("error", "predict_result") and not bad.get("ok", False)
    viewer = h.open_session("10.0.0.9")
    assert code(send(h, viewer, {"type": "predict", "route": ROUTE})) == "not_pilot"
