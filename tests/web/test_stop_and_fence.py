"""Over the real socket, with the supervisor behind it (issue 41): every request is answered by
the boat (`confirmed`, matched by the page's request id), and a route leaving the launch config's
area is refused by the boat even when a client sends it straight over the WebSocket."""

from __future__ import annotations

import json

import pytest
from websockets.sync.client import connect

from lotsen.messages import Topic
from lotsen.stack.stack import example_route

from .conftest import TOKEN, recv_until, start_stack, stop_stack


@pytest.fixture(scope="module")
def boat():
    rs = start_stack(parts=("state", "supervisor"), route=example_route("figure_eight"),
                     extra={"failsafes": {"prearm_skip": ["pilot_link"]}})
    yield rs
    stop_stack(rs)


def test_a_stop_is_confirmed_by_the_boat_and_a_resend_answered_again(boat):
    with connect(boat.ws_url) as ws:
        ws.send(json.dumps({"type": "auth", "token": TOKEN, "id": 1}))
        assert recv_until(ws, lambda m: m.get("id") == 1)["type"] == "auth_ok"
        for _ in range(2):  # the page's resend of an unconfirmed press carries the same request id
            ws.send(json.dumps({"type": "command", "action": "estop", "request": "press-41"}))
            c = recv_until(ws, lambda m: m["type"] == "confirmed" and m["request"] == "press-41", timeout=5)
            assert c["accepted"] and c["mode"] == "ESTOP" and c["armed"] is False
        ws.send(json.dumps({"type": "command", "action": "reset_estop", "request": "press-42"}))
        c = recv_until(ws, lambda m: m["type"] == "confirmed" and m["request"] == "press-42", timeout=5)
        assert c["accepted"] and c["mode"] == "MANUAL"
    estops = [m for m in boat.messages(Topic.OPERATOR) if m.action == "estop"]
    assert len(estops) == 2 and {m.request_id for m in estops} == {"press-41"}


def test_a_route_outside_the_configured_area_is_refused_when_sent_straight_over_the_socket(boat):
    """The north-500 typo of the issue, with the area left out (as after Clear): the page's planner
    plans it, the boat refuses it and keeps its route."""
    with connect(boat.ws_url) as ws:
        ws.send(json.dumps({"type": "auth", "token": TOKEN, "id": 1}))
        assert recv_until(ws, lambda m: m.get("id") == 1)["type"] == "auth_ok"
        held = recv_until(ws, lambda m: m["type"] == "telemetry" and (m.get("sup") or {}).get("route_id"),
                          timeout=10)["sup"]["route_id"]
        typo = {"harbour": {"north": 4.0, "east": 20.0, "heading_deg": 0.0},
                "nodes": [{"north": 20.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5},
                          {"north": 500.0, "east": 20.0, "heading_deg": 0.0, "speed_mps": 0.5}]}
        ws.send(json.dumps({"type": "route", "route": typo, "id": 2}))
        assert recv_until(ws, lambda m: m.get("id") == 2, timeout=30)["type"] == "route_ok"  # the web side planned it
        alert = recv_until(ws, lambda m: m["type"] == "alert" and m["code"] == "refused:route", timeout=5)
        assert "leaves the navigable area of the boat" in alert["text"]
        frame = recv_until(ws, lambda m: m["type"] == "telemetry" and m.get("sup"), timeout=5)
        assert frame["sup"]["route_id"] == held
