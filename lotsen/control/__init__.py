"""Control (seed section 3.5): path-following MPC on OSQP, fallbacks, station keeping, thrust allocation.

Public API::

    from lotsen.control import (ControlConfig, make_path_follower, MPCController, MPCConfig,
        PurePursuitController, LOSController, LQController, StationKeepingController,
        ThrustAllocator, PathFollower, StationKeeper, HoldTarget)

    follower = make_path_follower(ControlConfig(controller="mpc"))
    follower.reset(path)                                  # a lotsen.planning.Path
    command, status = follower.update(t, vessel_state)    # ThrustCommand, ControllerStatus
"""

from __future__ import annotations

from dataclasses import dataclass, field

from lotsen.control.allocation import AllocationConfig, AllocationResult, ThrustAllocator, rate_limit
from lotsen.control.base import HoldTarget, PathFollower, PathReference, StationKeeper, wrap_angle
from lotsen.control.fallback import (
    LOSConfig, LOSController, LQConfig, LQController, PursuitConfig, PurePursuitController,
    SpeedPIDConfig,
)
from lotsen.control.mpc import MPCConfig, MPCController
from lotsen.control.station_keeping import StationKeepingConfig, StationKeepingController
from lotsen.errors import ConfigError
from lotsen.model.dynamics import VesselModel
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits

CONTROLLERS = ("mpc", "pursuit", "los", "lq")


@dataclass(frozen=True)
class ControlConfig:
    """Which path follower runs, and the settings of each (the fallbacks are selectable here)."""

    controller: str = "mpc"
    mpc: MPCConfig = field(default_factory=MPCConfig)
    pursuit: PursuitConfig = field(default_factory=PursuitConfig)
    los: LOSConfig = field(default_factory=LOSConfig)
    lq: LQConfig = field(default_factory=LQConfig)
    station_keeping: StationKeepingConfig = field(default_factory=StationKeepingConfig)

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise ConfigError(f"control.controller: {self.controller!r} is not one of {', '.join(CONTROLLERS)}")

    @property
    def dt_s(self) -> float:
        return {"mpc": self.mpc.dt_s, "pursuit": self.pursuit.dt_s, "los": self.los.dt_s,
                "lq": self.lq.dt_s}[self.controller]


def make_path_follower(config: ControlConfig = ControlConfig(), model: VesselModel | None = None,
                       limits: ActuatorLimits = DEFAULT_LIMITS) -> PathFollower:
    """The path follower named by `config.controller`."""
    model = model or VesselModel()
    if config.controller == "mpc":
        return MPCController(model, limits, config.mpc)
    if config.controller == "pursuit":
        return PurePursuitController(model, limits, config.pursuit)
    if config.controller == "los":
        return LOSController(model, limits, config.los)
    return LQController(model, limits, config.lq)


def make_station_keeper(config: ControlConfig = ControlConfig(), model: VesselModel | None = None,
                        limits: ActuatorLimits = DEFAULT_LIMITS) -> StationKeepingController:
    return StationKeepingController(model or VesselModel(), limits, config.station_keeping)


__all__ = [
    "AllocationConfig", "AllocationResult", "CONTROLLERS", "ControlConfig", "HoldTarget", "LOSConfig",
    "LOSController", "LQConfig", "LQController", "MPCConfig", "MPCController", "PathFollower",
    "PathReference", "PursuitConfig", "PurePursuitController", "SpeedPIDConfig", "StationKeeper",
    "StationKeepingConfig", "StationKeepingController", "ThrustAllocator", "make_path_follower",
    "make_station_keeper", "rate_limit", "wrap_angle",
]
