"""The phone as the primary device (issue 41), in headless Chromium with real touch at 390x844
(a phone) and 820x1180 (a tablet), against a stack with the supervisor and a configured area:

- a two-finger pinch on the map zooms the map, never the page, and the e-stop stays on screen;
- Manual is one tap from the first screen and shows the pad with mode, speed and heading beside it;
- e-stop, then reset: both on screen, each confirmed by the boat;
- the map's tools sit beside the map, not over it; a refused field says why beside itself
  (aria-invalid) with a Restore button; Esc on the gain slider does not stop the boat; the
  toggles show their state; Clear asks first; a leg far longer than the others is flagged and
  the upload asks; a pairing address makes the page the pilot with nothing typed.

One served stack and one page per screen for the whole module (the browser tests must stay cheap).
Screenshots: test-artifacts/web-phone-*.png."""

from __future__ import annotations

import pytest

from lotsen.messages import Topic
from lotsen.stack.stack import example_route

from .conftest import TOKEN, start_stack, stop_stack
from .test_browser import ARTIFACTS, browser, pytestmark, wait_js  # noqa: F401  (browser: the fixture)
from .test_browser_touch import hit, on_screen, open_page, tab, tap

SCREENS = {"phone": {"width": 390, "height": 844}, "tablet": {"width": 820, "height": 1180}}


@pytest.fixture(scope="module")
def stack():
    rs = start_stack(parts=None, route=example_route("figure_eight"),
                     extra={"failsafes": {"prearm_skip": ["pilot_link"]}})
    yield rs
    stop_stack(rs)


@pytest.fixture(scope="module", params=list(SCREENS))
def page(request, browser, stack):
    # paired by the address of the boat's QR code: the pilot with nothing typed
    pg = open_page(browser, f"{stack.url}#pair={TOKEN}", SCREENS[request.param])
    pg.screen = request.param
    wait_js(pg, "window.lotsen.pilot === true", timeout=10)
    yield pg
    pg.context.close()


def shot(pg, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    pg.screenshot(path=str(ARTIFACTS / f"web-phone-{name}-{pg.screen}.png"))


def touch(pg, kind: str, points: list[tuple[float, float]]) -> None:
    cdp = pg.context.new_cdp_session(pg) if not hasattr(pg, "cdp") else pg.cdp
    pg.cdp = cdp
    cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [
        {"x": x, "y": y, "id": i, "radiusX": 5, "radiusY": 5, "force": 1} for i, (x, y) in enumerate(points)]})


def pinch(pg, cx: float, cy: float, d0: float, d1: float, steps: int = 8) -> None:
    """Two fingers at (cx -+ d/2, cy), moved from d0 apart to d1 apart, then lifted."""
    touch(pg, "touchStart", [(cx - d0 / 2, cy), (cx + d0 / 2, cy)])
    for k in range(1, steps + 1):
        d = d0 + (d1 - d0) * k / steps
        touch(pg, "touchMove", [(cx - d / 2, cy), (cx + d / 2, cy)])
    touch(pg, "touchEnd", [])


def page_scale(pg) -> float:
    return pg.evaluate("() => window.visualViewport ? window.visualViewport.scale : 1")


def test_paired_by_its_address_the_page_is_the_pilot_and_keeps_the_credential(page):
    assert "#pair" not in page.url  # taken off the address bar at once
    assert page.evaluate("() => localStorage.getItem('lotsen.pilot-credential')") == TOKEN
    assert page.locator("#btn-forget").is_visible() and page.locator("#token").is_hidden()


def _settled_map_box(pg) -> dict:
    """The map's box once the first screen is done: the boat fitted into view (the first fit) and
    the layout still for 0.3 s with the map itself under the box's centre (a loaded machine finished
    the page's layout after the box was read, so the fingers could land beside the map)."""
    wait_js(pg, "window.lotsen.fits >= 1", timeout=15)
    box = None
    for _ in range(50):
        m = pg.locator("#map").bounding_box()
        cx, cy = m["x"] + m["width"] / 2, m["y"] + m["height"] / 2
        on_top = pg.evaluate(f"() => document.elementFromPoint({cx}, {cy})?.id")
        if m == box and on_top == "map":
            return m
        box = m
        pg.wait_for_timeout(300)
    raise AssertionError(f"the map's box never settled with the map on top: {box}, {on_top!r} at its centre")


