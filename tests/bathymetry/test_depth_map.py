"""Depth: soundings placed where the transducer was, the gridded depth map (mean, count, spread),
coverage and holes of a survey polygon, the re-run over the holes, and the whole chain on the
simulated stack over a simulated lake bed: the map against the bed, `lotsen export` of the run's
log, and the re-run filling the holes."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Point, Polygon, box

from lotsen.bathymetry import DepthGrid, SoundingMaker, coverage, rerun_pattern
from lotsen.cli.main import main
from lotsen.harness.survey import SurveyRunConfig, run_survey
from lotsen.messages import DepthSample, VesselState
from lotsen.planning.io import route_from_dict
from lotsen.planning.survey import SurveyPattern
from lotsen.runtime.config import LakeBedSection


@settings(max_examples=40, deadline=None)
@given(depths=st.lists(st.floats(0.1, 50.0), min_size=1, max_size=60))
def test_a_cell_holds_the_mean_count_and_spread_of_its_soundings(depths):
    g = DepthGrid(2.0)
    for d in depths:
        g.add(3.1, -0.5, d)
    count, mean, spread = g.cell(g.key(3.1, -0.5))
    assert count == len(depths) and mean == pytest.approx(np.mean(depths), rel=1e-9, abs=1e-9)
    if len(depths) > 1:
        assert spread == pytest.approx(np.std(depths, ddof=1), rel=1e-6, abs=1e-9)
    assert g.key(3.1, -0.5) == (1, -1)                        # cells on multiples of their size


def _state(t, n, e, psi):
    return VesselState(stamp_s=t, north_m=n, east_m=e, heading_rad=psi, u_mps=0, v_mps=0, r_radps=0,
                       std=(0.01, 0.02, 0.001, 0, 0, 0))


def test_a_sounding_is_at_the_transducer_at_the_pings_time_with_the_draft():
    m = SoundingMaker(transducer_m=(0.4, 0.1), draft_m=0.15)
    m.on_state(_state(10.0, 0.0, 0.0, math.pi / 2))           # heading east
    m.on_state(_state(10.2, 0.0, 0.2, math.pi / 2))
    s = m.on_depth(DepthSample(stamp_s=10.1, depth_m=3.0))
    assert (s.north_m, s.east_m) == pytest.approx((-0.1, 0.1 + 0.4))   # starboard of east is south
    assert s.depth_m == pytest.approx(3.15) and s.position_std_m == pytest.approx(math.hypot(0.01, 0.02))
    assert m.on_depth(DepthSample(stamp_s=10.1, depth_m=math.nan)) is None and m.no_bottom == 1
    assert m.on_depth(DepthSample(stamp_s=20.0, depth_m=3.0)) is None and m.no_position == 1   # no estimate near it


def test_heading_is_interpolated_the_short_way_round():
    m = SoundingMaker(transducer_m=(1.0, 0.0))
    m.on_state(_state(0.0, 0.0, 0.0, math.pi - 0.1))
    m.on_state(_state(0.2, 0.0, 0.0, -math.pi + 0.1))
    s = m.on_depth(DepthSample(stamp_s=0.1, depth_m=2.0))
    assert (s.north_m, s.east_m) == pytest.approx((-1.0, 0.0), abs=1e-9)     # due south, not north


def test_every_cell_of_the_polygon_is_covered_or_in_a_hole_and_the_rerun_crosses_every_hole_cell():
    poly = Polygon([(0, 0), (12, 0), (12, 10), (0, 10)])
    g = DepthGrid(2.0)
    missing = {(1, 1), (1, 2), (4, 3)}
    for i in range(6):
        for j in range(5):
            if (i, j) not in missing:
                g.add(2 * i + 1, 2 * j + 1, 3.0)
    cov = coverage(g, poly)
    assert len(cov.cells) == 30 and set(cov.hole_cells) == missing
    assert len(cov.covered) + len(cov.hole_cells) == len(cov.cells)
    assert len(cov.holes) == 2 and cov.fraction == pytest.approx(27 / 30)
    safe = box(-20, -20, 40, 40)
    rerun = rerun_pattern(cov, SurveyPattern(spacing_m=2.0, speed_mps=0.6), safe, (0.0, 0.0))
    tracks = [(a, b) for a, b in rerun.lines]
    for i, j in missing:
        centre = Point(2 * i + 1, 2 * j + 1)
        assert min(LineString([a, b]).distance(centre) for a, b in tracks) < 1e-6, (i, j)
    full = DepthGrid(2.0)
    for i in range(6):
        for j in range(5):
            full.add(2 * i + 1, 2 * j + 1, 3.0)
    assert coverage(full, poly).fraction == 1.0 and rerun_pattern(coverage(full, poly), SurveyPattern(), safe, (0, 0)) is None


# ----------------------------------------------------------------------------- on the stack
NOISE_M = 0.02


def bed_rows(n0, e0, cell, rows, cols):
    """A sloping bed with a ridge: 2 m deep, 5 cm deeper per metre north, +-0.5 m east-west."""
    return tuple(tuple(round(2.0 + 0.05 * (n0 + i * cell) + 0.5 * math.sin((e0 + j * cell) / 6.0), 3)
                       for j in range(cols)) for i in range(rows))


BED = LakeBedSection(depths_m=bed_rows(-10, -10, 2.5, 15, 13), origin_m=(-10.0, -10.0), cell_m=2.5,
                     sounder_noise_m=NOISE_M, sounder_dropout=0.02)
ROUTE = {"origin": {"lat_deg": 57.6905, "lon_deg": 11.976}, "harbour": {"north": -4, "east": -4, "heading_deg": 0},
         "area": [[-10, -10], [25, -10], [25, 20], [-10, 20]],
         "survey": {"polygon": [[0, 0], [12, 0], [12, 8], [0, 8]], "spacing_m": 2.0, "speed_mps": 0.8,
                    "turnaround_m": 2.0}}


@pytest.fixture(scope="module")
def flown(tmp_path_factory):
    """The survey flown with a sounder outage (holes), recorded, then its re-run."""
    folder = tmp_path_factory.mktemp("survey")
    route = route_from_dict(ROUTE)
    run = run_survey(route, SurveyRunConfig(lakebed=BED, fusion="truth", controller="los", cell_m=2.0,
                                            sounder_outage_s=(30.0, 45.0), log_dir=str(folder / "logs")))
    return folder, route, run


def test_the_depth_map_of_a_survey_matches_the_bed_within_the_sounders_noise(flown):
    _, route, run = flown
    assert run.finished
    e = run.cell_errors_m
    assert len(e) >= 20
    assert run.rms_cell_error_m() <= NOISE_M                    # the map against the bed it sounded
    assert np.abs(e).max() <= 3 * NOISE_M
    t = run.grid.table()
    assert t["count"].min() >= 1 and np.nanmax(t["spread_m"]) < 10 * NOISE_M


def test_every_cell_is_covered_or_listed_and_the_outage_left_holes(flown):
    _, _, run = flown
    cov = run.coverage
    assert len(cov.covered) + len(cov.hole_cells) == len(cov.cells) == 24
    assert 1 <= len(cov.hole_cells) < len(cov.cells)             # 15 s without a bottom: a stretch of line


def test_lotsen_export_writes_the_depth_map_and_a_rerun_that_fills_the_holes(flown, capsys):
    folder, route, run = flown
    out = folder / "export"
    assert main(["export", str(run.log_path), "--out", str(out), "--sysid", "none"]) == 0
    text = capsys.readouterr().out
    assert "survey coverage" in text and "rerun.yaml" in text
    rows = list(csv.DictReader(open(out / "depth_map.csv")))
    assert len(rows) == len(run.grid) and {"lat_deg", "depth_m", "count", "spread_m"} <= set(rows[0])
    geo = json.loads((out / "depth_map.geojson").read_text())
    assert geo["lotsen_coverage"]["holes"] == len(run.coverage.hole_cells)
    assert sum(f["properties"]["role"] == "hole" for f in geo["features"]) == len(run.coverage.holes)
    rerun = route_from_dict(yaml.safe_load((out / "rerun.yaml").read_text()))
    again = run_survey(rerun, SurveyRunConfig(lakebed=BED, fusion="truth", controller="los", cell_m=2.0, seed=1))
    assert again.finished
    merged = DepthGrid(2.0)
    for s in run.soundings + again.soundings:
        merged.add(s.north_m, s.east_m, s.depth_m)
    assert coverage(merged, route.survey.polygon).fraction == 1.0          # the re-run filled every hole
