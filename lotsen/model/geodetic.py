"""The one geodetic frame: WGS84 latitude/longitude/height <-> local north/east/down at an origin.

`LocalFrame` converts both ways, exactly (through Earth-centred coordinates, no flat-Earth
approximation), so a position the simulated receiver reports and the estimator places again
comes back within micrometres. `FixFrame` is the one origin resolution for a stream of fixes:
the configured origin, else the first usable fix (the estimators, the identification export).
Which origin a run configures is decided once by the stack (`lotsen.stack.stack.resolve_origin`).

Equations: geodetic -> ECEF with the prime vertical radius N(phi) = a / sqrt(1 - e^2 sin^2 phi),
ECEF difference rotated into NED at the origin; back by the inverse rotation and Bowring's
iteration for the latitude (converged to < 1e-12 rad in a few steps near the Earth's surface).
"""

from __future__ import annotations

import math

from lotsen.model.angles import all_finite

#: WGS84 ellipsoid
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)


def geodetic_to_ecef(lat_deg: float, lon_deg: float, height_m: float) -> tuple[float, float, float]:
    phi, lam = math.radians(lat_deg), math.radians(lon_deg)
    s, c = math.sin(phi), math.cos(phi)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
    return ((n + height_m) * c * math.cos(lam), (n + height_m) * c * math.sin(lam),
            (n * (1.0 - WGS84_E2) + height_m) * s)


def ecef_to_geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    lam = math.atan2(y, x)
    p = math.hypot(x, y)
    phi = math.atan2(z, p * (1.0 - WGS84_E2))
    n = WGS84_A_M
    for _ in range(8):
        s = math.sin(phi)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
        nxt = math.atan2(z + WGS84_E2 * n * s, p)
        if abs(nxt - phi) < 1e-14:
            phi = nxt
            break
        phi = nxt
    s, c = math.sin(phi), math.cos(phi)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * s * s)
    # height along the normal; the form that stays accurate at any latitude
    h = p * c + z * s - WGS84_A_M * WGS84_A_M / n
    return math.degrees(phi), math.degrees(lam), h


class LocalFrame:
    """WGS84 geodetic <-> local north/east/down (NED) at a fixed origin."""

    def __init__(self, lat0_deg: float, lon0_deg: float, h0_m: float = 0.0) -> None:
        if not all_finite(lat0_deg, lon0_deg, h0_m) or not -90.0 <= lat0_deg <= 90.0:
            raise ValueError(f"local frame origin must be a finite position on the Earth, got "
                             f"{(lat0_deg, lon0_deg, h0_m)}")
        self.origin = (float(lat0_deg), float(lon0_deg), float(h0_m))
        self._ecef0 = geodetic_to_ecef(*self.origin)
        phi, lam = math.radians(lat0_deg), math.radians(lon0_deg)
        self._sp, self._cp, self._sl, self._cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)

    def __repr__(self) -> str:
        return f"LocalFrame(lat0_deg={self.origin[0]!r}, lon0_deg={self.origin[1]!r}, h0_m={self.origin[2]!r})"

    def to_ned(self, lat_deg: float, lon_deg: float, height_m: float) -> tuple[float, float, float]:
        x, y, z = geodetic_to_ecef(lat_deg, lon_deg, height_m)
        dx, dy, dz = x - self._ecef0[0], y - self._ecef0[1], z - self._ecef0[2]
        sp, cp, sl, cl = self._sp, self._cp, self._sl, self._cl
        t = cl * dx + sl * dy
        return (-sp * t + cp * dz, -sl * dx + cl * dy, -(cp * t + sp * dz))

    def to_ne(self, lat_deg: float, lon_deg: float, height_m: float | None = None) -> tuple[float, float]:
        """North and east of a position; a missing or non-finite height is taken as the origin's."""
        h = self.origin[2] if height_m is None or not math.isfinite(height_m) else height_m
        n, e, _ = self.to_ned(lat_deg, lon_deg, h)
        return n, e

    def to_geodetic(self, north_m: float, east_m: float, down_m: float = 0.0) -> tuple[float, float, float]:
        """Latitude (deg), longitude (deg) and height (m) of a local position."""
        sp, cp, sl, cl = self._sp, self._cp, self._sl, self._cl
        t = -sp * north_m - cp * down_m
        dx, dy, dz = cl * t - sl * east_m, sl * t + cl * east_m, cp * north_m - sp * down_m
        return ecef_to_geodetic(self._ecef0[0] + dx, self._ecef0[1] + dy, self._ecef0[2] + dz)

    @classmethod
    def at_fix(cls, lat_deg: float, lon_deg: float, height_m: float) -> "LocalFrame":
        """The frame with its origin at a fix (a fix without a height: height 0)."""
        return cls(lat_deg, lon_deg, height_m if math.isfinite(height_m) else 0.0)


class FixFrame:
    """The local frame a stream of fixes is placed in: at `origin` (lat, lon, h) when one is
    configured, else at the first fix placed (the caller passes usable fixes only)."""

    def __init__(self, origin: tuple[float, float, float] | None = None) -> None:
        self.frame: LocalFrame | None = LocalFrame(*origin) if origin else None

    @property
    def origin(self) -> tuple[float, float, float] | None:
        return self.frame.origin if self.frame is not None else None

    def to_ne(self, lat_deg: float, lon_deg: float, height_m: float | None = None) -> tuple[float, float]:
        if self.frame is None:
            self.frame = LocalFrame.at_fix(lat_deg, lon_deg, math.nan if height_m is None else height_m)
        return self.frame.to_ne(lat_deg, lon_deg, height_m)