def test_a_pinch_on_the_map_zooms_the_map_not_the_page_and_the_estop_stays(page):
    m = _settled_map_box(page)
    cx, cy = m["x"] + m["width"] / 2, m["y"] + m["height"] / 2
    # the view is the operator's from here on, as after any touch (no first-screen fit comes after it)
    before = page.evaluate("() => { window.lotsen.viewTouched = true; return window.lotsen.map.scale; }")
    pinch(page, cx, cy, 60, min(300, m["width"] - 20))
    try:
        wait_js(page, f"window.lotsen.map.scale > {before} * 2")
    except AssertionError:  # say what the map saw: its scale and the fingers it still holds
        seen = page.evaluate("() => [window.lotsen.map.scale, window.lotsen.map.pointers.size]")
        raise AssertionError(f"the pinch did not zoom the map: scale {before} -> {seen[0]}, {seen[1]} "
                             f"finger(s) held, map box {m}") from None
    assert page_scale(page) == 1.0
    on_screen(page, "#estop")
    # and apart again: the map zooms out, the page still not
    pinch(page, cx, cy, min(300, m["width"] - 20), 60)
    wait_js(page, f"window.lotsen.map.scale < {before} * 1.2")
    # a pinch on the status and the panels below the map does not zoom the page either
    h = page.locator("#hud").bounding_box()
    pinch(page, h["x"] + h["width"] / 2, h["y"] + h["height"] / 2, 40, 250)
    page.wait_for_timeout(300)
    assert page_scale(page) == 1.0
    on_screen(page, "#estop")
    # the map's tools are beside the map, not over it: a tap on the map never switches a tool
    t, m = page.locator("#maptools").bounding_box(), page.locator("#map").bounding_box()
    assert t["y"] >= m["y"] + m["height"] - 0.5 or t["y"] + t["height"] <= m["y"] + 0.5, (t, m)
    shot(page, "pinch")


def test_manual_is_one_tap_from_the_first_screen_with_the_pad_speed_and_heading(page, stack):
    # the boat holding position (armed), as it is when the operator wants to drive
    wait_js(page, "window.lotsen.telemetry.sup.available.includes('arm')", timeout=15)
    page.evaluate("() => window.lotsen.send({type: 'command', action: 'arm'})")
    wait_js(page, "window.lotsen.telemetry.sup.available.includes('hold')", timeout=10)
    page.evaluate("() => window.lotsen.send({type: 'command', action: 'hold'})")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'HOLD'")
    page.evaluate("() => { document.querySelector('#side').scrollTop = 0; }")
    tab(page, "plan")  # the first screen: map, status, the Plan tab
    on_screen(page, "#btn-drive")
    tap(page, "#btn-drive")  # the one tap
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    wait_js(page, "document.querySelector('#cmdstate').textContent.includes('the boat confirmed manual')")
    for sel in ("#drivepad [data-drive=KeyW]", "#drivepad [data-drive=KeyS]", "#dh-speed", "#dh-heading", "#dh-mode"):
        on_screen(page, sel)
        assert hit(page, sel), sel
    assert page.inner_text("#dh-mode") == "MANUAL"
    # the mode's confirmation is never covered: the request line is a line of its own, and a toast
    # sits under the top bar, clear of the mode and armed badges
    page.evaluate("() => { const t = document.querySelector('#toast'); t.textContent = 'a toast'; t.className = 'show'; }")
    t = page.locator("#toast").bounding_box()
    for badge in ("#mode", "#armed"):
        b = page.locator(badge).bounding_box()
        apart = (t["y"] >= b["y"] + b["height"] - 0.5 or t["y"] + t["height"] <= b["y"] + 0.5
                 or t["x"] >= b["x"] + b["width"] - 0.5 or t["x"] + t["width"] <= b["x"] + 0.5)
        assert apart, (badge, t, b)
    page.evaluate("() => { document.querySelector('#toast').className = ''; }")
    assert page.inner_text("#dh-speed").endswith("m/s") and page.inner_text("#dh-heading").endswith("°")
    on_screen(page, "#estop")
    shot(page, "drive")


