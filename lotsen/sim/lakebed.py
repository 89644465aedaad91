"""The simulated lake's bed and the echosounder that sees it.

`LakeBed`: depths below the water surface on a regular grid (the launch config's `sim.lakebed`),
bilinear between the grid points; outside the grid the nearest edge value (the lake goes on as it
ends). `SounderModel`: a single-beam sounder at the transducer (body x forward, y starboard of the
hull's origin, `draft_m` below the surface) pinging at `rate_hz`; each ping is the bed's depth under
the transducer less the draft, with Gaussian noise, dropouts (no bottom found: depth NaN, as the
sounder's empty NMEA field) and nothing beyond its range. Pure: the random stream is its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lotsen.messages import DepthSample
from lotsen.model.angles import lever_arm_ne


@dataclass(frozen=True)
class LakeBed:
    """Depths (m, positive down) at grid points `origin_m` + (i, j) * `cell_m`, row i north, column j east."""

    depths_m: tuple[tuple[float, ...], ...]
    origin_m: tuple[float, float] = (0.0, 0.0)
    cell_m: float = 5.0
    _grid: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        grid = np.asarray(self.depths_m, dtype=float)
        if grid.ndim != 2 or grid.shape[0] < 2 or grid.shape[1] < 2:
            raise ValueError(f"sim.lakebed.depths_m: expected rows of equal length, at least 2 x 2, got shape {grid.shape}")
        if not np.all(np.isfinite(grid)) or grid.min() < 0:
            raise ValueError("sim.lakebed.depths_m: depths are finite and not negative (metres below the surface)")
        object.__setattr__(self, "_grid", grid)

    @property
    def grid(self) -> np.ndarray:
        return self._grid

    def depth_at(self, north_m: float | np.ndarray, east_m: float | np.ndarray) -> float | np.ndarray:
        """The bed's depth below the surface at (north, east), bilinear, clamped to the grid's edge."""
        g = self._grid
        i = np.clip((np.asarray(north_m, float) - self.origin_m[0]) / self.cell_m, 0.0, g.shape[0] - 1.0)
        j = np.clip((np.asarray(east_m, float) - self.origin_m[1]) / self.cell_m, 0.0, g.shape[1] - 1.0)
        i0 = np.minimum(np.floor(i).astype(int), g.shape[0] - 2)
        j0 = np.minimum(np.floor(j).astype(int), g.shape[1] - 2)
        a, b = i - i0, j - j0
        d = ((1 - a) * (1 - b) * g[i0, j0] + a * (1 - b) * g[i0 + 1, j0]
             + (1 - a) * b * g[i0, j0 + 1] + a * b * g[i0 + 1, j0 + 1])
        return float(d) if np.ndim(d) == 0 else d


@dataclass(frozen=True)
class SounderConfig:
    rate_hz: float = 5.0
    noise_std_m: float = 0.02          # a 200 kHz single beam's depth noise on a soft bed
    dropout_probability: float = 0.02  # pings without a bottom
    max_range_m: float = 50.0
    transducer_m: tuple[float, float] = (0.0, 0.0)   # body x forward, y starboard of the hull's origin
    draft_m: float = 0.1               # transducer face below the surface


class SounderModel:
    """Pings of a sounder over `bed` (see the module docstring)."""

    def __init__(self, config: SounderConfig, bed: LakeBed, rng: np.random.Generator) -> None:
        self.config = config
        self.bed = bed
        self.rng = rng

    def sample(self, t: float, north_m: float, east_m: float, psi_rad: float) -> DepthSample:
        c = self.config
        dn, de = lever_arm_ne(psi_rad, c.transducer_m)
        below = float(self.bed.depth_at(north_m + dn, east_m + de)) - c.draft_m
        noise = float(self.rng.normal(0.0, c.noise_std_m)) if c.noise_std_m > 0 else 0.0
        dropout = float(self.rng.random()) < c.dropout_probability
        depth = below + noise
        if dropout or not 0.0 < depth <= c.max_range_m:
            depth = math.nan
        return DepthSample(stamp_s=t, depth_m=depth, offset_m=c.draft_m)


def sounder_rng(seed: int) -> np.random.Generator:
    """The sounder's own random stream (the simulator's other streams stay as they were)."""
    return np.random.default_rng(np.random.SeedSequence([seed, 0x5D]))
