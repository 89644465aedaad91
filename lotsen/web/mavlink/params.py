"""The MAVLink parameter table: names of at most 16 characters, every value a float (REAL32).

Writable: the planner limits the page may change (the same rule: lower only / raise only, lotsen.web
.settings; a change reaches every page) and WP_SPEED, the speed of an uploaded mission's waypoints
before its first DO_CHANGE_SPEED. Read-only: the model in use (MDL_*, model/in_use's coefficients),
the failsafes' key thresholds (FS_*), the controller and the endpoint's own identity. A write to a
read-only parameter is answered with its unchanged value and a STATUSTEXT saying why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

#: MAVLink name -> the page's setting (lotsen.web.settings.EDITABLE_NAMES)
PLANNER = {"PLN_SPEED_MAX": "planner.speed_max_mps", "PLN_ACC_LONG": "planner.a_long_max_mps2",
           "PLN_ACC_LAT": "planner.a_lat_max_mps2", "PLN_CLEARANCE": "planner.clearance_m"}
WP_SPEED = "WP_SPEED"
#: read-only failsafe thresholds: MAVLink name -> FailsafeConfig field
FAILSAFES = {"FS_LINK_TMO": "link_timeout_s", "FS_MANUAL_TMO": "manual_timeout_s", "FS_GNSS_LOST": "gnss_lost_s",
             "FS_BATT_LOW_V": "battery_low_v", "FS_BATT_CRT_V": "battery_critical_v",
             "FS_FENCE_MARGIN": "geofence_margin_m", "FS_POS_STD_MAX": "max_position_std_m"}
CONTROLLERS = ("mpc", "pursuit", "los", "lq")
MAX_NAME = 16


@dataclass(frozen=True)
class Param:
    name: str
    get: Callable[[], float]
    writable: bool = False
    doc: str = ""


def model_name(key: str) -> str:
    """MDL_<coefficient> within 16 characters (m11 -> MDL_M11, kappa -> MDL_KAPPA)."""
    return f"MDL_{key.upper()}"[:MAX_NAME]


class ParameterTable:
    """The names in a fixed order (the index a ground station asks by) and their current values."""

    def __init__(self, planner_value: Callable[[str], float], model_parameters: dict[str, float],
                 failsafes: Any, controller: str, control_rate_hz: float, command_deadline_s: float,
                 gcs_timeout_s: float, system_id: int, wp_speed: Callable[[], float]) -> None:
        params: list[Param] = [Param(WP_SPEED, wp_speed, True, "waypoint speed before a mission's first "
                                                                 "DO_CHANGE_SPEED (m/s)")]
        params += [Param(n, (lambda k=k: planner_value(k)), True, k) for n, k in PLANNER.items()]
        params += [Param(model_name(k), (lambda v=float(v): v), doc=f"model coefficient {k}")
                   for k, v in sorted(model_parameters.items()) if isinstance(v, (int, float))]
        params += [Param(n, (lambda f=f: float(getattr(failsafes, f))), doc=f"extra.failsafes.{f}")
                   for n, f in FAILSAFES.items()]
        params += [Param("FS_GCS_TMO", lambda: float(gcs_timeout_s), doc="extra.mavlink.gcs_timeout_s"),
                   Param("CTRL_TYPE", lambda: float(CONTROLLERS.index(controller) if controller in CONTROLLERS else -1),
                         doc="nodes.controller: 0 mpc, 1 pursuit, 2 los, 3 lq"),
                   Param("CTRL_RATE_HZ", lambda: float(control_rate_hz), doc="nodes.control_rate_hz"),
                   Param("CTRL_DEADLINE", lambda: float(command_deadline_s), doc="nodes.command_deadline_s"),
                   Param("SYSID_THISMAV", lambda: float(system_id), doc="extra.mavlink.system_id")]
        assert all(len(p.name) <= MAX_NAME for p in params)
        self.params = params
        self.by_name = {p.name: p for p in params}

    def __len__(self) -> int:
        return len(self.params)

    def value(self, name: str) -> float:
        v = float(self.by_name[name].get())
        return v if math.isfinite(v) else math.nan

    def index(self, name: str) -> int:
        return next(i for i, p in enumerate(self.params) if p.name == name)
