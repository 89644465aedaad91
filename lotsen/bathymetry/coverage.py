"""How much of a survey polygon the depth map covers, the holes left (cells without enough
soundings, merged into polygons) and a re-run: survey lines over the holes only.

A cell belongs to the polygon when its centre lies inside it; it is covered with at least
`min_count` soundings. Every cell of the polygon is either covered or in a hole, so the holes are
the whole of what is missing, not a sample of it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import shapely
from shapely.geometry import Point, Polygon, box

from lotsen.bathymetry.grid import DepthGrid
from lotsen.errors import ConfigError
from lotsen.planning.survey import SurveyPattern, survey_lines


@dataclass(frozen=True)
class Coverage:
    cell_m: float
    cells: tuple[tuple[int, int], ...]          # the polygon's cells
    covered: tuple[tuple[int, int], ...]
    hole_cells: tuple[tuple[int, int], ...]
    holes: tuple[tuple[tuple[float, float], ...], ...]   # merged hole cells, rings [north, east]

    @property
    def fraction(self) -> float:
        return len(self.covered) / len(self.cells) if self.cells else 1.0


def polygon_cells(polygon: Polygon, cell_m: float) -> list[tuple[int, int]]:
    """The cells of `cell_m` whose centre lies inside `polygon`."""
    if polygon.is_empty:
        return []
    n0, e0, n1, e1 = polygon.bounds
    i = np.arange(math.floor(n0 / cell_m), math.ceil(n1 / cell_m))
    j = np.arange(math.floor(e0 / cell_m), math.ceil(e1 / cell_m))
    ii, jj = np.meshgrid(i, j, indexing="ij")
    inside = shapely.contains_xy(polygon, (ii + 0.5) * cell_m, (jj + 0.5) * cell_m)
    return [(int(a), int(b)) for a, b in zip(ii[inside], jj[inside])]


def coverage(grid: DepthGrid, polygon: Polygon | tuple, min_count: int = 1) -> Coverage:
    poly = polygon if isinstance(polygon, Polygon) else Polygon(polygon)
    cells = polygon_cells(poly, grid.cell_m)
    covered = [k for k in cells if grid.count(k) >= min_count]
    missing = [k for k in cells if grid.count(k) < min_count]
    c = grid.cell_m
    merged = shapely.union_all([box(i * c, j * c, (i + 1) * c, (j + 1) * c) for i, j in missing]) if missing else None
    rings: list[tuple[tuple[float, float], ...]] = []
    if merged is not None:
        for g in getattr(merged, "geoms", [merged]):
            rings.append(tuple((round(x, 4), round(y, 4)) for x, y in g.exterior.coords[:-1]))
    return Coverage(c, tuple(cells), tuple(covered), tuple(missing), tuple(rings))


def rerun_pattern(cov: Coverage, survey: SurveyPattern, safe, start_near: tuple[float, float]) -> SurveyPattern | None:
    """Survey lines over the holes only, at the survey's angle, a line per hole cell row (spacing
    one cell), the holes visited nearest first from `start_near`; the survey's speed, turnaround,
    turn radius and margin. None without holes. `safe`: the navigable water shrunk by the margin."""
    if not cov.holes:
        return None
    todo = [Polygon(r) for r in cov.holes]
    here = np.asarray(start_near, float)
    pattern = replace(survey, polygon=None, lines=None, spacing_m=cov.cell_m, crosshatch=False, side="both", entry=None)
    lines: list[tuple[tuple[float, float], tuple[float, float]]] = []
    while todo:
        k = int(np.argmin([h.distance(Point(*here)) for h in todo]))
        hole = todo.pop(k)
        try:
            over = survey_lines(pattern, hole, safe, tuple(here))
        except ConfigError:   # no water the boat may run in over this hole (the area's edge): left out
            continue
        for ln in over:
            for a, b in ln.pieces:
                lines.append((a, b))
            here = np.asarray(ln.end, float)
    if not lines:
        return None
    return replace(pattern, lines=tuple(lines))
