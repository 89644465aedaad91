"""The one angle wrap and the one finite check of the project (floats and numpy arrays alike)."""

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