def test_estop_then_reset_both_on_screen_and_confirmed(page, stack):
    tap(page, "#estop")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
    wait_js(page, "document.querySelector('#cmdstate').textContent.includes('the boat confirmed estop')")
    on_screen(page, "#estop")
    on_screen(page, "#estop-reset")
    assert hit(page, "#estop-reset")
    assert "press Manual" not in page.inner_text("#drivestate")
    shot(page, "estop")
    page.tap("#estop-reset")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    wait_js(page, "document.querySelector('#estop-reset').hidden")
    assert [m.action for m in stack.messages(Topic.OPERATOR)][-2:] == ["estop", "reset_estop"]


def test_esc_on_the_gain_slider_restores_it_and_does_not_stop_the_boat(page, stack):
    if page.screen != "phone":
        pytest.skip("once is enough")
    tab(page, "operate")
    n = len(stack.messages(Topic.OPERATOR))
    page.focus("#gain")
    page.keyboard.press("ArrowRight")
    page.keyboard.press("Escape")
    page.wait_for_timeout(300)
    assert page.input_value("#gain") == "0.6"
    assert [m.action for m in stack.messages(Topic.OPERATOR)[n:]] == []
    assert page.evaluate("() => window.lotsen.telemetry.sup.mode") == "MANUAL"


def test_toggles_show_their_state_and_switch_it(page):
    if page.screen != "phone":
        pytest.skip("once is enough")
    tab(page, "operate")
    wait_js(page, "document.querySelector('#tog-rtk').textContent.startsWith('RTK: ON')", timeout=15)
    assert page.get_attribute("#tog-rtk", "aria-pressed") == "true"
    assert page.get_attribute("#tog-rtk", "data-action") == "rtk_stop"
    assert "not connected" not in (page.get_attribute("#tog-rtk", "title") or "")
    tap(page, "#tog-rtk")
    wait_js(page, "document.querySelector('#tog-rtk').textContent.startsWith('RTK: off')", timeout=10)
    assert page.get_attribute("#tog-rtk", "aria-pressed") == "false"
    assert page.inner_text("#tog-log").startswith("Logging: ")


def test_a_refused_field_says_why_beside_itself_and_restores_by_a_tap(page):
    tab(page, "plan")
    wait_js(page, "document.querySelectorAll('#nodetable input[data-f=speed_mps]').length > 0")
    cell = "#nodetable tr[data-i='1'] input[data-f=speed_mps]"
    tap(page, cell)
    page.fill(cell, "fast")
    page.dispatch_event(cell, "change")
    wait_js(page, f"document.querySelector(\"{cell}\").getAttribute('aria-invalid') === 'true'")
    err_id = page.get_attribute(cell, "aria-describedby")
    assert err_id and "not applied" in page.inner_text(f"#{err_id}")
    c, e = page.locator(cell).bounding_box(), page.locator(f"#{err_id}").bounding_box()
    assert 0 <= e["y"] - (c["y"] + c["height"]) < 40  # right under the field, not under the whole table
    on_screen(page, f"#{err_id}")
    tap(page, f"#{err_id} button.restore")
    assert page.input_value(cell) == "0.5" and page.get_attribute(cell, "aria-invalid") is None


