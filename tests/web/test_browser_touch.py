"""The operator page on a phone (390x844 portrait and 844x390 landscape, touch only), a tablet
(820x1180) and a laptop (1280x800), in headless Chromium: no sideways scrolling, the e-stop on
screen and within the thumb's reach, every field tappable, hold-to-drive by touch that stops when
the finger lifts or the page loses focus, the viewer's e-stop disabled with its reason (or open to
viewers when the config says so). Screenshots go to test-artifacts/web-touch-*.png."""

from __future__ import annotations

import math
import time

import pytest

from lotsen.messages import Topic

from .conftest import TOKEN, start_stack, stop_stack
from .test_browser import ARTIFACTS, browser, pytestmark, wait_js, wait_until  # noqa: F401  (browser: the fixture)

PHONE = {"width": 390, "height": 844}
LANDSCAPE = {"width": 844, "height": 390}
TABLET = {"width": 820, "height": 1180}
LAPTOP = {"width": 1280, "height": 800}


LOG_DIR: list[str] = []


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    logs = tmp_path_factory.mktemp("logs")
    LOG_DIR[:] = [str(logs)]
    rs = start_stack(parts=None, log_dir=str(logs))
    yield rs
    stop_stack(rs)


def open_page(browser, url: str, viewport: dict, touch: bool = True):
    ctx = browser.new_context(viewport=viewport, has_touch=touch, is_mobile=touch,
                              device_scale_factor=2 if touch else 1)
    pg = ctx.new_page()
    pg.errors = []
    pg.on("pageerror", lambda e: pg.errors.append(str(e)))
    pg.goto(url)
    wait_js(pg, "window.lotsen && window.lotsen.framesRx > 3 && !!window.lotsen.telemetry.pose", timeout=20)
    return pg


@pytest.fixture(scope="module")
def phone(browser, stack):
    pg = open_page(browser, stack.url, PHONE)
    yield pg
    pg.context.close()


def shot(pg, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    pg.screenshot(path=str(ARTIFACTS / f"web-touch-{name}.png"))


def box(pg, sel: str) -> dict:
    return pg.locator(sel).bounding_box()


def no_sideways_scroll(pg) -> None:
    w = pg.evaluate("() => [document.documentElement.scrollWidth, document.body.scrollWidth, innerWidth]")
    assert w[0] <= w[2] and w[1] <= w[2], f"page wider than the screen: {w}"


def on_screen(pg, sel: str) -> dict:
    b = box(pg, sel)
    vp = pg.viewport_size
    assert b is not None, sel
    assert b["x"] >= 0 and b["y"] >= 0 and b["x"] + b["width"] <= vp["width"] + 0.5 \
        and b["y"] + b["height"] <= vp["height"] + 0.5, f"{sel} not fully on screen: {b} in {vp}"
    return b


def hit(pg, sel: str) -> bool:
    """A tap at the element's centre lands on it (nothing drawn over it)."""
    return pg.evaluate("""(sel) => {
        const el = document.querySelector(sel); el.scrollIntoView({block: 'center'});
        const r = el.getBoundingClientRect();
        const top = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
        return !!top && (top === el || el.contains(top) || top.control === el);
    }""", sel)


def tap(pg, sel: str) -> None:
    # a draft plan due or on its way rewrites the plan's status above the buttons when it lands: a tap
    # aimed before that can land on the button the text pushed there (on a busy machine, #btn-clear's
    # tap opened nothing and the next tap waited 30 s for the box)
    pg.wait_for_function("() => !window.lotsen || !window.lotsen.planPending", timeout=30000)
    pg.locator(sel).scroll_into_view_if_needed()
    pg.tap(sel)


def take_controls_by_touch(pg) -> None:
    if pg.evaluate("() => window.lotsen.pilot"):
        return
    tap(pg, "#token")
    pg.keyboard.insert_text(TOKEN)  # the phone's on-screen keyboard
    tap(pg, "#btn-auth")
    wait_js(pg, "window.lotsen.pilot === true")


def tab(pg, name: str) -> None:
    tap(pg, f"[data-tab={name}]")
    wait_js(pg, f"!document.querySelector('#tab-{name}').hidden")


def test_phone_portrait_viewer_sees_map_status_and_a_disabled_estop_with_its_reason(phone, stack):
    no_sideways_scroll(phone)
    est = on_screen(phone, "#estop")
    assert est["y"] > PHONE["height"] * 2 / 3 and est["height"] >= 48  # at the bottom edge: the thumb's zone
    assert est["width"] > PHONE["width"] * 0.8
    # the map first, then the status, then the panels
    assert box(phone, "#map")["y"] < box(phone, "#hud")["y"] < box(phone, "#tabs")["y"]
    assert box(phone, "#map")["height"] > 250
    assert phone.get_attribute("#estop", "aria-disabled") == "true"
    assert "only the pilot can stop the boat" in phone.inner_text("#estop")
    n = len(stack.messages(Topic.OPERATOR))
    phone.tap("#estop", force=True)  # aria-disabled, yet a finger still lands on it
    wait_js(phone, "document.querySelector('#toast').textContent.includes('only the pilot')")
    wait_js(phone, "document.activeElement === document.querySelector('#token')")  # where to go next
    assert len(stack.messages(Topic.OPERATOR)) == n
    shot(phone, "phone-viewer")
    assert phone.errors == []


def test_phone_every_field_and_button_can_be_tapped(phone):
    take_controls_by_touch(phone)
    wait_js(phone, "!document.querySelector('#estop').classList.contains('off')")
    assert phone.get_attribute("#estop", "aria-disabled") == "false"
    assert phone.inner_text("#estop-why") == ""
    phone.evaluate("() => { window.lotsen.map.fit(); }")
    covered = []
    for name in ("plan", "operate", "maps", "logs", "log"):
        tab(phone, name)
        sels = phone.evaluate(f"""() => Array.from(document.querySelectorAll(
            '#tab-{name} input, #tab-{name} select, #tab-{name} button, #tab-{name} .filebtn'))
            .filter(e => e.offsetParent !== null && !(e.type === 'file'))
            .map((e, i) => {{ e.dataset.probe = '{name}' + i; return `[data-probe="{name}${{i}}"]`; }})""")
        covered += [s for s in sels if not hit(phone, s)]
        no_sideways_scroll(phone)
        on_screen(phone, "#estop")
    for sel in ("#maptools [data-tool=node]", "#btn-fit", "#follow", "[data-tab=plan]"):
        if not hit(phone, sel):
            covered.append(sel)
    assert covered == []
    tab(phone, "plan")
    tap(phone, "#default-speed")  # a real tap focuses the field and the phone keyboard types into it
    assert phone.evaluate("() => document.activeElement.id") == "default-speed"
    phone.keyboard.press("Escape")
    shot(phone, "phone-plan")


def hold(cdp, x: float, y: float) -> None:
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [{"x": x, "y": y, "id": 1}]})


