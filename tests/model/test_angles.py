"""The project's one angle wrap, one finite check and one lever arm (lotsen.model.angles)."""

import math

import numpy as np
import pytest

from lotsen.model import all_finite, wrap_angle
from lotsen.model.angles import lever_arm_ne


def test_wrap_angle_range_and_equivalence_for_arrays_and_floats():
    a = np.array([-np.pi, np.pi, 3 * np.pi, -3.5 * np.pi, 0.1, 1e6])
    w = wrap_angle(a)
    assert np.all(w >= -np.pi) and np.all(w < np.pi)
    assert np.allclose(np.cos(w), np.cos(a)) and np.allclose(np.sin(w), np.sin(a))
    for x in a:
        y = wrap_angle(float(x))
        assert isinstance(y, float) and -math.pi <= y < math.pi and math.isclose(math.cos(y), math.cos(x), abs_tol=1e-9)


@pytest.mark.parametrize("values, finite", [
    ((1.0, np.zeros(3)), True),
    ((-0.0, 5), True),
    ((1.0, float("nan")), False),
    ((np.array([0.0, np.inf]),), False),
])
def test_all_finite(values, finite):
    assert all_finite(*values) is finite


def test_lever_arm_turns_with_the_heading_and_its_derivative_is_minus_east_north():
    arm = (0.05, -0.02)
    assert lever_arm_ne(0.0, arm) == arm
    dn, de = lever_arm_ne(math.pi / 2, arm)  # bow east: body x points east, body y south
    assert math.isclose(dn, 0.02, abs_tol=1e-12) and math.isclose(de, 0.05, abs_tol=1e-12)
    psi, h = 0.7, 1e-6
    n1, e1 = lever_arm_ne(psi + h, arm)
    n0, e0 = lever_arm_ne(psi - h, arm)
    dn, de = lever_arm_ne(psi, arm)
    assert math.isclose((n1 - n0) / (2 * h), -de, rel_tol=1e-6)
    assert math.isclose((e1 - e0) / (2 * h), dn, rel_tol=1e-6)
    assert math.isclose(math.hypot(dn, de), math.hypot(*arm))
