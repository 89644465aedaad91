"""Depth from the echosounder: soundings placed where the transducer was at each ping, a gridded
depth map (cell mean, count, spread), its coverage of a survey polygon, the holes left and a re-run
route over them, and the map's exports (CSV, GeoJSON). Pure: no I/O, threads or clock.

    from lotsen.bathymetry import SoundingMaker, DepthGrid, coverage, rerun_pattern
"""

from lotsen.bathymetry.coverage import Coverage, coverage, rerun_pattern
from lotsen.bathymetry.grid import DepthGrid
from lotsen.bathymetry.soundings import SoundingMaker

__all__ = ["Coverage", "DepthGrid", "SoundingMaker", "coverage", "rerun_pattern"]
