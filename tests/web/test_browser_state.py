"""Issue 28 items 4, 5 and 7 in headless Chromium, each on a phone (390x844, touch) and a laptop
(1280x800): state that is never stale (connection loss greys every live value and un-greys on
reconnect, heading 0-359, alerts clear when their cause clears with the history in Events, the
active path kept for late joiners and replaced by a new upload, detours announced and drawn,
speeds along the path), operator language (1-based nodes, "exceeds the boat's", the offending
cell marked, a refused plan or upload never silently kept), the magnetometer fit plotted with
accept/reject, and the parameter sheet (read-only for viewers, validated edits for the pilot).
Screenshots: test-artifacts/web-state-*.png."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
import yaml

from lotsen.messages import Topic
from lotsen.stack.parts import mag_calibrator

from .conftest import TOKEN, start_stack, stop_stack
from .test_browser import ARTIFACTS, browser, pytestmark, wait_js, wait_until  # noqa: F401  (browser: the fixture)
from .test_browser_touch import LAPTOP, PHONE, open_page, take_controls_by_touch

ROOT = Path(__file__).resolve().parents[2]
DETOUR_ROUTE = yaml.safe_load((ROOT / "examples/routes/square_with_obstacle.yaml").read_text())
VIEWPORTS = {"phone": (PHONE, True), "laptop": (LAPTOP, False)}


@pytest.fixture(scope="module")
def stack():
    rs = start_stack(parts=None)
    yield rs
    stop_stack(rs)


@pytest.fixture(scope="module", params=sorted(VIEWPORTS))
def pilot(request, browser, stack):
    """The pilot's page at this viewport (touch on the phone); its seat is freed when it closes."""
    vp, touch = VIEWPORTS[request.param]
    pg = open_page(browser, stack.url, vp, touch=touch)
    pg.kind = request.param
    if touch:
        take_controls_by_touch(pg)
    else:
        pg.fill("#token", TOKEN)
        pg.click("#btn-auth")
        wait_js(pg, "window.lotsen.pilot === true")
    yield pg
    pg.context.close()


def viewer(browser, stack, kind: str):
    vp, touch = VIEWPORTS[kind]
    pg = open_page(browser, stack.url, vp, touch=touch)
    pg.kind = kind
    return pg


def press(pg, sel: str) -> None:
    """A tap on the phone, a click on the laptop."""
    pg.locator(sel).scroll_into_view_if_needed()
    if pg.kind == "phone":
        pg.tap(sel)
    else:
        pg.click(sel)


def tab(pg, name: str) -> None:
    press(pg, f"[data-tab={name}]")
    wait_js(pg, f"!document.querySelector('#tab-{name}').hidden")


