"""End to end in headless Chromium (Playwright, sync API) against a running realtime stack:
the page works offline, routes are drawn by clicking on the map, planned and used; a simulated
mission moves the boat; keyboard driving moves it; the emergency stop neutralises the thrusters.
Screenshots go to test-artifacts/ (gitignored); LOTSEN_UPDATE_SCREENSHOT=1 also refreshes
docs/images/operator-ui.png."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import pytest

from lotsen.messages import Topic

from .conftest import TOKEN, start_stack, stop_stack
from .test_maps_and_logs import TileServer, small_mcap

CHROMIUM = "/usr/bin/chromium"
ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = ROOT / "test-artifacts"

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(not os.path.exists(CHROMIUM), reason=f"needs Debian's Chromium at {CHROMIUM} "
                       "(apt-get install chromium; `playwright install` cannot download browsers here)"),
]

LAUNCH_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
               "--no-first-run", "--disable-sync"]




@pytest.fixture(scope="module")
def tile_server():
    ts = TileServer(refuse_from_zoom=23)  # a stand-in for the online tile server
    yield ts
    ts.close()


@pytest.fixture(scope="module")
def stack(tile_server, tmp_path_factory):
    logs = tmp_path_factory.mktemp("logs")
    small_mcap(logs / "2026-11-23_lake.mcap")
    rs = start_stack(parts=None, log_dir=str(logs),
                     extra_web={"tile_dir": str(tmp_path_factory.mktemp("tiles")), "tile_url": tile_server.url,
                                "battery_capacity_ah": 5.0})
    yield rs
    stop_stack(rs)


@pytest.fixture(scope="module")
def browser():
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=LAUNCH_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def page(browser, stack):
    ctx = browser.new_context(viewport={"width": 1440, "height": 900})
    pg = ctx.new_page()
    pg.requests = []  # every URL the page asks for
    pg.errors = []
    pg.on("request", lambda r: pg.requests.append(r.url))
    pg.on("pageerror", lambda e: pg.errors.append(str(e)))
    pg.goto(stack.url)
    # the simulated boat's first pose can take a second or two on a busy machine
    wait_js(pg, "window.lotsen && window.lotsen.framesRx > 3 && !!window.lotsen.telemetry.pose", timeout=20)
    yield pg
    ctx.close()


def wait_js(pg, expr: str, timeout: float = 8.0):
    """Poll a JS expression (page.wait_for_function needs eval, which our CSP forbids)."""
    t_end = time.monotonic() + timeout
    while True:
        value = pg.evaluate(f"() => ({expr})")
        if value:
            return value
        assert time.monotonic() < t_end, f"timed out waiting for: {expr}; the page said: {page_said(pg)}"
        time.sleep(0.05)


# what a failed wait reports: the page's status lines and its last toast (a planner's refusal, a busy worker)
_SAID = ("#conn", "#planstatus", "#surveyinfo", "#predictinfo", "#coverageinfo", "#readback", "#toast")


def page_said(pg) -> dict:
    return pg.evaluate("(ids) => Object.fromEntries(ids.map(i => [i, document.querySelector(i) ? "
                       "document.querySelector(i).textContent.slice(0, 300) : null]))", list(_SAID))


def wait_until(pred, timeout: float = 3.0) -> None:
    t_end = time.monotonic() + timeout
    while not pred():
        assert time.monotonic() < t_end, "condition not met in time"
        time.sleep(0.02)


def shot(pg, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    pg.screenshot(path=str(ARTIFACTS / f"web-{name}.png"))


def set_view(pg, scale: float, north: float, east: float) -> None:
    """Zoom and pan as the operator would: a moved view is the operator's, so the first-screen fit
    (which fires on telemetry until the view is touched) must not move it between two clicks."""
    pg.evaluate(f"() => {{ const m = window.lotsen.map; m.scale = {scale}; m.n0 = {north}; m.e0 = {east};"
                " m.invalidate(); window.lotsen.viewTouched = true; }")


def click_map(pg, north: float, east: float) -> None:
    x, y = pg.evaluate(f"() => window.lotsen.map.toScreen({north}, {east})")
    box = pg.locator("#map").bounding_box()
    pg.mouse.click(box["x"] + x, box["y"] + y)


def boat(pg) -> dict:
    return pg.evaluate("() => window.lotsen.telemetry.pose")


def test_page_works_offline_and_shows_the_live_boat(page, stack):
    pose = boat(page)
    assert pose is not None and math.isfinite(pose["n"]) and math.isfinite(pose["psi"])
    assert page.inner_text("#conn") == "connected"
    assert page.locator("#estop").is_visible()
    origin = f"http://127.0.0.1:{stack.port}/"
    offsite = [u for u in page.requests if not (u.startswith(origin) or u.startswith("data:")
                                                or u.startswith(f"ws://127.0.0.1:{stack.port}/"))]
    assert offsite == []  # nothing from a CDN, no tiles, no fonts
    assert page.errors == []


def test_viewer_cannot_control(page, stack):
    assert page.locator("[data-action=auto]").is_disabled()
    assert page.locator("#btn-use").is_disabled()
    n = len(stack.messages(Topic.OPERATOR))
    # always visible; without the token it is marked disabled with the reason, and a click explains
    assert page.get_attribute("#estop", "aria-disabled") == "true"
    assert "only the pilot can stop the boat" in page.inner_text("#estop-why")
    page.click("#estop", force=True)
    wait_js(page, "document.querySelector('#toast').textContent.includes('take controls')")
    assert len(stack.messages(Topic.OPERATOR)) == n
    # drafts are planned by the boat's planner worker, which only the pilot may load
    assert "pilot" in page.get_attribute("#btn-use", "title")


def test_alerts_are_ordered_by_severity_dismissable_and_can_sound(page):
    """Alerts stack most severe first; the sound option (off by default: autoplay rules) beeps
    once per new or changed alert above info, through one AudioContext made on the click."""
    assert page.get_attribute("#btn-sound", "aria-pressed") == "false"
    push = "(a) => window.lotsen.alerts.push(a)"
    page.evaluate(push, {"severity": "warning", "code": "test:w", "text": "test warning"})
    assert page.evaluate("() => window.lotsen.alerts.beeps || 0") == 0  # silent while off
    page.click("#btn-sound")
    assert page.get_attribute("#btn-sound", "aria-pressed") == "true"
    assert page.inner_text("#btn-sound") == "sound on"
    wait_js(page, "!!window.lotsen.alerts.audio && window.lotsen.alerts.audio.state === 'running'")
    for sev in ("info", "critical", "error"):
        page.evaluate(push, {"severity": sev, "code": f"test:{sev[0]}", "text": f"test {sev}"})
    codes = page.evaluate("() => [...document.querySelectorAll('#alerts .alert')].map(e => e.dataset.code)"
                          ".filter(c => c.startsWith('test:'))")
    assert codes == ["test:c", "test:e", "test:w", "test:i"]
    assert page.evaluate("() => window.lotsen.alerts.beeps") == 2  # critical and error; info never beeps
    page.evaluate(push, {"severity": "error", "code": "test:e", "text": "test error"})  # a repeat: counted, silent
    assert "×2" in page.inner_text("#alerts .alert[data-code='test:e']")
    assert page.evaluate("() => window.lotsen.alerts.beeps") == 2
    page.click("#btn-sound")
    assert page.get_attribute("#btn-sound", "aria-pressed") == "false"
    page.evaluate(push, {"severity": "critical", "code": "test:c2", "text": "another"})
    assert page.evaluate("() => window.lotsen.alerts.beeps") == 2
    for code in ("test:i", "test:c", "test:e", "test:w", "test:c2"):
        page.click(f"#alerts .alert[data-code='{code}'] button.dismiss")
    wait_js(page, "![...document.querySelectorAll('#alerts .alert')].some(e => e.dataset.code.startsWith('test:'))")
    assert page.errors == []



def test_battery_with_current_and_time_left(page):
    """The HUD's time left = remaining fraction x capacity (configured: 5 Ah) / mean current."""
    wait_js(page, "window.lotsen.telemetry.bat && window.lotsen.telemetry.bat.left_s != null", timeout=10)
    b = page.evaluate("() => window.lotsen.telemetry.bat")
    assert b["a"] > 0 and 0 < b["frac"] <= 1 and b["left_basis"] == "capacity"
    assert b["left_s"] == pytest.approx(b["frac"] * 5.0 * 3600 / b["a_avg"], rel=0.02)
    text = page.inner_text("#hud-bat")
    assert " A" in text and "%" in text and "left" in text and " h " in text  # hours at the idle current
    assert "configured capacity" in page.get_attribute("#hud-bat", "title")



