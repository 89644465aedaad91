"""System identification of the vessel model (seed section 3.2): experiments, grey-box
estimation (single / multiple shooting), Fisher information and identifiability, validation,
a black-box peer and experiment design. See docs/sysid.md."""

from lotsen.sysid.data import IdRecord, Segment, load_csv, load_record, register_loader, save_csv, split_segments
from lotsen.sysid.estimate import (
    DEFAULT_NOISE_STD, SCALE_GROUP, EstimationError, IdentifiabilityError, IdentificationResult, estimate,
)
from lotsen.sysid.experiment import (
    Area, Experiment, InputGenerator, check_experiment, load_experiment, parse_experiment, predict_trajectory,
)

__all__ = [
    "IdRecord", "Segment", "load_csv", "load_record", "register_loader", "save_csv", "split_segments",
    "DEFAULT_NOISE_STD", "SCALE_GROUP", "EstimationError", "IdentifiabilityError", "IdentificationResult",
    "estimate", "Area", "Experiment", "InputGenerator", "check_experiment", "load_experiment",
    "parse_experiment", "predict_trajectory",
]