def test_clear_asks_first_a_long_leg_is_flagged_and_the_boat_refuses_leaving_its_area(page, stack):
    """The issue's lake: the area cleared, north 500 typed for 50: the page flags the leg and asks
    before the upload; uploaded anyway, the boat refuses it (its configured area) and keeps its route."""
    if page.screen != "phone":
        pytest.skip("once is enough")
    tab(page, "plan")
    nodes = page.evaluate("() => window.lotsen.route.nodes.length")
    tap(page, "#btn-clear")
    assert page.locator("#clearbox").is_visible()
    assert page.evaluate("() => window.lotsen.route.nodes.length") == nodes  # nothing cleared yet
    tap(page, "#btn-clear-cancel")
    assert page.evaluate("() => window.lotsen.route.nodes.length") == nodes and page.locator("#clearbox").is_hidden()
    tap(page, "#btn-clear")
    tap(page, "#btn-clear-nodes")
    assert page.evaluate("() => [window.lotsen.route.nodes.length, !!window.lotsen.route.area]") == [0, True]
    page.evaluate("() => window.lotsen.route.undo()")
    tap(page, "#btn-clear")
    tap(page, "#btn-clear-all")
    assert page.evaluate("() => [window.lotsen.route.nodes.length, !!window.lotsen.route.area]") == [0, False]
    page.evaluate("() => window.lotsen.route.undo()")
    # the area gone, the typo in: planned (no area to keep it in), flagged, the upload asks
    page.evaluate("""() => window.lotsen.route.fromDict({harbour: {north: 4, east: 20, heading_deg: 0}, nodes: [
        {north: 14, east: 20, heading_deg: 0, speed_mps: 0.5}, {north: 24, east: 20, heading_deg: 0, speed_mps: 0.5},
        {north: 500, east: 20, heading_deg: 0, speed_mps: 0.5}, {north: 510, east: 20, heading_deg: 0, speed_mps: 0.5}]})""")
    try:
        wait_js(page, "document.querySelector('#planstatus').textContent.includes('a typo?')", timeout=15)
    except AssertionError:
        raise AssertionError(page.inner_text("#planstatus") + str(page.evaluate("() => window.lotsen.longLegs()")))
    held = page.evaluate("() => window.lotsen.telemetry.sup.route_id")
    n = len(stack.messages(Topic.ROUTE))
    tap(page, "#btn-use")
    assert page.locator("#uploadbox").is_visible() and "x the other legs" in page.inner_text("#uploadbox-text")
    tap(page, "#btn-upload-cancel")
    assert len(stack.messages(Topic.ROUTE)) == n  # nothing was sent
    tap(page, "#btn-use")
    tap(page, "#btn-upload-anyway")
    wait_js(page, "document.querySelector('#readback').textContent.includes('the boat refused the upload')", timeout=20)
    assert "leaves the navigable area of the boat" in page.inner_text("#readback")
    assert page.evaluate("() => window.lotsen.telemetry.sup.route_id") == held
    shot(page, "fence")
    page.evaluate("() => window.lotsen.route.undo()")


def test_nothing_that_starts_motion_is_offered_on_stale_state(page):
    """A half-open link (the socket open, nothing arriving): the e-stop, disarm and hold stay
    offered, arm, AUTO, return, Manual and the pad are not, with the reason."""
    if page.screen != "phone":
        pytest.skip("once is enough")
    tab(page, "operate")
    wait_js(page, "!document.body.classList.contains('stale')")
    page.evaluate("() => { window._onmsg = window.lotsen.ws.onmessage; window.lotsen.ws.onmessage = null; }")
    try:
        wait_js(page, "document.body.classList.contains('stale')", timeout=5)
        states = page.evaluate("""() => Object.fromEntries(['auto', 'return', 'arm', 'manual', 'estop', 'disarm', 'hold']
            .map(a => [a, window.lotsen.actionState(a)]))""")
        for a in ("auto", "return", "arm", "manual"):
            assert not states[a]["ok"] and "no live data from the boat" in states[a]["why"], (a, states[a])
        assert states["estop"]["ok"]
        assert page.is_disabled("[data-action=auto]") and page.is_disabled("[data-action=manual]")
        assert page.is_enabled("#estop")
        assert "not driving on old state" in page.inner_text("#drivestate")
    finally:
        page.evaluate("() => { window.lotsen.ws.onmessage = window._onmsg; }")
    wait_js(page, "!document.body.classList.contains('stale')", timeout=5)