def take_controls(pg) -> None:
    if not pg.evaluate("() => window.lotsen.pilot"):
        pg.fill("#token", TOKEN)
        pg.click("#btn-auth")
        wait_js(pg, "window.lotsen.pilot === true")


def arm(pg) -> None:
    """Arm (thrust allowed) once the simulated ESCs are ready: the button is enabled only then."""
    pg.click("[data-tab=operate]")
    if not pg.evaluate("() => window.lotsen.telemetry.sup.armed"):
        wait_js(pg, "window.lotsen.actionState('arm').ok", timeout=10)
        pg.click("[data-action=arm]")
        wait_js(pg, "window.lotsen.telemetry.sup.armed === true")



def test_draw_a_route_by_clicking_and_see_the_plan_and_its_errors(page):
    take_controls(page)
    page.evaluate("() => window.lotsen.map.fit()")
    set_view(page, 14, 8, 4)
    page.click("[data-tool=harbour]")
    click_map(page, 0, 0)
    page.click("[data-tool=node]")
    click_map(page, 6, 0)
    click_map(page, 14, 5)
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    route = page.evaluate("() => window.lotsen.route.toDict()")
    assert len(route["nodes"]) == 2 and abs(route["nodes"][0]["north"] - 6) < 0.2
    assert page.evaluate("() => window.lotsen.map.draftPath.n.length") > 20
    # a node right behind the last one cannot be reached: the error is shown next to it
    click_map(page, 13, 6)
    wait_js(page, "document.querySelector('#planstatus').classList.contains('bad')")
    err_rows = page.locator("#nodetable tr.err td.errmsg")
    assert "node 3" in err_rows.first.inner_text() and "nodes[" not in err_rows.first.inner_text()  # 1-based
    shot(page, "plan-error")
    page.locator("#nodetable button[data-del='2']").click()
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    # set a node's speed in the table: re-planned at once
    page.fill("#nodetable tr[data-kind=node][data-i='1'] input[data-f=speed_mps]", "0.4")
    page.press("#nodetable tr[data-kind=node][data-i='1'] input[data-f=speed_mps]", "Enter")
    wait_js(page, "window.lotsen.route.nodes[1].speed_mps === 0.4")


