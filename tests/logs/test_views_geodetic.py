"""The recorder's estimate-on-the-map view converts every estimate to latitude / longitude; its
scalar conversion must give pymap3d's bits exactly (the recorded view is unchanged)."""

import math
import random

import pymap3d
import pytest

from lotsen.logs.foxglove_views import NedToGeodetic


@pytest.mark.parametrize("origin", [(57.69, 11.97, 10.0), (0.0, 0.0, 0.0), (-33.9, 151.2, 50.0),
                                    (31.5, 35.5, -430.0), (89.99, 10.0, 0.0), (-60.0, -170.0, 3000.0)])
def test_the_scalar_conversion_gives_pymap3d_bits(origin):
    rng = random.Random(7)
    convert = NedToGeodetic(*origin)
    points = [(rng.uniform(-5000, 5000), rng.uniform(-5000, 5000)) for _ in range(300)]
    points += [(rng.uniform(-5, 5), rng.uniform(-5, 5)) for _ in range(100)] + [(0.0, 0.0), (-0.0, 1e-9)]
    for north, east in points:
        expected = tuple(float(v) for v in pymap3d.ned2geodetic(north, east, 0.0, *origin))
        assert convert(north, east) == expected, (north, east)


def test_special_points_take_pymap3d_itself():
    assert all(math.isnan(v) for v in NedToGeodetic(57.69, 11.97, 10.0)(float("nan"), 1.0))
    pole = NedToGeodetic(90.0, 0.0, 0.0)  # on the Earth's axis: pymap3d's own branch
    assert pole(0.0, 0.0) == tuple(float(v) for v in pymap3d.ned2geodetic(0.0, 0.0, 0.0, 90.0, 0.0, 0.0))
