"""The page's geo.js is the browser's copy of lotsen.model.geodetic and lotsen.web.tiles (a page
cannot import Python): both must give the same numbers, or a route drawn on the map lands
somewhere else than the exported GeoJSON says."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from lotsen.model.geodetic import LocalFrame
from lotsen.web.tiles import lonlat_to_tile, tile_to_lonlat

GEO_JS = Path(__file__).resolve().parents[2] / "lotsen" / "web" / "static" / "js" / "geo.js"

pytestmark = pytest.mark.skipif(shutil.which("node") is None, reason="node (to run the page's JavaScript) not installed")

ORIGINS = [(59.3293, 18.0686, 12.0), (-33.86, 151.21, 0.0), (0.0, 0.0, 0.0), (69.5, -20.0, 300.0)]


def _points(seed: int = 3) -> list[tuple[float, float, float]]:
    rng = np.random.default_rng(seed)
    return [(float(n), float(e), float(d)) for n, e, d in
            zip(rng.uniform(-2000, 2000, 8), rng.uniform(-2000, 2000, 8), rng.uniform(-5, 5, 8))]


def _run_js(cases: list[dict]) -> list[dict]:
    script = f"""
import {{ geodeticToNed, nedToGeodetic, lonLatToTile, tileToLonLat }} from {json.dumps(GEO_JS.as_uri())};
const cases = {json.dumps(cases)};
const out = cases.map(c => ({{
  ned: geodeticToNed(c.lat, c.lon, c.h, c.o),
  geo: nedToGeodetic(c.n, c.e, c.d, c.o),
  tile: lonLatToTile(c.o.lat, c.o.lon, 17),
  corner: tileToLonLat(70000.5, 38000.25, 17),
}}));
console.log(JSON.stringify(out));
"""
    done = subprocess.run(["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_geo_js_agrees_with_the_servers_local_frame_and_tiles():
    cases = []
    for lat0, lon0, h0 in ORIGINS:
        frame = LocalFrame(lat0, lon0, h0)
        for n, e, d in _points():
            lat, lon, h = frame.to_geodetic(n, e, d)
            cases.append({"o": {"lat": lat0, "lon": lon0, "h": h0}, "n": n, "e": e, "d": d,
                          "lat": lat, "lon": lon, "h": h})
    out = _run_js(cases)
    assert len(out) == len(cases)
    for c, js in zip(cases, out):
        frame = LocalFrame(c["o"]["lat"], c["o"]["lon"], c["o"]["h"])
        np.testing.assert_allclose(js["ned"], frame.to_ned(c["lat"], c["lon"], c["h"]), rtol=0, atol=1e-6)
        np.testing.assert_allclose(js["geo"][:2], [c["lat"], c["lon"]], rtol=0, atol=1e-10)
        assert abs(js["geo"][2] - c["h"]) < 1e-6
        np.testing.assert_allclose(js["tile"], lonlat_to_tile(c["o"]["lat"], c["o"]["lon"], 17), rtol=1e-12)
        np.testing.assert_allclose(js["corner"], tile_to_lonlat(70000.5, 38000.25, 17), rtol=1e-12)