def test_drag_a_node_and_the_path_follows(page):
    page.click("[data-tool=select]")
    before = page.evaluate("() => window.lotsen.map.draftPath.e.slice(-1)[0]")
    x, y = page.evaluate("() => window.lotsen.map.toScreen(14, 5)")
    box = page.locator("#map").bounding_box()
    page.mouse.move(box["x"] + x, box["y"] + y)
    page.mouse.down()
    page.mouse.move(box["x"] + x + 20, box["y"] + y, steps=4)
    page.mouse.move(box["x"] + x + 42, box["y"] + y, steps=4)  # 3 m east at 14 px/m
    page.mouse.up()
    wait_js(page, f"Math.abs(window.lotsen.map.draftPath.e.slice(-1)[0] - {before}) > 2")
    assert abs(page.evaluate("() => window.lotsen.route.nodes[1].east") - 8.0) < 0.3


def test_insert_a_node_undo_redo_and_numbers_are_validated_on_entry(page):
    before = page.evaluate("() => window.lotsen.route.toDict()")
    page.locator("#nodetable button[data-ins='1']").click()  # + : a node halfway before node 1
    wait_js(page, "window.lotsen.route.nodes.length === 3")
    mid = page.evaluate("() => window.lotsen.route.nodes[1]")
    n0, n2 = before["nodes"][0], before["nodes"][1]
    assert abs(mid["north"] - (n0["north"] + n2["north"]) / 2) < 0.01
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    page.click("#btn-undo")
    wait_js(page, "window.lotsen.route.nodes.length === 2")
    page.click("#btn-redo")
    wait_js(page, "window.lotsen.route.nodes.length === 3")
    page.locator("#map").focus()
    page.keyboard.press("Control+z")
    wait_js(page, "window.lotsen.route.nodes.length === 2")
    assert page.evaluate("() => window.lotsen.route.toDict()") == before
    # a cleared or nonsensical cell is refused with the reason, never read as 0
    cell = "#nodetable tr[data-kind=node][data-i='1'] input[data-f=speed_mps]"
    for text, why in (("", "a number is required"), ("fast", "is not a number"), ("1e308", "exceeds the boat")):
        page.fill(cell, text)
        page.press(cell, "Enter")
        wait_js(page, f"document.querySelector('#fielderr').textContent.includes('{why}')")
    assert page.evaluate("() => window.lotsen.route.nodes[1].speed_mps") == 0.4
    page.fill(cell, "0.4")
    page.press(cell, "Enter")
    wait_js(page, "document.querySelector('#fielderr').textContent === ''")
    # the navigable area: corners clicked with the Area tool, closed with Finish polygon
    page.click("[data-tool=area]")
    for n, e in ((-4, -4), (18, -4), (18, 12), (-4, 12)):
        click_map(page, n, e)
    page.click("#btn-finish")
    wait_js(page, "window.lotsen.route.area && window.lotsen.route.area.length === 4")
    corner = page.evaluate("() => window.lotsen.route.area[2]")
    assert abs(corner[0] - 18) < 0.2 and abs(corner[1] - 12) < 0.2
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    assert "navigable area, 4 corners" in page.inner_text("#polylist")
    page.click("[data-tool=select]")


