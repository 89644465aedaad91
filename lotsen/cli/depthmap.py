"""`lotsen export RUN.mcap --out DIR`'s depth map: the run's soundings (depth/sounding) gridded
(lotsen.bathymetry), written as DIR/depth_map.csv and, with a geographic origin, .geojson; when the
log holds a survey route, its coverage, the holes and DIR/rerun.yaml (a route over the holes)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from lotsen.bathymetry import DepthGrid, coverage, rerun_pattern
from lotsen.bathymetry.export import depth_csv, depth_geojson
from lotsen.errors import ConfigError, DataError
from lotsen.files import write_output
from lotsen.logs.reader import LogReader
from lotsen.messages import Topic
from lotsen.model.geodetic import LocalFrame


def _survey_route(route_dicts: list[dict]) -> Any:
    """The last route of the log that is a survey, as a Route (None without one)."""
    from lotsen.planning.io import route_from_dict

    for d in reversed(route_dicts):
        if isinstance(d, dict) and d.get("survey") is not None:
            try:
                return route_from_dict(d)
            except ConfigError:
                continue
    return None


def export_depth_map(log: str, out: str, cell_m: float | None) -> list[str]:
    """Write the depth map files; returns the lines to print (empty when the log has no soundings)."""
    grid_points, routes = [], []
    for m in LogReader(log).read([Topic.SOUNDING, Topic.ROUTE, Topic.ACTIVE_ROUTE]):
        if m.topic == Topic.SOUNDING:
            s = m.message
            grid_points.append((s.north_m, s.east_m, s.depth_m))
        elif isinstance(getattr(m.message, "route", None), dict):
            routes.append(m.message.route)
    if not grid_points:
        return []
    route = _survey_route(routes)
    cell = cell_m or (route.survey.spacing_m if route is not None else 1.0)
    grid = DepthGrid(cell)
    for n, e, d in grid_points:
        grid.add(n, e, d)
    o = route.origin if route is not None else None
    frame = LocalFrame(o.lat_deg, o.lon_deg, o.height_m) if o is not None else None
    folder = Path(out)
    lines = [f"depth map: {grid.soundings} soundings in {len(grid)} cells of {cell:g} m"]
    write_output(folder / "depth_map.csv", depth_csv(grid, frame), (log,), DataError, "depth map")
    lines.append(f"depth/sounding -> {folder / 'depth_map.csv'}")
    cov = None
    if route is not None and route.survey.polygon is not None:
        cov = coverage(grid, route.survey.polygon)
        lines.append(f"survey coverage: {100 * cov.fraction:.1f} % of {len(cov.cells)} cells, "
                     f"{len(cov.hole_cells)} cells in {len(cov.holes)} holes")
        from dataclasses import replace

        from lotsen.planning.io import route_to_dict

        pattern = rerun_pattern(cov, route.survey, route.free_region().buffer(-(route.survey.margin_m + 1e-3)),
                                (route.harbour.north_m, route.harbour.east_m))
        if pattern is not None:
            rerun = {**route_to_dict(replace(route, nodes=(), survey_lines=())), "survey": {}}
            from lotsen.planning.survey import pattern_to_dict

            rerun["survey"] = pattern_to_dict(pattern)
            write_output(folder / "rerun.yaml", yaml.safe_dump(rerun, sort_keys=False, default_flow_style=None),
                         (log,), DataError, "re-run route")
            lines.append(f"re-run over the holes ({len(pattern.lines or ())} lines) -> {folder / 'rerun.yaml'}")
    if frame is not None:
        write_output(folder / "depth_map.geojson", json.dumps(depth_geojson(grid, frame, cov)), (log,), DataError,
                     "depth map")
        lines.append(f"depth map -> {folder / 'depth_map.geojson'}")
    else:
        lines.append("depth_map.geojson not written: the log's route has no geographic origin")
    return lines
