"""The project's one angle wrap and one finite check (lotsen.model.angles)."""

import math

import numpy as np
import pytest

from lotsen.model import all_finite, wrap_angle


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