def drag_map(pg, n0: float, e0: float, n1: float, e1: float) -> None:
    box = pg.locator("#map").bounding_box()
    x0, y0 = pg.evaluate(f"() => window.lotsen.map.toScreen({n0}, {e0})")
    x1, y1 = pg.evaluate(f"() => window.lotsen.map.toScreen({n1}, {e1})")
    pg.mouse.move(box["x"] + x0, box["y"] + y0)
    pg.mouse.down()
    pg.mouse.move(box["x"] + (x0 + x1) / 2, box["y"] + (y0 + y1) / 2, steps=4)
    pg.mouse.move(box["x"] + x1, box["y"] + y1, steps=4)
    pg.mouse.up()


def test_edit_area_corners_and_draw_an_obstacle(page):
    """Corners as in QGroundControl: drag one (one undo step), + on an edge inserts, Delete or a
    right-click removes (never below 3); an obstacle drawn on the map is planned around."""
    take_controls(page)
    page.click("[data-tab=plan]")
    page.click("[data-tool=select]")
    set_view(page, 14, 7, 4)
    area = lambda: page.evaluate("() => window.lotsen.route.area")  # noqa: E731
    assert area() == [[-4, -4], [18, -4], [18, 12], [-4, 12]]
    drag_map(page, 18, 12, 20, 14)
    wait_js(page, "window.lotsen.route.area[2][0] > 19")
    assert area()[2] == pytest.approx([20, 14], abs=0.15)
    assert page.evaluate("() => window.lotsen.route.selected") == {"kind": "vertex", "poly": "area", "k": 2}
    page.click("#btn-undo")
    wait_js(page, "window.lotsen.route.area[2][0] === 18")
    page.click("#btn-redo")
    wait_js(page, "window.lotsen.route.area[2][0] > 19")
    assert page.evaluate("() => window.lotsen.route.selected") is None  # undo/redo clear the selection
    click_map(page, *area()[2])  # select the corner again: its polygon shows + handles halfway
    wait_js(page, "window.lotsen.route.selected && window.lotsen.route.selected.kind === 'vertex'")
    # along its edges, and one inserts a corner
    click_map(page, 7, -4)
    wait_js(page, "window.lotsen.route.area.length === 5")
    assert area()[1] == [7, -4]
    assert "navigable area, 5 corners" in page.inner_text("#polylist")
    page.locator("#map").focus()
    page.keyboard.press("Delete")  # the inserted corner is selected: Delete removes it
    wait_js(page, "window.lotsen.route.area.length === 4")
    click_map(page, -4, -4)  # select a corner (deleting cleared the selection), + once more,
    click_map(page, 7, -4)  # then a right-click removes that corner
    wait_js(page, "window.lotsen.route.area.length === 5")
    x, y = page.evaluate("() => window.lotsen.map.toScreen(7, -4)")
    box = page.locator("#map").bounding_box()
    page.mouse.click(box["x"] + x, box["y"] + y, button="right")
    wait_js(page, "window.lotsen.route.area.length === 4")
    assert area() == [[-4, -4], [18, -4], pytest.approx([20, 14], abs=0.15), [-4, 12]]
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    # an obstacle: corners clicked with the Obstacle tool, closed with Finish polygon
    page.click("[data-tool=obstacle]")
    for n, e in ((0, 6), (3, 6), (3, 9), (0, 9)):
        click_map(page, n, e)
    page.click("#btn-finish")
    wait_js(page, "window.lotsen.route.obstacles.length === 1")
    obst = page.evaluate("() => window.lotsen.route.toDict().obstacles")
    assert obst[0]["forbidden"] == "inside" and len(obst[0]["polygon"]) == 4
    assert "obstacle 1, 4 corners" in page.inner_text("#polylist")
    page.click("[data-tool=select]")
    drag_map(page, 3, 9, 4, 10)  # its corners are edited like the area's
    wait_js(page, "window.lotsen.route.obstacles[0].polygon[2][0] > 3.5")
    assert page.evaluate("() => window.lotsen.route.obstacles[0].polygon[2]") == pytest.approx([4, 10], abs=0.15)
    # with a corner selected a polygon keeps at least 3 corners
    page.locator("#map").focus()
    page.keyboard.press("Delete")
    wait_js(page, "window.lotsen.route.obstacles[0].polygon.length === 3")
    click_map(page, 0, 9)
    page.locator("#map").focus()
    page.keyboard.press("Delete")
    wait_js(page, "document.querySelector('#toast').textContent.includes('at least 3 corners')")
    assert page.evaluate("() => window.lotsen.route.obstacles[0].polygon.length") == 3
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")
    assert page.errors == []


