"""A gridded depth map: square cells of `cell_m` aligned on multiples of it in the local frame; per
cell the number of soundings, their mean and their spread (standard deviation, Welford's update,
so one pass and no list of soundings is kept).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class _Cell:
    count: int = 0
    mean: float = 0.0
    m2: float = 0.0


class DepthGrid:
    def __init__(self, cell_m: float = 1.0) -> None:
        if not 0.05 <= cell_m <= 100.0:
            raise ValueError(f"depth map cell {cell_m:g} m: allowed 0.05 to 100 m")
        self.cell_m = cell_m
        self._cells: dict[tuple[int, int], _Cell] = {}
        self.soundings = 0

    def key(self, north_m: float, east_m: float) -> tuple[int, int]:
        return (math.floor(north_m / self.cell_m), math.floor(east_m / self.cell_m))

    def centre(self, key: tuple[int, int]) -> tuple[float, float]:
        return ((key[0] + 0.5) * self.cell_m, (key[1] + 0.5) * self.cell_m)

    def add(self, north_m: float, east_m: float, depth_m: float) -> tuple[int, int] | None:
        if not (math.isfinite(north_m) and math.isfinite(east_m) and math.isfinite(depth_m)):
            return None
        k = self.key(north_m, east_m)
        c = self._cells.get(k)
        if c is None:
            c = self._cells[k] = _Cell()
        c.count += 1
        delta = depth_m - c.mean
        c.mean += delta / c.count
        c.m2 += delta * (depth_m - c.mean)
        self.soundings += 1
        return k

    def __len__(self) -> int:
        return len(self._cells)

    def count(self, key: tuple[int, int]) -> int:
        c = self._cells.get(key)
        return c.count if c else 0

    def cell(self, key: tuple[int, int]) -> tuple[int, float, float] | None:
        """(count, mean depth, spread) of a cell; None when it has no sounding."""
        c = self._cells.get(key)
        if c is None:
            return None
        return c.count, c.mean, math.sqrt(c.m2 / (c.count - 1)) if c.count > 1 else math.nan

    def table(self) -> dict[str, np.ndarray]:
        """Every cell with soundings, sorted north then east: centre north/east, count, mean, spread."""
        keys = sorted(self._cells)
        cells = [self.cell(k) for k in keys]
        return {"north_m": np.array([self.centre(k)[0] for k in keys]),
                "east_m": np.array([self.centre(k)[1] for k in keys]),
                "count": np.array([c[0] for c in cells], dtype=int),  # type: ignore[index]
                "depth_m": np.array([c[1] for c in cells]),  # type: ignore[index]
                "spread_m": np.array([c[2] for c in cells]),  # type: ignore[index]
                "i": np.array([k[0] for k in keys], dtype=int), "j": np.array([k[1] for k in keys], dtype=int)}
