"""Survey and depth map (issue 48 items 1 and 4): the 40 x 30 m survey at 2 m spacing and 0.8 m/s
flown by the stack `lotsen run` builds (lake boat, EKF, MPC) on simulated time in 0.1 m/s current
and 3 m/s wind over a simulated lake bed (a slope with a ridge and a hollow), the sounder at 2 cm
noise and 2 % dropouts with a 20-s outage (holes); the depth map against the bed, the coverage, the
re-run over the holes (flown) and the coverage after it. Quick mode: a 16 x 12 m polygon.

    python bench/run.py survey
"""

from __future__ import annotations

import math

import numpy as np

from lotsen.bathymetry import DepthGrid, coverage, rerun_pattern
from lotsen.harness.survey import SurveyRunConfig, run_survey
from lotsen.planning import plan_route
from lotsen.planning.io import route_from_dict, route_to_dict
from lotsen.planning.survey import pattern_to_dict
from lotsen.runtime.config import EnvironmentConfig, LakeBedSection

NOISE_M = 0.02


def lake_bed(n0: float, e0: float, cell: float, rows: int, cols: int) -> LakeBedSection:
    def depth(n: float, e: float) -> float:
        return (2.0 + 0.04 * n + 0.4 * math.sin(e / 7.0)
                + 0.8 * math.exp(-((n - 20.0) ** 2 + (e - 12.0) ** 2) / 40.0))   # a hollow
    grid = tuple(tuple(round(depth(n0 + i * cell, e0 + j * cell), 3) for j in range(cols)) for i in range(rows))
    return LakeBedSection(depths_m=grid, origin_m=(n0, e0), cell_m=cell, sounder_noise_m=NOISE_M, sounder_dropout=0.02)


def run(quick: bool = False) -> list[dict]:
    size = (16.0, 12.0) if quick else (40.0, 30.0)
    route = route_from_dict({
        "origin": {"lat_deg": 57.6905, "lon_deg": 11.976},
        "harbour": {"north": -5.0, "east": -5.0, "heading_deg": 0.0},
        "area": [[-12, -12], [size[0] + 12, -12], [size[0] + 12, size[1] + 12], [-12, size[1] + 12]],
        "survey": {"polygon": [[0, 0], [size[0], 0], [size[0], size[1]], [0, size[1]]], "spacing_m": 2.0,
                   "speed_mps": 0.8, "turnaround_m": 2.0}})
    bed = lake_bed(-12.0, -12.0, 2.0, int((size[0] + 24) / 2) + 1, int((size[1] + 24) / 2) + 1)
    env = EnvironmentConfig(current_speed_mps=0.1, current_to_deg=90.0, wind_speed_mps=3.0, wind_from_deg=45.0)
    path = plan_route(route)
    on_lines = sum(ln.length_m for ln in route.survey_lines)
    cfg = SurveyRunConfig(lakebed=bed, environment=env, cell_m=2.0, sounder_outage_s=(60.0, 80.0),
                          max_duration_s=path.duration_s() * 1.5 + 60)
    first = run_survey(route, cfg)
    cov = first.coverage
    rows = [{"table": "survey flown (lake boat, EKF, MPC, 0.1 m/s current, 3 m/s wind)",
             "case": f"{size[0]:g} x {size[1]:g} m at 2 m, 0.8 m/s", "lines": len(route.survey_lines),
             "planned_s": round(path.duration_s(), 1), "flown_s": round(first.duration_s, 1),
             "planned_share_on_lines": round(on_lines / 0.8 / path.duration_s(), 3), "finished": first.finished,
             "soundings": len(first.soundings), "wall_s": round(first.wall_s, 1),
             "target": "finished", "pass": first.finished}]
    e = first.cell_errors_m
    rms, worst = first.rms_cell_error_m(), float(np.abs(e).max()) if len(e) else math.nan
    rows.append({"table": "depth map against the bed", "case": "cells of 2 m (mean of the soundings in each)",
                 "cells": len(e), "rms_error_m": round(rms, 4), "max_error_m": round(worst, 4),
                 "sounder_noise_m": NOISE_M, "target": "rms <= sounder noise", "pass": bool(rms <= NOISE_M)})
    rows.append({"table": "coverage", "case": "after the survey (20-s sounder outage)", "cells": len(cov.cells),
                 "covered": len(cov.covered), "hole_cells": len(cov.hole_cells), "holes": len(cov.holes),
                 "fraction": round(cov.fraction, 4), "target": "every cell covered or listed as a hole",
                 "pass": len(cov.covered) + len(cov.hole_cells) == len(cov.cells)})
    safe = route.free_region().buffer(-(route.survey.margin_m + 1e-3))
    pattern = rerun_pattern(cov, route.survey, safe, (route.harbour.north_m, route.harbour.east_m))
    if pattern is not None:
        d = route_to_dict(route)
        d["survey"] = pattern_to_dict(pattern)
        rerun = route_from_dict(d)
        second = run_survey(rerun, SurveyRunConfig(lakebed=bed, environment=env, cell_m=2.0, seed=1))
        merged = DepthGrid(2.0)
        for s in first.soundings + second.soundings:
            merged.add(s.north_m, s.east_m, s.depth_m)
        after = coverage(merged, route.survey.polygon)
        rows.append({"table": "coverage", "case": "after the re-run over the holes", "cells": len(after.cells),
                     "covered": len(after.covered), "hole_cells": len(after.hole_cells), "holes": len(after.holes),
                     "fraction": round(after.fraction, 4), "rerun_lines": len(pattern.lines or ()),
                     "rerun_flown_s": round(second.duration_s, 1), "target": "1.0", "pass": after.fraction == 1.0})
    return rows


if __name__ == "__main__":
    for row in run(quick=True):
        print(row)