def test_edit_a_node_in_latitude_and_longitude(page):
    pymap3d = pytest.importorskip("pymap3d")
    origin = page.evaluate("() => window.lotsen.origin")
    assert origin is not None
    before = page.evaluate("() => window.lotsen.route.nodes[0]")
    page.click("#nodetable tr[data-kind=node][data-i='0'] td:first-child")
    wait_js(page, "!document.querySelector('#nodegeo').hidden")
    assert page.inner_text("#nodegeo-label") == "node 1"  # counted from 1, as in every message
    lat0, lon0 = float(page.input_value("#geo-lat")), float(page.input_value("#geo-lon"))
    la, lo, _ = pymap3d.ned2geodetic(before["north"], before["east"], 0.0, origin["lat"], origin["lon"], origin["h"])
    assert lat0 == pytest.approx(la, abs=2e-7) and lon0 == pytest.approx(lo, abs=2e-7)
    lat, lon, _ = pymap3d.ned2geodetic(6.5, 0.75, 0.0, origin["lat"], origin["lon"], origin["h"])
    page.fill("#geo-lat", f"{lat:.8f}")
    page.fill("#geo-lon", f"{lon:.8f}")
    page.press("#geo-lon", "Enter")
    wait_js(page, "Math.abs(window.lotsen.route.nodes[0].east - 0.75) < 0.01")
    node = page.evaluate("() => window.lotsen.route.nodes[0]")
    assert node["north"] == pytest.approx(6.5, abs=0.01) and node["east"] == pytest.approx(0.75, abs=0.01)
    assert page.input_value("#nodetable tr[data-kind=node][data-i='0'] input[data-f=north]") == str(node["north"])
    # bad input is refused with the reason; the node stays
    page.fill("#geo-lat", "91")
    page.press("#geo-lat", "Enter")
    wait_js(page, "document.querySelector('#fielderr').textContent !== ''")
    assert page.evaluate("() => window.lotsen.route.nodes[0].north") == node["north"]
    page.fill("#geo-lat", f"{lat:.8f}")
    page.press("#geo-lat", "Enter")
    wait_js(page, "document.querySelector('#fielderr').textContent === ''")
    # a polygon corner too: the obstacle's corner at N3 E6 moved to N2.5 E6.5
    click_map(page, 3, 6)
    wait_js(page, "document.querySelector('#nodegeo-label').textContent === 'obstacle 1 corner 2'")
    lat, lon, _ = pymap3d.ned2geodetic(2.5, 6.5, 0.0, origin["lat"], origin["lon"], origin["h"])
    page.fill("#geo-lat", f"{lat:.8f}")
    page.fill("#geo-lon", f"{lon:.8f}")
    page.press("#geo-lon", "Enter")
    wait_js(page, "Math.abs(window.lotsen.route.obstacles[0].polygon[1][1] - 6.5) < 0.01")
    assert page.evaluate("() => window.lotsen.route.obstacles[0].polygon[1]") == pytest.approx([2.5, 6.5], abs=0.01)
    # back where it was, in local metres (the mission below uses the original route)
    for f in ("north", "east"):
        cell = f"#nodetable tr[data-kind=node][data-i='0'] input[data-f={f}]"
        page.fill(cell, str(before[f]))
        page.press(cell, "Enter")
        wait_js(page, f"window.lotsen.route.nodes[0].{f} === {before[f]}")
    wait_js(page, "document.querySelector('#planstatus').textContent.startsWith('planned')")