def lift(cdp, kind: str = "touchEnd") -> None:
    cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": []})


def centre(pg, sel: str) -> tuple[float, float]:
    pg.locator(sel).scroll_into_view_if_needed()
    b = box(pg, sel)
    return b["x"] + b["width"] / 2, b["y"] + b["height"] / 2


def test_phone_hold_to_drive_stops_when_the_finger_lifts_or_the_page_goes(phone, stack):
    take_controls_by_touch(phone)
    tab(phone, "operate")
    if not phone.evaluate("() => window.lotsen.telemetry.sup.armed"):
        wait_js(phone, "window.lotsen.actionState('arm').ok", timeout=10)
        tap(phone, "[data-action=arm]")
        wait_js(phone, "window.lotsen.telemetry.sup.armed === true")
    tap(phone, "[data-action=manual]")
    wait_js(phone, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    assert phone.locator("[aria-label=drive]").count() == 1
    wait_js(phone, "document.querySelector('#drivestate').textContent.startsWith('hold a button')")
    ahead = "#drivepad [aria-label=ahead]"
    assert hit(phone, ahead)  # scrolls it to the middle: measure after that, not before
    x, y = centre(phone, ahead)
    on_screen(phone, ahead)
    on_screen(phone, "#estop")
    no_sideways_scroll(phone)
    cdp = phone.context.new_cdp_session(phone)
    p0 = phone.evaluate("() => window.lotsen.telemetry.pose")
    hold(cdp, x, y)
    wait_js(phone, f"document.querySelector('{ahead}').classList.contains('on')")
    wait_js(phone, "window.lotsen.telemetry.cmd && Math.abs(window.lotsen.telemetry.cmd.n1) > 5")
    time.sleep(2.0)  # held: the 10 Hz stream keeps going
    shot(phone, "phone-drive")
    p1 = phone.evaluate("() => window.lotsen.telemetry.pose")
    assert math.hypot(p1["n"] - p0["n"], p1["e"] - p0["e"]) > 0.15 and p1["u"] > 0.05
    assert stack.messages(Topic.MANUAL)[-1].surge > 0
    lift(cdp)
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0, timeout=1.0)  # stop on lift
    wait_js(phone, f"!document.querySelector('{ahead}').classList.contains('on')")
    n = len(stack.messages(Topic.MANUAL))
    time.sleep(0.5)
    assert len(stack.messages(Topic.MANUAL)) == n  # and nothing more after the stop
    # a touch the browser cancels (a system gesture, a palm) stops too
    hold(cdp, x, y)
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge > 0, timeout=1.0)
    lift(cdp, "touchCancel")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0, timeout=1.0)
    # still touching, but the page loses the focus (a call, the app switcher) or is hidden
    for lose in ("window.dispatchEvent(new Event('blur'))",
                 "Object.defineProperty(document, 'hidden', {value: true, configurable: true});"
                 "document.dispatchEvent(new Event('visibilitychange'))"):
        hold(cdp, x, y)
        wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge > 0, timeout=1.0)
        phone.evaluate(f"() => {{ {lose}; }}")
        wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0, timeout=1.0)
        n = len(stack.messages(Topic.MANUAL))
        time.sleep(0.4)
        assert len(stack.messages(Topic.MANUAL)) == n, "driving went on after the focus was lost"
        lift(cdp)
        phone.evaluate("() => { delete document.hidden; }")
    # two fingers combine: ahead and turn right
    xd, yd = centre(phone, "#drivepad [aria-label='turn right']")
    cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": [
        {"x": x, "y": y, "id": 1}, {"x": xd, "y": yd, "id": 2}]})
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge > 0 and stack.messages(Topic.MANUAL)[-1].yaw > 0,
               timeout=1.0)
    lift(cdp)
    wait_until(lambda: (stack.messages(Topic.MANUAL)[-1].surge, stack.messages(Topic.MANUAL)[-1].yaw) == (0.0, 0.0),
               timeout=1.0)
    assert phone.errors == []


