"""Sensor fusion (seed section 3.3 and beyond): magnetometer calibration, the seed's yaw and
velocity Kalman filters, and a model-aided EKF. Pure: time comes only from message stamps."""

from lotsen.fusion.common import Counters, GnssNoise, wrap_angle
from lotsen.model.geodetic import LocalFrame
from lotsen.fusion.ekf import EkfConfig, ModelAidedEKF
from lotsen.fusion.magcal import (
    CalibrationError, CalibrationLimits, MagCalibration, calibrated_heading, fit_mag_calibration,
)
from lotsen.fusion.seed_filters import (
    SeedFilters, SeedFiltersConfig, VelocityFilterConfig, VelocityKalmanFilter, YawFilterConfig,
    YawKalmanFilter,
)

__all__ = [
    "Counters", "GnssNoise", "LocalFrame", "wrap_angle", "EkfConfig", "ModelAidedEKF", "CalibrationError",
    "CalibrationLimits", "MagCalibration", "calibrated_heading", "fit_mag_calibration", "SeedFilters",
    "SeedFiltersConfig", "VelocityFilterConfig", "VelocityKalmanFilter", "YawFilterConfig", "YawKalmanFilter",
]