def test_preload_map_tiles_for_the_area_and_see_them_under_the_route(page, tile_server):
    take_controls(page)
    page.evaluate("() => window.lotsen.map.fit()")
    page.click("[data-tab=maps]")
    wait_js(page, "document.querySelector('#tilecount').textContent.includes('tiles')")
    page.click("#btn-tiles")
    wait_js(page, "window.lotsen.tileProgress && window.lotsen.tileProgress.state === 'done'", timeout=15)
    prog = page.evaluate("() => window.lotsen.tileProgress")
    assert prog["fetched"] == prog["total"] > 0 and prog["failed"] == 0
    wait_js(page, f"window.lotsen.tiles.count === {prog['total']}")
    # drawn from the boat's cache, never from the tile server
    wait_js(page, "window.lotsen.map.tilesDrawn > 0 || performance.getEntriesByType('resource')"
                  ".some(e => e.name.includes('/tiles/'))")
    assert not [u for u in page.requests if str(tile_server.httpd.server_address[1]) in u]
    assert "tiles cached" in page.inner_text("#tilestatus")
    page.click("[data-tab=plan]")


def test_logs_are_listed_and_downloaded(page):
    page.click("[data-tab=logs]")
    link = page.locator("a[data-log='2026-11-23_lake.mcap']")
    link.wait_for()
    assert "app.foxglove.dev" in page.get_attribute("a[data-foxglove='2026-11-23_lake.mcap']", "href")
    with page.expect_download() as info:
        link.click()
    d = info.value
    assert d.suggested_filename == "2026-11-23_lake.mcap"
    assert Path(d.path()).read_bytes().startswith(b"\x89MCAP0")
    page.click("[data-tab=plan]")


def test_use_the_route_and_run_a_simulated_mission(page, stack):
    take_controls(page)
    page.click("#btn-use")
    wait_js(page, "document.querySelector('#toast').textContent.startsWith('route uploaded')")
    # the server hands the message to the executor thread: it reaches the bus a moment later
    deadline = time.monotonic() + 5.0
    while not stack.messages(Topic.ROUTE) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert stack.messages(Topic.ROUTE)[-1].route["nodes"][1]["speed_mps"] == 0.4
    sent = stack.messages(Topic.ROUTE)[-1].route  # the area and obstacle drawn on the map go with it
    drawn = page.evaluate("() => window.lotsen.route.toDict()")
    assert sent["area"] == drawn["area"] and len(sent["area"]) == 4
    assert sent["obstacles"] == [drawn["obstacles"][0]["polygon"]]  # inside forbidden: a plain polygon
    wait_js(page, "window.lotsen.map.activePath && window.lotsen.map.activePath.n.length > 10")
    wait_js(page, "window.lotsen.readbackMatch === true")  # the boat holds what was uploaded
    arm(page)
    page.click("[data-action=auto]")
    wait_js(page, "window.lotsen.telemetry.sup && window.lotsen.telemetry.sup.mode === 'AUTO'")
    # moving along the route (the speed ramps up from 0 at the harbour, seed eq. 42)
    wait_js(page, "window.lotsen.telemetry.pose.n > 1.2 && window.lotsen.telemetry.ctrl.progress > 1.0", timeout=20)
    # progress along the route with the distance left and an ETA, on the HUD and the next-action line
    wait_js(page, "document.querySelector('#hud-progress').textContent.includes('ETA')")
    assert "% of" in page.inner_text("#next-text")
    t = page.evaluate("() => window.lotsen.telemetry")
    assert abs(t["ctrl"]["xte"]) < 0.5 and abs(t["pose"]["e"]) < 0.5 and len(t["ctrl"]["pred_n"]) > 2
    page.evaluate("() => { document.querySelector('[data-tab=plan]').click(); }")
    shot(page, "mission")
    if os.environ.get("LOTSEN_UPDATE_SCREENSHOT"):
        page.screenshot(path=str(ROOT / "docs" / "images" / "operator-ui.png"))
    page.click("[data-tab=operate]")
    page.click("[data-action=hold]")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'HOLD'")