def tap_map(pg, north: float, east: float) -> None:
    pg.locator("#map").scroll_into_view_if_needed()
    x, y = pg.evaluate(f"() => window.lotsen.map.toScreen({north}, {east})")
    b = box(pg, "#map")
    pg.touchscreen.tap(b["x"] + x, b["y"] + y)


def test_phone_first_mission_by_touch_only(phone, stack):
    """Draw a route with taps on the map, upload, AUTO, and stop it, all by touch."""
    take_controls_by_touch(phone)
    tab(phone, "plan")
    tap(phone, "#btn-clear")
    phone.evaluate("() => { window.lotsen.viewTouched = true; const m = window.lotsen.map; m.follow = false;"
                   " m.scale = 12; m.n0 = 7; m.e0 = 3; m.invalidate(); }")
    tap(phone, "#maptools [data-tool=harbour]")
    tap_map(phone, 0.0, 0.0)
    tap(phone, "#maptools [data-tool=node]")
    tap_map(phone, 6.0, 0.0)
    tap_map(phone, 14.0, 5.0)
    wait_js(phone, "window.lotsen.route.complete() && window.lotsen.route.nodes.length === 2")
    tap(phone, "#maptools [data-tool=select]")
    wait_js(phone, "document.querySelector('#planstatus').textContent.startsWith('planned')", timeout=10)
    tap(phone, "#btn-use")
    wait_js(phone, "window.lotsen.readbackMatch === true", timeout=10)
    tab(phone, "operate")
    if not phone.evaluate("() => window.lotsen.telemetry.sup.armed"):
        wait_js(phone, "window.lotsen.actionState('arm').ok", timeout=10)
        tap(phone, "[data-action=arm]")
    wait_js(phone, "window.lotsen.actionState('auto').ok", timeout=10)
    tap(phone, "[data-action=auto]")
    wait_js(phone, "window.lotsen.telemetry.sup.mode === 'AUTO'")
    shot(phone, "phone-auto")
    phone.tap("#estop")
    wait_js(phone, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
    tap(phone, "[data-action=reset_estop]")
    wait_js(phone, "window.lotsen.telemetry.sup.mode !== 'ESTOP'")
    assert phone.errors == []


def test_a_gamepad_drives_only_while_its_dead_man_is_held(phone, stack):
    """A stand-in for navigator.getGamepads (headless Chromium has no pads): left stick ahead with
    and without a shoulder button held, then disconnected."""
    take_controls_by_touch(phone)
    wait_js(phone, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    phone.evaluate("""() => {
        window.fakePad = {id: 'test pad', connected: true, axes: [0, -0.8, 0, 0],
                          buttons: Array.from({length: 16}, () => ({pressed: false, value: 0}))};
        navigator.getGamepads = () => [window.fakePad];
        document.hasFocus = () => true;
    }""")
    n = len(stack.messages(Topic.MANUAL))
    time.sleep(0.4)
    assert all(m.surge == 0.0 for m in stack.messages(Topic.MANUAL)[n:])  # stick without dead-man: nothing
    phone.evaluate("() => { window.fakePad.buttons[5].pressed = true; }")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge > 0.3, timeout=1.0)
    wait_js(phone, "document.querySelector('#gamepad').textContent.includes('driving')")
    phone.evaluate("() => { window.fakePad.buttons[5].pressed = false; }")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0, timeout=1.0)
    phone.evaluate("() => { window.fakePad.buttons[5].pressed = true; }")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge > 0.3, timeout=1.0)
    phone.evaluate("() => { navigator.getGamepads = () => []; window.dispatchEvent(new Event('gamepaddisconnected')); }")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0, timeout=1.0)
    assert phone.errors == []


