"""The one geodetic frame: WGS84 <-> local NED both ways, and one origin resolution for fixes."""

import math

import numpy as np
import pytest

from lotsen.messages import GnssFix, GnssFixType
from lotsen.model.geodetic import FixFrame, LocalFrame
from lotsen.sim.sensors import GnssConfig, GnssModel

ORIGINS = [(57.6905, 11.976, 10.0), (-33.86, 151.21, 0.0), (0.0, -179.999, 120.0), (78.2, 15.6, -20.0)]


@pytest.mark.parametrize("origin", ORIGINS)
def test_round_trip_geodetic_ned_geodetic_within_a_millimetre_at_a_kilometre(origin):
    frame = LocalFrame(*origin)
    rng = np.random.default_rng(1)
    worst_m = 0.0
    for north, east in [(1000.0, 0.0), (0.0, 1000.0), (-707.1, 707.1), *rng.uniform(-1000, 1000, (50, 2))]:
        lat, lon, h = frame.to_geodetic(north, east)
        n, e, d = frame.to_ned(lat, lon, h)
        worst_m = max(worst_m, abs(n - north), abs(e - east), abs(d))
        # and back to the same geodetic position (1 mm is ~1e-8 deg)
        lat2, lon2, h2 = frame.to_geodetic(n, e, d)
        assert abs(lat2 - lat) < 1e-8 and abs(lon2 - lon) < 1e-8 and abs(h2 - h) < 1e-3
    assert worst_m < 1e-3


def test_the_frame_agrees_with_an_independent_implementation():
    pymap3d = pytest.importorskip("pymap3d")
    frame = LocalFrame(*ORIGINS[0])
    for north, east, down in [(1000.0, -500.0, 2.0), (-250.0, 800.0, -3.0)]:
        lat, lon, h = frame.to_geodetic(north, east, down)
        ref = pymap3d.ned2geodetic(north, east, down, *ORIGINS[0])
        assert np.allclose((lat, lon), ref[:2], atol=1e-9) and abs(h - ref[2]) < 1e-6
        assert np.allclose(frame.to_ned(*ref), (north, east, down), atol=1e-6)
    # a kilometre north is ~0.009 deg of latitude, and the tangent plane is ~7.8 cm above the ellipsoid there
    lat, lon, h = frame.to_geodetic(1000.0, 0.0)
    assert 0.0089 < lat - ORIGINS[0][0] < 0.0091 and abs(lon - ORIGINS[0][1]) < 1e-9 and 0.07 < h - ORIGINS[0][2] < 0.09


def test_to_ne_takes_the_origin_height_when_a_fix_has_none():
    frame = LocalFrame(*ORIGINS[0])
    lat, lon, _ = frame.to_geodetic(30.0, -40.0)
    for h in (None, math.nan):
        n, e = frame.to_ne(lat, lon, h)
        assert abs(n - 30.0) < 1e-6 and abs(e + 40.0) < 1e-6


def test_a_bad_origin_is_refused():
    for bad in [(math.nan, 11.0, 0.0), (91.0, 0.0, 0.0), (57.0, math.inf, 0.0)]:
        with pytest.raises(ValueError, match="origin"):
            LocalFrame(*bad)


def test_the_origin_is_resolved_once_configured_else_at_the_first_fix():
    configured = FixFrame(ORIGINS[0])
    assert configured.origin == ORIGINS[0]
    first = FixFrame()
    assert first.origin is None
    here = LocalFrame(*ORIGINS[0]).to_geodetic(100.0, 50.0)
    there = LocalFrame(*ORIGINS[0]).to_geodetic(110.0, 20.0)
    assert first.to_ne(*here) == (0.0, 0.0)  # the first fix is the origin ...
    assert first.origin == pytest.approx(here)
    frame = first.frame
    n, e = first.to_ne(*there)  # ... and stays it: later fixes are placed in that frame
    assert first.frame is frame and n == pytest.approx(10.0, abs=1e-3) and e == pytest.approx(-30.0, abs=1e-3)
    # a configured origin is never moved by a fix
    assert configured.to_ne(*here) == pytest.approx((100.0, 50.0), abs=1e-6) and configured.origin == ORIGINS[0]
    # a first fix without height: the origin at height 0
    assert FixFrame().to_ne(57.7, 11.98, math.nan) == (0.0, 0.0)


def test_the_simulated_receiver_and_the_estimator_share_the_frame():
    """A noise-free simulated fix 1 km out is placed back where the boat is, to well under a mm."""
    config = GnssConfig(noise_m={GnssFixType.RTK_FIXED: 0.0}, bias_walk_m_sqrt_s={GnssFixType.RTK_FIXED: 0.0},
                        velocity_noise_mps=0.0)
    gnss = GnssModel(config, np.random.default_rng(0))
    fix = gnss.sample(1.0, 800.0, -600.0, 0.0, 0.0, 0.125)
    assert isinstance(fix, GnssFix)
    frame = FixFrame((config.origin_lat_deg, config.origin_lon_deg, config.origin_height_m))
    n, e = frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m)
    assert abs(n - 800.0) < 1e-4 and abs(e + 600.0) < 1e-4