def test_drive_with_the_keyboard_then_emergency_stop(page, stack):
    take_controls(page)
    arm(page)
    page.click("[data-action=manual]")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    page.locator("#map").focus()
    p0 = boat(page)
    page.keyboard.down("w")
    wait_js(page, "document.querySelector('#drivepad [data-key=w]').classList.contains('on')")
    wait_js(page, "window.lotsen.telemetry.cmd && Math.abs(window.lotsen.telemetry.cmd.n1) > 5")
    shot(page, "manual")

    def ahead() -> bool:  # 0.3 m and 0.1 m/s: about 2 s from rest here, longer when the machine is busy
        p1 = boat(page)
        return math.hypot(p1["n"] - p0["n"], p1["e"] - p0["e"]) > 0.3 and p1["u"] > 0.1

    wait_until(ahead, timeout=10.0)
    page.keyboard.up("w")
    wait_js(page, "!document.querySelector('#drivepad [data-key=w]').classList.contains('on')")
    wait_until(lambda: stack.messages(Topic.MANUAL)[-1].surge == 0.0)  # a zero command on release
    page.keyboard.down("w")  # drive again, then hit the big red button
    wait_js(page, "Math.abs(window.lotsen.telemetry.cmd.n1) > 5")
    page.click("#estop")
    page.keyboard.up("w")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
    # the latched stop is a critical alert on the map, and the mode buttons say why they are off
    wait_js(page, "!!document.querySelector('#alerts .alert.critical[data-code=estop]')")
    wait_js(page, "document.querySelector('[data-action=auto]').disabled")
    assert "emergency stop" in page.get_attribute("[data-action=auto]", "title")
    wait_js(page, "['n1','n2','nt'].every(k => Math.abs(window.lotsen.telemetry.act[k]) < 0.5)", timeout=3)
    wait_until(lambda: all(getattr(stack.stack.bus.latest[Topic.SHIP_COMMAND], k) == 0.0
                           for k in ("n1_rps", "n2_rps", "nt_rps")))
    shot(page, "estop")
    page.click("[data-action=reset_estop]")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    wait_js(page, "!document.querySelector('#alerts .alert.critical')")  # cleared with the latch
    assert page.errors == []


def test_esc_in_a_text_field_cancels_the_edit_and_does_not_stop_the_boat(page, stack):
    """Esc inside a field is "cancel this edit": the old value comes back and the boat keeps its
    mode. Esc with the focus elsewhere is still the emergency stop."""
    take_controls(page)
    arm(page)
    page.click("[data-action=manual]")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    page.click("[data-tab=plan]")
    field = page.locator("#default-speed")
    before = field.input_value()
    sent_before = len(stack.messages(Topic.OPERATOR))
    field.click()
    field.fill("0.9")
    page.keyboard.press("Escape")
    assert field.input_value() == before
    time.sleep(1.0)
    assert page.evaluate("window.lotsen.telemetry.sup.mode") == "MANUAL"
    assert not any(m.action == "estop" for m in stack.messages(Topic.OPERATOR)[sent_before:])
    page.locator("#map").focus()
    page.keyboard.press("Escape")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'ESTOP'")
    page.click("[data-tab=operate]")
    page.click("[data-action=reset_estop]")
    wait_js(page, "window.lotsen.telemetry.sup.mode === 'MANUAL'")
    assert page.errors == []


def test_a_refusal_is_a_visible_dismissable_alert(page, stack):
    """The page offers only what the supervisor allows; a request it refuses anyway (sent by a
    second page, or racing a mode change) comes back as an error alert, not as a 'sent' toast."""
    take_controls(page)
    wait_js(page, "window.lotsen.telemetry.sup.armed === false")  # the e-stop reset disarmed
    assert page.locator("[data-action=auto]").is_disabled()
    assert "arm first" in page.get_attribute("[data-action=auto]", "title")
    page.evaluate("() => window.lotsen.send({type: 'command', action: 'auto'})")
    sel = "#alerts .alert.error[data-code='refused:auto']"
    wait_js(page, f"!!document.querySelector(\"{sel}\")")
    assert "arm first" in page.inner_text(sel)
    page.click(f"{sel} button.dismiss")
    wait_js(page, f"!document.querySelector(\"{sel}\")")
    assert page.errors == []
