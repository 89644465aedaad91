"""Route files the ground stations write (lotsen.planning.formats): QGroundControl .plan, QGC WPL
110, KML and GPX, read into lotsen's route and written from it, with the item rules of
docs/mavlink.md (harbour, headings, speeds, fences) and clear errors for what a boat cannot do."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from lotsen.errors import ConfigError
from lotsen.model.geodetic import LocalFrame
from lotsen.planning import GeoOrigin, plan_route
from lotsen.planning.formats import read_route_text, write_route_text
from lotsen.planning.formats.items import MissionItemError, computed_headings
from lotsen.planning.io import load_route, route_from_dict, route_to_dict

ORIGIN = GeoOrigin(47.3977, 8.5456, 0.0)
FRAME = LocalFrame(ORIGIN.lat_deg, ORIGIN.lon_deg, 0.0)


def ll(n: float, e: float) -> list[float]:
    lat, lon, _ = FRAME.to_geodetic(n, e)
    return [lat, lon]


def qgc_plan(items: list[dict], fence: dict | None = None, rally: list | None = None, home=(0.0, 0.0)) -> str:
    """A .plan as QGroundControl writes it (its developer guide's "Plan File Format": version 1,
    mission version 2 with plannedHomePosition and SimpleItems whose unset params are null)."""
    return json.dumps({
        "fileType": "Plan", "groundStation": "QGroundControl", "version": 1,
        "geoFence": fence or {"circles": [], "polygons": [], "version": 2},
        "mission": {"cruiseSpeed": 0.6, "firmwareType": 3, "globalPlanAltitudeMode": 1, "hoverSpeed": 5,
                    "items": items, "plannedHomePosition": [*ll(*home), 488.0], "vehicleType": 11, "version": 2},
        "rallyPoints": {"points": rally or [], "version": 2}})


def waypoint(n: float, e: float, jump: int, yaw=None) -> dict:
    return {"AMSLAltAboveTerrain": None, "Altitude": 0, "AltitudeMode": 1, "autoContinue": True, "command": 16,
            "doJumpId": jump, "frame": 3, "params": [0, 0, 0, yaw, *ll(n, e), 0], "type": "SimpleItem"}


def speed(v: float, jump: int) -> dict:
    return {"autoContinue": True, "command": 178, "doJumpId": jump, "frame": 2, "params": [1, v, -1, 0, 0, 0, 0],
            "type": "SimpleItem"}


def test_a_qgroundcontrol_plan_becomes_a_route_and_round_trips():
    text = qgc_plan(
        [waypoint(10, 0, 1), speed(0.8, 2), waypoint(20, 10, 3, yaw=90), waypoint(30, 10, 4)],
        fence={"version": 2, "circles": [{"circle": {"center": ll(20, 20), "radius": 3}, "inclusion": False,
                                          "version": 1}],
               "polygons": [{"inclusion": True, "polygon": [ll(-5, -10), ll(40, -10), ll(40, 40), ll(-5, 40)],
                             "version": 1}]})
    d = read_route_text(text, "plan", ORIGIN)
    r = route_from_dict(d)
    assert (r.harbour.north_m, r.harbour.east_m) == pytest.approx((0, 0), abs=1e-3)
    assert [c for n in r.nodes for c in (n.north_m, n.east_m)] == pytest.approx([10, 0, 20, 10, 30, 10], abs=1e-3)
    # before the speed change: the plan's cruise speed; after it: 0.8 m/s
    assert [n.speed_mps for n in r.nodes] == pytest.approx([0.6, 0.8, 0.8])
    # yaw given on waypoint 2 (90 deg); the others bisect their legs; the last follows its leg in
    assert math.degrees(r.nodes[1].heading_rad) == pytest.approx(90.0)
    assert math.degrees(r.nodes[0].heading_rad) == pytest.approx(22.5, abs=1e-3)
    assert math.degrees(r.nodes[2].heading_rad) % 360 == pytest.approx(0.0, abs=1e-3)
    assert len(r.area) == 4 and len(r.obstacles) == 1 and len(r.obstacles[0].polygon) == 32
    plan_route(r)  # a boat can do it
    # written as .plan and read back: the same route
    text2, notes = write_route_text(r, "plan", ORIGIN)
    assert not notes
    back = route_to_dict(route_from_dict(read_route_text(text2, "plan", ORIGIN)))
    _same(route_to_dict(r), back)


def _same(a: dict, b: dict, tol: float = 1e-3) -> None:
    assert len(a["nodes"]) == len(b["nodes"])
    for key in ("north", "east", "heading_deg"):
        assert b["harbour"][key] == pytest.approx(a["harbour"][key], abs=tol), key
    for x, y in zip(a["nodes"], b["nodes"]):
        for key in ("north", "east", "speed_mps"):
            assert y[key] == pytest.approx(x[key], abs=tol), key
        assert (y["heading_deg"] - x["heading_deg"] + 180) % 360 - 180 == pytest.approx(0, abs=tol)
    assert (a.get("area") is None) == (b.get("area") is None)
    if a.get("area"):
        assert [c for p in b["area"] for c in p] == pytest.approx([c for p in a["area"] for c in p], abs=tol)
    assert len(a.get("obstacles", [])) == len(b.get("obstacles", []))


@pytest.mark.parametrize("fmt", ["plan", "wpl", "kml", "gpx"])
def test_every_format_round_trips_the_example_route(fmt):
    route = load_route("examples/routes/square_with_obstacle.yaml")
    text, notes = write_route_text(route, fmt, ORIGIN)
    back = route_from_dict(read_route_text(text, fmt, ORIGIN))
    a, b = route_to_dict(route), route_to_dict(back)
    if fmt in ("wpl", "gpx"):  # no polygons in these formats: said, not silently dropped
        assert notes and "not written" in notes[0]
        a.pop("area"), a.pop("obstacles")
    else:
        assert not notes
    _same(a, b)


def test_mission_planner_waypoints_with_zero_yaw_get_computed_headings():
    """Mission Planner writes 0 for "no yaw": the headings follow the legs (the documented rule)."""
    rows = [(0, 1, 0, 16, 0, 0, 0, 0, *ll(0, 0), 0, 1), (1, 0, 3, 16, 0, 0, 0, 0, *ll(0, 10), 0, 1),
            (2, 0, 3, 16, 0, 0, 0, 0, *ll(10, 10), 0, 1), (3, 0, 3, 16, 0, 0, 0, 360, *ll(10, 20), 0, 1)]
    text = "QGC WPL 110\r\n" + "\r\n".join("\t".join(str(v) for v in r) for r in rows) + "\r\n"
    r = route_from_dict(read_route_text(text, "wpl", ORIGIN, default_speed_mps=0.4))
    h = [round(math.degrees(n.heading_rad) % 360, 3) for n in r.nodes]
    assert h == [45.0, 45.0, 0.0]  # bisectors of east/north legs; 360 means north
    assert math.degrees(r.harbour.heading_rad) == pytest.approx(90.0)  # towards the first node
    assert [n.speed_mps for n in r.nodes] == [0.4] * 3


def test_computed_headings_bisect_the_legs():
    assert computed_headings([(0, 0), (10, 0), (10, 10)]) == pytest.approx([45.0, 90.0])


def test_foreign_kml_and_gpx_read_with_default_speed_and_simplified_tracks():
    kml = f"""<?xml version="1.0"?><kml xmlns="http://www.opengis.net/kml/2.2"><Document>
      <Placemark><name>lake</name><Polygon><outerBoundaryIs><LinearRing><coordinates>
        {' '.join(f'{p[1]},{p[0]},0' for p in (ll(-5, -5), ll(40, -5), ll(40, 40), ll(-5, 40), ll(-5, -5)))}
      </coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>
      <Placemark><name>pier</name><Polygon><outerBoundaryIs><LinearRing><coordinates>
        {' '.join(f'{p[1]},{p[0]},0' for p in (ll(20, 20), ll(22, 20), ll(22, 22), ll(20, 22)))}
      </coordinates></LinearRing></outerBoundaryIs></Polygon></Placemark>
      <Placemark><name>tour</name><LineString><coordinates>
        {' '.join(f'{p[1]},{p[0]}' for p in (ll(0, 0), ll(10, 0), ll(10, 10)))}</coordinates></LineString></Placemark>
    </Document></kml>"""
    r = route_from_dict(read_route_text(kml, "kml", ORIGIN, default_speed_mps=0.3))
    assert len(r.nodes) == 2 and r.nodes[0].speed_mps == 0.3 and len(r.area) == 4 and len(r.obstacles) == 1
    # a recorded track: a point every 0.2 m along two straight legs -> the corner survives, not 100 points
    pts = [(0.2 * k, 0.0) for k in range(51)] + [(10.0, 0.2 * k) for k in range(1, 51)]
    gpx = ('<gpx xmlns="http://www.topografix.com/GPX/1/1" version="1.1"><trk><trkseg>'
           + "".join(f'<trkpt lat="{ll(*p)[0]}" lon="{ll(*p)[1]}"/>' for p in pts) + "</trkseg></trk></gpx>")
    r = route_from_dict(read_route_text(gpx, "gpx", ORIGIN))
    assert [(round(n.north_m, 2), round(n.east_m, 2)) for n in r.nodes] == [(10.0, 0.0), (10.0, 10.0)]


@pytest.mark.parametrize("items, words", [
    ([{"command": 22, "params": [0, 0, 0, None, 0, 0, 10]}], "item 1: take-off"),
    ([{"command": 16, "params": [0, 0, 0, None, *ll(5, 0), 0]}, {"command": 177, "params": [1, 3, 0, 0, 0, 0, 0]}],
     "item 2: jump"),
    ([{"command": 16, "params": [0, 0, 0, None, *ll(5, 0), 0]}, {"command": 20, "params": [0] * 7}],
     "item 2: return to launch inside a mission"),
    ([{"command": 183, "params": [0] * 7}], "item 1: MAV_CMD 183: not supported"),
])
def test_what_a_boat_cannot_do_is_refused_naming_the_item(items, words):
    text = qgc_plan([{"type": "SimpleItem", "frame": 3, "autoContinue": True, "doJumpId": k + 1, **it}
                     for k, it in enumerate(items)])
    with pytest.raises(MissionItemError, match=words):
        read_route_text(text, "plan", ORIGIN)


def test_bad_files_are_refused_with_the_reason():
    with pytest.raises(ConfigError, match="StructureScan item is not supported"):
        read_route_text(qgc_plan([{"type": "ComplexItem", "complexItemType": "StructureScan"}]), "plan", ORIGIN)
    with pytest.raises(ConfigError, match="survey item version None; lotsen reads versions 4 and 5"):
        read_route_text(qgc_plan([{"type": "ComplexItem", "complexItemType": "survey"}]), "plan", ORIGIN)
    with pytest.raises(ConfigError, match="DOCTYPE"):
        read_route_text('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "b">]><kml/>', "kml", ORIGIN)
    with pytest.raises(ConfigError, match="one rally point"):
        read_route_text(qgc_plan([waypoint(5, 0, 1)], rally=[[*ll(0, 0), 0], [*ll(1, 1), 0]]), "plan", ORIGIN)
    with pytest.raises(ConfigError, match="line 2: expected 12 fields"):
        read_route_text("QGC WPL 110\n0\t1\t0\t16\n", "wpl", ORIGIN)
    with pytest.raises(ConfigError, match="2 lines"):
        read_route_text('<kml><Placemark><LineString><coordinates>8.5,47.3 8.6,47.3</coordinates></LineString>'
                        '</Placemark><Placemark><LineString><coordinates>8.5,47.3 8.6,47.3</coordinates>'
                        '</LineString></Placemark></kml>', "kml", ORIGIN)


def test_lotsen_plan_reads_and_exports_ground_station_files(tmp_path):
    src = tmp_path / "mission.plan"
    src.write_text(qgc_plan([waypoint(10, 0, 1), waypoint(20, 10, 2)]))
    run = subprocess.run([sys.executable, "-m", "lotsen", "plan", str(src), "--export", str(tmp_path / "m.gpx")],
                         capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "wrote" in run.stdout and (tmp_path / "m.gpx").read_text().count("<rtept") == 3
    bad = subprocess.run([sys.executable, "-m", "lotsen", "plan", str(src), "--export", str(tmp_path / "m.xyz")],
                         capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert bad.returncode != 0 and "unknown route file type" in bad.stderr and "Traceback" not in bad.stderr
