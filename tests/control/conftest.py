"""Small path fixtures with the attributes of lotsen.planning.Path (built with the real class)."""

from __future__ import annotations

import numpy as np
import pytest

from lotsen.planning import Path


def straight_path(length_m: float = 25.0, speed_mps: float = 0.5, heading_rad: float = 0.0) -> Path:
    s = np.arange(0.0, length_m + 1e-9, 0.01)
    return Path(north_m=s * np.cos(heading_rad), east_m=s * np.sin(heading_rad),
                heading_rad=np.full_like(s, heading_rad), curvature_1pm=np.zeros_like(s),
                speed_mps=np.full_like(s, speed_mps), s_m=s)


def circle_path(radius_m: float = 4.0, angle_rad: float = 1.5 * np.pi, speed_mps: float = 0.5,
                lead_in_m: float = 3.0) -> Path:
    """Straight lead-in heading north, then a starboard turn (curvature +1/R)."""
    s1 = np.arange(0.0, lead_in_m, 0.01)
    s2 = np.arange(0.0, radius_m * angle_rad + 1e-9, 0.01)
    th = s2 / radius_m
    north = np.concatenate([s1, lead_in_m + radius_m * np.sin(th)])
    east = np.concatenate([np.zeros_like(s1), radius_m * (1.0 - np.cos(th))])
    heading = np.concatenate([np.zeros_like(s1), th])
    kappa = np.concatenate([np.zeros_like(s1), np.full_like(s2, 1.0 / radius_m)])
    s = np.concatenate([s1, lead_in_m + s2])
    return Path(north_m=north, east_m=east, heading_rad=heading, curvature_1pm=kappa,
                speed_mps=np.full_like(s, speed_mps), s_m=s)


@pytest.fixture
def straight() -> Path:
    return straight_path()


@pytest.fixture
def circle() -> Path:
    return circle_path()
