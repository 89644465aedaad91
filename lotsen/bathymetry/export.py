"""The depth map as files a GIS reads: CSV (a row per cell) and GeoJSON (a square per cell with its
depth, count and spread; the holes as polygons), in WGS84 from the run's geographic origin."""

from __future__ import annotations

import io
import math
from typing import Any

from lotsen.bathymetry.coverage import Coverage
from lotsen.bathymetry.grid import DepthGrid
from lotsen.model.geodetic import LocalFrame


def _num(x: float, digits: int = 3) -> float | None:
    return round(float(x), digits) if math.isfinite(x) else None


def depth_csv(grid: DepthGrid, frame: LocalFrame | None = None) -> str:
    """`north_m,east_m[,lat_deg,lon_deg],depth_m,count,spread_m`: cell centres, mean depth below the
    surface, soundings, their standard deviation (empty for a single sounding)."""
    t = grid.table()
    out = io.StringIO()
    out.write("north_m,east_m," + ("lat_deg,lon_deg," if frame else "") + "depth_m,count,spread_m\n")
    for n, e, d, c, s in zip(t["north_m"], t["east_m"], t["depth_m"], t["count"], t["spread_m"]):
        ll = ""
        if frame is not None:
            lat, lon, _ = frame.to_geodetic(n, e)
            ll = f"{lat:.8f},{lon:.8f},"
        out.write(f"{n:.3f},{e:.3f},{ll}{d:.3f},{c},{'' if not math.isfinite(s) else f'{s:.3f}'}\n")
    return out.getvalue()


def depth_geojson(grid: DepthGrid, frame: LocalFrame, cov: Coverage | None = None) -> dict[str, Any]:
    """FeatureCollection (RFC 7946, [lon, lat]): each cell a Polygon with depth_m, count, spread_m;
    each hole a Polygon with role "hole"; the cell size and origin as foreign members."""
    def ring(pts: list[tuple[float, float]]) -> list[list[float]]:
        out = []
        for n, e in pts + pts[:1]:
            lat, lon, _ = frame.to_geodetic(n, e)
            out.append([round(lon, 9), round(lat, 9)])
        return [out]

    c = grid.cell_m
    t = grid.table()
    feats = []
    for i, j, d, cnt, s in zip(t["i"], t["j"], t["depth_m"], t["count"], t["spread_m"]):
        corners = [(i * c, j * c), ((i + 1) * c, j * c), ((i + 1) * c, (j + 1) * c), (i * c, (j + 1) * c)]
        feats.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": ring(corners)},
                      "properties": {"role": "cell", "depth_m": _num(d), "count": int(cnt), "spread_m": _num(s)}})
    for h in (cov.holes if cov else ()):
        feats.append({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": ring(list(h))},
                      "properties": {"role": "hole"}})
    doc: dict[str, Any] = {"type": "FeatureCollection", "features": feats, "lotsen_cell_m": c,
                           "lotsen_origin": {"lat_deg": frame.origin[0], "lon_deg": frame.origin[1]}}
    if cov is not None:
        doc["lotsen_coverage"] = {"cells": len(cov.cells), "covered": len(cov.covered), "holes": len(cov.hole_cells)}
    return doc