def shot(pg, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    pg.screenshot(path=str(ARTIFACTS / f"web-state-{name}-{pg.kind}.png"))


def load_route(pg, route: dict) -> None:
    pg.evaluate("(r) => { document.querySelector('#planstatus').textContent = ''; window.lotsen.route.fromDict(r); window.lotsen.route.changed(); window.lotsen.map.fit(); }",
                route)
    wait_js(pg, "document.querySelector('#planstatus').textContent.startsWith('planned')", timeout=15)


def upload(pg) -> str:
    tab(pg, "plan")
    pg.evaluate("() => { window.lotsen.readbackMatch = false; }")
    press(pg, "#btn-use")
    wait_js(pg, "window.lotsen.readbackMatch === true", timeout=15)
    return pg.evaluate("() => window.lotsen.boatRoute.route_id")


def grey(pg, sel: str) -> bool:
    return pg.evaluate(f"() => getComputedStyle(document.querySelector('{sel}')).color") == "rgb(122, 133, 145)"


# -- item 4: detours, speeds along the path, the path for late joiners, replan replaces it ----------
def test_detours_and_speeds_shown_and_the_active_path_kept_for_a_late_joiner(pilot, browser, stack):
    tab(pilot, "plan")
    load_route(pilot, DETOUR_ROUTE)
    status = pilot.inner_text("#planstatus")
    assert "detour: the leg from node 1 to node 2 goes round an obstacle or the area edge" in status
    assert pilot.evaluate("() => window.lotsen.map.draftDetours.length") == 1
    assert pilot.evaluate("() => window.lotsen.map.speedLabels") >= 2  # planned speeds drawn along the path
    rid = upload(pilot)
    wait_js(pilot, "window.lotsen.map.activeDetours.length === 1")
    shot(pilot, "detour")
    late = viewer(browser, stack, pilot.kind)  # connects after the upload
    try:
        wait_js(late, f"window.lotsen.boatRoute && window.lotsen.boatRoute.route_id === {rid!r}")
        wait_js(late, "window.lotsen.map.activePath && window.lotsen.map.activePath.n.length > 50")
        end = late.evaluate("() => { const p = window.lotsen.map.activePath; return [p.n[p.n.length - 1], p.e[p.e.length - 1]]; }")
        last = DETOUR_ROUTE["nodes"][-1]
        assert math.hypot(end[0] - last["north"], end[1] - last["east"]) < 0.5  # this route's path, not an old one
        wait_js(late, "window.lotsen.map.activeDetours.length === 1")  # detours known to the late joiner too
        # the labels are counted when the map next draws, which may come after the detours arrive
        wait_js(late, "window.lotsen.map.speedLabels >= 2")
        shot(late, "late-joiner")
        # a replan replaces the active path on every page
        shorter = {**DETOUR_ROUTE, "nodes": DETOUR_ROUTE["nodes"][:3]}
        load_route(pilot, shorter)
        rid2 = upload(pilot)
        assert rid2 != rid
        for pg in (pilot, late):
            wait_js(pg, f"window.lotsen.boatRoute.route_id === {rid2!r}")
            wait_js(pg, "(() => { const p = window.lotsen.map.activePath, n = p.n.length;"
                        f" return Math.hypot(p.n[n - 1] - {shorter['nodes'][-1]['north']}, p.e[n - 1] - "
                        f"{shorter['nodes'][-1]['east']}) < 0.5; }})()")
        assert late.errors == [] and pilot.errors == []
    finally:
        late.context.close()


# -- item 5: operator language, the offending cell marked, never silently kept ---------------------
def test_messages_in_operator_language_and_the_bad_field_marked(pilot, stack):
    tab(pilot, "plan")
    load_route(pilot, DETOUR_ROUTE)
    cell = "#nodetable tr[data-kind=node][data-i='1'] input[data-f=speed_mps]"
    assert pilot.inner_text("#nodetable tr[data-kind=node][data-i='1'] td:first-child") == "2"  # counted from 1
    pilot.locator(cell).scroll_into_view_if_needed()
    pilot.fill(cell, "2.3")
    pilot.press(cell, "Enter")
    wait_js(pilot, "document.querySelector('#fielderr').textContent !== ''")
    err = pilot.inner_text("#fielderr")
    assert err.startswith("node 2 speed 2.3 m/s exceeds the boat's 1.5 m/s") and "not applied" in err, err
    assert "invalid" in pilot.get_attribute(cell, "class")
    assert pilot.evaluate("() => window.lotsen.route.nodes[1].speed_mps") == 0.5  # the route keeps its value
    pilot.press(cell, "Escape")  # cancels the edit, never stops the boat
    assert pilot.input_value(cell) == "0.5" and pilot.inner_text("#fielderr") == ""
    assert pilot.evaluate("() => window.lotsen.telemetry.sup.mode") != "ESTOP"
    pilot.fill("#default-speed", "fast")
    pilot.press("#default-speed", "Enter")
    wait_js(pilot, "document.querySelector('#fielderr').textContent.includes('new node speed')")
    assert "invalid" in pilot.get_attribute("#default-speed", "class")
    pilot.press("#default-speed", "Escape")
    assert pilot.input_value("#default-speed") == "0.5"
    # the server's planner refuses: the message names node 1 and its speed cell is marked; the draft
    # path goes (the plan is not silently kept), and a forced upload says the old plan stays active
    held = pilot.evaluate("() => window.lotsen.boatRoute.route_id")
    assert pilot.evaluate("() => window.lotsen.send({type: 'params', name: 'planner.speed_max_mps', value: 0.4})")
    wait_js(pilot, "window.lotsen.settings.planner.speed_max_mps.value === 0.4")
    try:
        pilot.evaluate("() => { window.lotsen.route.nodes[0].north += 0.5; window.lotsen.route.changed(); }")
        wait_js(pilot, "document.querySelector('#planstatus').classList.contains('bad')", timeout=15)
        assert pilot.inner_text("#planstatus") == "node 1: speed 0.5 m/s exceeds the boat's 0.4 m/s"
        wait_js(pilot, "document.querySelector(\"#nodetable tr[data-kind=node][data-i='0'] input[data-f=speed_mps]\")"
                       ".classList.contains('invalid')")
        assert pilot.evaluate("() => window.lotsen.map.draftPath") is None
        assert pilot.is_disabled("#btn-use")
        pilot.evaluate("() => document.querySelector('#btn-use').onclick()")  # forced: the server refuses it too
        wait_js(pilot, "document.querySelector('#readback').textContent.includes('still active')")
        text = pilot.inner_text("#readback")
        assert "upload refused: node 1: speed 0.5 m/s exceeds the boat's 0.4 m/s" in text and held in text
        assert "nodes[" not in text and "speed_mps" not in text
        shot(pilot, "refused")
    finally:
        pilot.evaluate("() => window.lotsen.send({type: 'params', name: 'planner.speed_max_mps', value: 1.5})")
        wait_js(pilot, "window.lotsen.settings.planner.speed_max_mps.value === 1.5")
    assert pilot.errors == []


# -- item 4: stale values, heading range, alerts that clear ---------------------------------------
def test_connection_loss_greys_every_live_value_and_reconnect_restores(pilot):
    wait_js(pilot, "!document.body.classList.contains('stale')")
    assert not grey(pilot, "#hud-speed")
    # a half-open link: the socket stays open but nothing arrives
    pilot.evaluate("() => { window._onmsg = window.lotsen.ws.onmessage; window.lotsen.ws.onmessage = null; }")
    wait_js(pilot, "document.body.classList.contains('stale')", timeout=4)
    assert pilot.inner_text("#conn").startswith("no data for")
    for sel in ("#hud-speed", "#hud-heading", "#hud-gnss", "#hud-bat", "#hud-pose", "#mode"):
        assert grey(pilot, sel), sel
    assert pilot.evaluate("() => window.lotsen.map.stale") is True
    shot(pilot, "stale")
    pilot.evaluate("() => { window.lotsen.ws.onmessage = window._onmsg; }")
    wait_js(pilot, "!document.body.classList.contains('stale')", timeout=4)
    # the socket closes: offline at once, greyed, then back after the reconnection
    pilot.evaluate("() => window.lotsen.ws.close()")
    wait_js(pilot, "document.body.classList.contains('stale')", timeout=2)
    assert pilot.inner_text("#conn").startswith("offline")
    wait_js(pilot, "window.lotsen.connected && !document.body.classList.contains('stale')", timeout=8)
    assert not grey(pilot, "#hud-speed") and pilot.inner_text("#conn") == "connected"
    wait_js(pilot, "window.lotsen.pilot === true", timeout=5)  # the seat is taken again with the kept token
    # heading: whole degrees 0..359, never negative, never 360
    assert pilot.evaluate("() => [-1e-3, 2 * Math.PI - 4e-3, -Math.PI / 2, 3 * Math.PI].map(window.lotsen.heading360)") \
        == [0, 0, 270, 180]
    hdg = pilot.inner_text("#hud-heading")
    assert hdg.endswith("°") and 0 <= int(hdg[:-1]) <= 359


def test_alerts_clear_when_their_cause_clears_and_events_keep_the_history(pilot, stack):
    if pilot.evaluate("() => window.lotsen.telemetry.sup.mode") == "ESTOP":
        pilot.evaluate("() => window.lotsen.send({type: 'command', action: 'reset_estop'})")
        wait_js(pilot, "window.lotsen.telemetry.sup.mode !== 'ESTOP'")
    # a request the boat refuses (sent past the page's own check): an error alert
    pilot.evaluate("() => window.lotsen.send({type: 'command', action: 'reset_estop'})")
    wait_js(pilot, "window.lotsen.alerts.items.has('refused:reset_estop')")
    press(pilot, "#estop")
    wait_js(pilot, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
    wait_js(pilot, "window.lotsen.alerts.items.has('estop')")
    # reset_estop is possible now: its refusal is no longer true and goes
    wait_js(pilot, "!window.lotsen.alerts.items.has('refused:reset_estop')")
    shot(pilot, "alerts-estop")
    tab(pilot, "operate")
    press(pilot, "[data-action=reset_estop]")
    wait_js(pilot, "window.lotsen.telemetry.sup.mode !== 'ESTOP'")
    wait_js(pilot, "!window.lotsen.alerts.items.has('estop')")  # the core cleared it (active=false)
    events = pilot.inner_text("#log")
    assert "cleared: reset_estop refused" in events and "emergency stop" in events
    assert events.count("reset_estop refused: no emergency stop to reset") == 1  # listed once, not twice
    assert pilot.errors == []


# -- item 7: the magnetometer fit, accept / reject --------------------------------------------------
def _publish_fit(stack) -> object:
    """The supervisor's end of the calibration manoeuvre with a real fit of one turn's samples."""
    samples = [(12.0 + 30.0 * math.cos(t) + 4.0 * math.sin(t), -5.0 + 4.0 * math.cos(t) + 24.0 * math.sin(t))
               for t in (2 * math.pi * k / 300 for k in range(300))]
    result = mag_calibrator(samples)
    sup = stack.stack.nodes["supervisor"]
    stack.stack.executor.call_soon_threadsafe(lambda: sup.publish_calibration(result))
    return result


def test_magnetometer_fit_is_plotted_and_accepted_or_rejected(pilot, stack):
    tab(pilot, "operate")
    fusion = next(n for n in stack.stack.nodes.values() if hasattr(n, "_before_review"))
    before = fusion.calibration
    fit = _publish_fit(stack)
    wait_js(pilot, "window.lotsen.magcal && window.lotsen.magcal.decision === '' && !document.querySelector('#magcal').hidden")
    n = pilot.evaluate("() => document.querySelectorAll('#magcal-plot circle').length")
    assert n == len(fit.samples) >= 150
    assert pilot.evaluate("() => document.querySelector('#magcal-plot polyline.fit').points.numberOfItems") == 73
    stats = pilot.inner_text("#magcal-stats")
    assert re.search(r"coverage 3[56]\d° of 360°", stats) and "residual" in stats
    assert "µT" in pilot.inner_text("#magcal-text")
    wait_js(pilot, "window.lotsen.actionState('mag_reject').ok && window.lotsen.actionState('mag_accept').ok")
    pilot.locator("#magcal-plot").scroll_into_view_if_needed()
    shot(pilot, "magcal")
    assert fusion.calibration.center == pytest.approx(fit.center)  # in use at once
    press(pilot, "[data-action=mag_reject]")
    wait_js(pilot, "window.lotsen.magcal.decision === 'rejected'")
    assert "the calibration in use before it is back" in pilot.inner_text("#magcal-text")
    wait_until(lambda: fusion.calibration is before)
    wait_js(pilot, "!window.lotsen.actionState('mag_accept').ok")  # nothing left to review
    _publish_fit(stack)
    wait_js(pilot, "window.lotsen.magcal.decision === ''")
    wait_js(pilot, "window.lotsen.actionState('mag_accept').ok")
    press(pilot, "[data-action=mag_accept]")
    wait_js(pilot, "window.lotsen.magcal.decision === 'accepted'")
    assert any(m.action == "mag_accept" for m in stack.messages(Topic.OPERATOR))
    assert pilot.errors == []


# -- item 7: the parameter sheet --------------------------------------------------------------------
def test_parameter_sheet_read_only_for_viewers_and_validated_edits_for_the_pilot(pilot, browser, stack):
    watcher = viewer(browser, stack, pilot.kind)
    try:
        tab(watcher, "settings")
        wait_js(watcher, "document.querySelector('#set-model').textContent.includes('default coefficients')")
        assert "simulated boat" in watcher.inner_text("#set-model")
        assert watcher.evaluate("() => document.querySelectorAll('#set-model-table tbody tr').length") > 5
        assert "mpc" in watcher.inner_text("#set-controller") or "los" in watcher.inner_text("#set-controller")
        assert watcher.evaluate("() => document.querySelectorAll('#set-failsafes tr').length") > 5
        speed = "[data-param='planner.speed_max_mps']"
        assert watcher.get_attribute(speed, "readonly") is not None
        assert "Read-only" in watcher.inner_text("#set-planner-why")
        shot(watcher, "settings-viewer")
        tab(pilot, "settings")
        assert pilot.get_attribute(speed, "readonly") is None
        pilot.fill(speed, "2.3")
        pilot.press(speed, "Enter")
        wait_js(pilot, "document.querySelector('#set-err').textContent !== ''")
        assert pilot.inner_text("#set-err") == ("top speed of planned routes: 2.3 m/s exceeds 1.5 m/s, the launch "
                                                "config's value (a pilot may lower it, not raise it) (not applied)")
        assert "invalid" in pilot.get_attribute(speed, "class")
        pilot.fill(speed, "1.2")
        pilot.press(speed, "Enter")
        wait_js(pilot, "document.querySelector('#set-err').textContent === ''")
        wait_js(watcher, "window.lotsen.settings.planner.speed_max_mps.value === 1.2")  # every page sees it
        wait_js(watcher, f"document.querySelector(\"{speed}\").value === '1.2'")
        assert "planner.speed_max_mps 1.5 → 1.2" in watcher.inner_text("#set-planner-why")
        shot(pilot, "settings-pilot")
        pilot.fill(speed, "1.5")
        pilot.press(speed, "Enter")
        wait_js(watcher, "window.lotsen.settings.planner.speed_max_mps.value === 1.5")
        assert pilot.errors == [] and watcher.errors == []
    finally:
        watcher.context.close()
