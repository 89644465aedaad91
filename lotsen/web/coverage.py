"""The page's live coverage layer: the soundings the boat publishes (depth/sounding) gridded as
they come (lotsen.bathymetry.DepthGrid; the cell is the held survey's line spacing, else 1 m), sent
to the pages as the cells that changed (about once a second), with the survey polygon's coverage
and holes; and the re-run route over the holes, offered to the pilot.

Thread-safe: the hub's reader thread adds soundings, the event loop asks for the re-run.
"""

from __future__ import annotations

import threading
from dataclasses import replace
from typing import Any

from lotsen.bathymetry import DepthGrid, coverage, rerun_pattern
from lotsen.errors import ConfigError, LotsenError
from lotsen.messages import Sounding
from lotsen.planning.io import route_from_dict, route_to_dict

#: cells a page is sent at most (a 2 km x 2 km lake at 1 m is 4 million: the layer shows the newest)
MAX_CELLS = 20_000
DEFAULT_CELL_M = 1.0


class CoverageLayer:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.grid = DepthGrid(DEFAULT_CELL_M)
        self.route: Any = None           # the held route, when it is a survey (its polygon is judged)
        self._soundings: list[tuple[float, float, float]] = []
        self._changed: set[tuple[int, int]] = set()
        self._summary: dict | None = None
        self._summary_due = True

    def set_route(self, route_dict: Any) -> None:
        """The boat's route (planning/active_route): a survey sets the cell and the polygon."""
        try:
            route = route_from_dict(route_dict) if isinstance(route_dict, dict) else None
        except LotsenError:
            route = None
        survey = route if route is not None and route.survey is not None else None
        with self._lock:
            if survey is None and self.route is None:
                return
            if survey is not None and self.route is not None and route_to_dict(survey) == route_to_dict(self.route):
                return
            # a re-run keeps the map and the polygon of the survey it completes
            if survey is not None and survey.survey.polygon is None and self.route is not None:
                return
            self.route = survey
            cell = survey.survey.spacing_m if survey is not None else DEFAULT_CELL_M
            if cell != self.grid.cell_m:
                self.grid = DepthGrid(cell)
                for n, e, d in self._soundings:
                    self.grid.add(n, e, d)
                self._changed = {self.grid.key(n, e) for n, e, _ in self._soundings}
            self._summary_due = True

    def add(self, s: Sounding) -> None:
        with self._lock:
            if len(self._soundings) < 2_000_000:
                self._soundings.append((s.north_m, s.east_m, s.depth_m))
            k = self.grid.add(s.north_m, s.east_m, s.depth_m)
            if k is not None:
                self._changed.add(k)
                self._summary_due = True

    def _cells(self, keys: Any) -> list[list[float]]:
        out = []
        for k in list(keys)[-MAX_CELLS:]:
            c = self.grid.cell(k)
            if c is not None:
                out.append([k[0], k[1], round(c[1], 3), c[0]])
        return out

    def _coverage_json(self) -> dict | None:
        if self.route is None or self.route.survey.polygon is None:
            return None
        cov = coverage(self.grid, self.route.survey.polygon)
        return {"fraction": round(cov.fraction, 4), "cells": len(cov.cells), "covered": len(cov.covered),
                "hole_cells": len(cov.hole_cells), "holes": [[list(p) for p in h] for h in cov.holes[:200]]}

    def take_update(self) -> dict | None:
        """The cells changed since the last call and the coverage, as a page event (None: nothing new)."""
        with self._lock:
            if not self._changed and not self._summary_due:
                return None
            cells, self._changed = self._cells(self._changed), set()
            if self._summary_due:
                self._summary = self._coverage_json()
                self._summary_due = False
            return {"type": "coverage", "cell_m": self.grid.cell_m, "cells": cells, "reset": False,
                    "survey": self._summary, "soundings": self.grid.soundings}

    def replay(self) -> dict | None:
        """Everything, for a page that connects now."""
        with self._lock:
            if not len(self.grid):
                return None
            keys = sorted(self.grid._cells)
            return {"type": "coverage", "cell_m": self.grid.cell_m, "cells": self._cells(keys), "reset": True,
                    "survey": self._summary, "soundings": self.grid.soundings}

    def rerun_route(self) -> dict:
        """A route over the holes of the held survey (the survey's harbour, area and obstacles; its
        speed, turnaround and margin); LotsenError when there is no survey or no hole."""
        with self._lock:
            route = self.route
            if route is None or route.survey.polygon is None:
                raise ConfigError("re-run: the boat holds no survey with a polygon (upload a survey first)")
            cov = coverage(self.grid, route.survey.polygon)
        safe = route.free_region().buffer(-(route.survey.margin_m + 1e-3))
        pattern = rerun_pattern(cov, route.survey, safe, (route.harbour.north_m, route.harbour.east_m))
        if pattern is None:
            raise ConfigError(f"re-run: no holes: {len(cov.covered)} of {len(cov.cells)} cells have soundings")
        from lotsen.planning.survey import pattern_to_dict

        out = route_to_dict(replace(route, survey=None, survey_lines=(), nodes=()))
        out.pop("nodes", None)
        out["survey"] = pattern_to_dict(pattern)
        return out