def test_recording_indicator_and_download_while_recording(phone, stack):
    """The HUD names the file being recorded with its size and duration, updated live; "download
    so far" gives an MCAP the mcap library reads, while the recording goes on."""
    import io

    from mcap.reader import make_reader

    from lotsen.logs.recorder import McapRecorder, RecorderConfig

    rec = McapRecorder(RecorderConfig(directory=LOG_DIR[0], flush_period_s=0.2, fsync=False)).attach(stack.stack.bus)
    try:
        path = rec.start()
        wait_js(phone, "!document.querySelector('#hud-rec-cell').hidden", timeout=6)
        text0 = phone.inner_text("#hud-rec")
        assert path.name in text0 and " MB" in text0
        time.sleep(2.5)
        wait_js(phone, f"document.querySelector('#hud-rec').textContent !== {text0!r}", timeout=4)
        assert hit(phone, "#hud-rec-dl")
        no_sideways_scroll(phone)
        shot(phone, "recording")
        with phone.expect_download() as info:
            phone.tap("#hud-rec-dl")
        data = open(info.value.path(), "rb").read()
        msgs = list(make_reader(io.BytesIO(data)).iter_messages())
        assert len(msgs) > 20 and info.value.suggested_filename == path.stem + ".partial.mcap"
        assert rec.recording  # still going
    finally:
        rec.close()
    wait_js(phone, "document.querySelector('#hud-rec-cell').hidden", timeout=10)  # closed: no longer shown


def test_phone_landscape_and_tablet(phone):
    for name, vp in (("landscape", LANDSCAPE), ("tablet", TABLET)):
        phone.set_viewport_size(vp)
        time.sleep(0.3)
        no_sideways_scroll(phone)
        est = on_screen(phone, "#estop")
        assert est["height"] >= 44
        if name == "landscape":  # bottom-right corner: the right thumb
            assert est["x"] + est["width"] > vp["width"] - 20 and est["y"] + est["height"] > vp["height"] - 20
        m = box(phone, "#map")
        assert m["width"] > 300 and m["height"] > 200
        tab(phone, "plan")
        for sel in ("#default-speed", "#btn-use", "[data-tab=operate]"):
            assert hit(phone, sel), f"{sel} covered at {name}"
        tab(phone, "operate")
        assert hit(phone, "#drivepad [aria-label=ahead]")
        on_screen(phone, "#estop")
        shot(phone, name)
    phone.set_viewport_size(PHONE)


def test_laptop_1280x800_keeps_its_layout(browser, stack):
    pg = open_page(browser, stack.url, LAPTOP, touch=False)
    try:
        no_sideways_scroll(pg)
        est = on_screen(pg, "#estop")
        assert est["y"] < 80  # in the top bar, as before
        assert box(pg, "#side")["x"] > box(pg, "#map")["x"] + 600  # map left, panels right
        assert pg.locator("#plots").is_visible()
        assert pg.get_attribute("#estop", "aria-disabled") == "true"  # a viewer here too
        assert "only the pilot" in pg.inner_text("#estop-why")
        pg.click("[data-tab=operate]")
        assert pg.locator("#drivepad").is_visible()
        for sel in ("#token", "#btn-auth", "#drivepad [aria-label=ahead]", "#gain"):
            assert hit(pg, sel), sel
        shot(pg, "laptop")
        assert pg.errors == []
    finally:
        pg.context.close()


def test_a_viewer_may_stop_the_boat_when_the_config_allows_it(browser):
    rs = start_stack(parts=None, extra_web={"viewer_may_estop": True})
    try:
        pg = open_page(browser, rs.url, PHONE)
        wait_js(pg, "window.lotsen.hello && window.lotsen.hello.viewer_may_estop === true")
        assert pg.get_attribute("#estop", "aria-disabled") == "false"
        assert pg.inner_text("#estop-why") == ""
        pg.tap("#estop")
        wait_until(lambda: any(m.action == "estop" for m in rs.messages(Topic.OPERATOR)), timeout=3.0)
        wait_js(pg, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
        shot(pg, "viewer-estop-allowed")
        pg.context.close()
    finally:
        stop_stack(rs)
