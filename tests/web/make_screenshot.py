"""Refresh docs/images/operator-ui.png: a mission on examples/routes/square_with_obstacle.yaml,
driven through the real page (load file, take controls, use route, start auto), simulated
faster than real time so the picture shows the boat well along its route.

    .venv/bin/python tests/web/make_screenshot.py [--speed 4] [--sim-seconds 75]
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from lotsen.runtime.config import LaunchConfig, LoggingSection, SimSection, WebSection  # noqa: E402
from lotsen.stack.launch import build_stack  # noqa: E402

TOKEN = "screenshot-Tq7vLx2Rb9KmZ4wNc8"  # >= 128 bits (a weak token is refused at start)
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
        "--no-first-run", "--disable-sync"]


def wait_js(pg, expr: str, timeout: float = 30.0) -> None:
    t_end = time.monotonic() + timeout
    while not pg.evaluate(f"() => ({expr})"):
        if time.monotonic() > t_end:
            raise SystemExit(f"timed out waiting for: {expr}")
        time.sleep(0.1)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--speed", type=float, default=4.0, help="simulated seconds per wall second")
    ap.add_argument("--sim-seconds", type=float, default=75.0)
    ap.add_argument("--out", default=str(ROOT / "docs" / "images" / "operator-ui.png"))
    args = ap.parse_args()
    cfg = LaunchConfig(sim=SimSection(initial_state=(2.0, 20.0, math.pi / 2, 0.0, 0.0, 0.0)),
                       web=WebSection(port=0, pilot_token=TOKEN), logging=LoggingSection(enabled=False))
    stack = build_stack(cfg, realtime=False)
    ex = stack.executor
    stop = threading.Event()

    def drive() -> None:  # simulated time at `speed` x wall clock
        t0, s0 = time.monotonic(), ex.clock.now()
        while not stop.is_set():
            target = s0 + (time.monotonic() - t0) * args.speed
            if ex.clock.now() < target:
                ex.run_until(min(target, ex.clock.now() + 0.05))
            else:
                time.sleep(0.005)

    threading.Thread(target=drive, daemon=True).start()
    from playwright.sync_api import sync_playwright

    try:
        with sync_playwright() as p:
            b = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
            pg = b.new_page(viewport={"width": 1440, "height": 900})
            pg.goto(stack.services["web"].url)
            pg.set_input_files("#file-load", str(ROOT / "examples" / "routes" / "square_with_obstacle.yaml"))
            time.sleep(1.5)
            pg.fill("#token", TOKEN)
            pg.click("#btn-auth")
            wait_js(pg, "window.lotsen.pilot === true")
            pg.click("#btn-use")
            wait_js(pg, "window.lotsen.readbackMatch === true")
            pg.click("[data-tab=operate]")
            wait_js(pg, "window.lotsen.actionState('arm').ok")  # the ESCs need neutral for a moment
            pg.click("[data-action=arm]")
            wait_js(pg, "window.lotsen.actionState('auto').ok")
            pg.click("[data-action=auto]")
            t_start = ex.clock.now()
            while ex.clock.now() - t_start < args.sim_seconds:
                time.sleep(0.2)
            pg.click("[data-tab=plan]")
            pg.evaluate("() => window.lotsen.map.fit()")
            pg.evaluate("() => { document.querySelector('#side').scrollTop = 0; }")  # the next action on top
            time.sleep(0.5)
            pg.screenshot(path=args.out)
            mode = pg.evaluate("() => window.lotsen.telemetry.sup && window.lotsen.telemetry.sup.mode")
            b.close()
    finally:
        stop.set()
        for f in stack.services.get("on_shutdown", []):
            f()
    print(f"wrote {args.out} (mode {mode})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
