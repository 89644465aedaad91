"""The one angle wrap, the one finite check (floats and numpy arrays alike) and the one lever arm
rotation of the project (a body velocity turned onto the map with it: `ground_velocity`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle(a: Any) -> Any:
    """Angle wrapped to [-pi, pi): a float for a float, an array for an array."""
    if isinstance(a, (float, int)):
        return (a + math.pi) % TWO_PI - math.pi
    return np.mod(np.asarray(a, dtype=float) + np.pi, TWO_PI) - np.pi


def all_finite(*values: Any) -> bool:
    """True when every value (numbers or arrays of numbers) is finite."""
    for v in values:
        if isinstance(v, (float, int)):
            if not math.isfinite(v):
                return False
        elif not np.all(np.isfinite(np.asarray(v, dtype=float))):
            return False
    return True


def lever_arm_ne(heading_rad: float, arm_m: tuple[float, float]) -> tuple[float, float]:
    """A point fixed on the hull at body (x, y) = `arm_m` from the model's origin, seen from that
    origin in north/east at `heading_rad` (R(psi) of seed eq. 7-8 applied to the arm). Its derivative
    by heading is (-east, north), and with yaw rate r its velocity relative to the origin is
    r (-east, north)."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    ax, ay = arm_m
    return c * ax - s * ay, s * ax + c * ay


def ground_velocity(u_mps: float, v_mps: float, heading_rad: float) -> tuple[float, float]:
    """Body velocities (surge, sway) as north / east over ground: R(psi) of seed eq. 7-8, the rotation of
    `lever_arm_ne`. (lotsen.web.mavlink.mapping keeps its own three lines: web may not import model,
    docs/architecture.md.)"""
    return lever_arm_ne(heading_rad, (u_mps, v_mps))


def mast_swing_body(height_m: float, roll_rad: float, pitch_rad: float) -> tuple[float, float]:
    """How far roll and pitch carry a point `height_m` above the roll and pitch centre, in the body's
    horizontal axes: (-h cos(roll) sin(pitch), h sin(roll)) (ZYX Euler angles; an antenna on a mast
    moves aft when the bow rises, to starboard when the boat rolls to starboard). Its velocity for
    small angles: (-h q, h p) with p, q the body rates about x and y. In north/east:
    `lever_arm_ne(heading, mast_swing_body(...))`."""
    return -height_m * math.cos(roll_rad) * math.sin(pitch_rad), height_m * math.sin(roll_rad)
