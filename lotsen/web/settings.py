"""The parameter sheet: what the boat runs with (controller, failsafes, planner limits; the model
comes from `model/in_use`), read-only for everyone, and the few planner limits the pilot may
change during a run.

Editable (pilot only, docs/web.md "Parameters"): the planner's top speed, longitudinal and lateral
acceleration limits may be *lowered* (never raised above the launch config: that value is what
someone checked on this boat), the clearance to obstacles may be *raised* (by up to 10 m). They
shape the next plan (draft and upload) made by this web process's planner; the path the boat
holds or follows is not touched until the next upload, so an edit is safe in any mode. The core's
own planner (return to harbour) keeps the launch values. Edits last until the web process ends.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from lotsen.errors import ConfigError
from lotsen.planning import PlannerConfig


@dataclass(frozen=True)
class Editable:
    label: str  # the operator's name of the value
    unit: str
    direction: str  # "lower": may go from `floor` up to the launch value; "raise": launch value .. +`span`
    floor: float = 0.0
    span: float = 0.0


#: planner settings the pilot may change, by their PlannerConfig field
EDITABLE: dict[str, Editable] = {
    "speed_max_mps": Editable("top speed of planned routes", "m/s", "lower", floor=0.1),
    "a_long_max_mps2": Editable("acceleration / braking limit", "m/s²", "lower", floor=0.05),
    "a_lat_max_mps2": Editable("lateral acceleration limit (turns)", "m/s²", "lower", floor=0.05),
    "clearance_m": Editable("clearance to obstacles and the area edge", "m", "raise", span=10.0),
}
EDITABLE_NAMES = tuple(f"planner.{k}" for k in EDITABLE)


def _plain(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 6) if math.isfinite(value) else None
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value if value is None or isinstance(value, (bool, int, str)) else str(value)


class Settings:
    """The launch values and the pilot's changes to the planner limits."""

    def __init__(self, planner: PlannerConfig, failsafes: Any = None, controller: dict | None = None) -> None:
        self.launch = planner
        self.planner = planner
        self.failsafes = _plain(dataclasses.asdict(failsafes)) if dataclasses.is_dataclass(failsafes) else {}
        self.controller = _plain(controller or {})
        self.changes: list[dict] = []  # who changed what, for the sheet's history

    def bounds(self, name: str) -> tuple[float, float]:
        e, launch = EDITABLE[name], float(getattr(self.launch, name))
        return (min(e.floor, launch), launch) if e.direction == "lower" else (launch, launch + e.span)

    def set(self, name: str, value: float, stamp_s: float = 0.0) -> PlannerConfig:
        """The planner config with `name` (planner.<field>) set to `value`; ConfigError in the
        operator's words when the value is refused."""
        key = name.removeprefix("planner.")
        if key not in EDITABLE:
            raise ConfigError(f"{name}: not editable on the page (editable: {', '.join(EDITABLE_NAMES)})")
        e = EDITABLE[key]
        lo, hi = self.bounds(key)
        if not math.isfinite(value):
            raise ConfigError(f"{e.label}: a number is required")
        if value > hi + 1e-9:
            raise ConfigError(f"{e.label}: {value:g} {e.unit} exceeds {hi:g} {e.unit}, " + (
                "the launch config's value (a pilot may lower it, not raise it)" if e.direction == "lower"
                else f"the launch config's {lo:g} {e.unit} plus the {e.span:g} {e.unit} the page allows"))
        if value < lo - 1e-9:
            raise ConfigError(f"{e.label}: {value:g} {e.unit} is below {lo:g} {e.unit}, " + (
                "the lowest the page accepts" if e.direction == "lower"
                else "the launch config's value (a pilot may raise it, not lower it)"))
        try:
            planner = dataclasses.replace(self.planner, **{key: float(value)})
        except (ConfigError, ValueError) as exc:
            raise ConfigError(f"{e.label}: {exc}") from None
        old = getattr(self.planner, key)
        self.planner = planner
        self.changes = (self.changes + [{"t": round(stamp_s, 2), "name": f"planner.{key}", "from": old,
                                         "to": float(value)}])[-20:]
        return planner

    def summary(self) -> dict:
        """The sheet: {planner: {field: {value, launch, editable, lo?, hi?, label?, unit?}},
        failsafes, controller, changes}."""
        planner = {}
        for f in dataclasses.fields(self.planner):
            v, launch = getattr(self.planner, f.name), getattr(self.launch, f.name)
            row: dict[str, Any] = {"value": _plain(v), "launch": _plain(launch), "editable": f.name in EDITABLE}
            if f.name in EDITABLE:
                lo, hi = self.bounds(f.name)
                row.update(lo=lo, hi=hi, label=EDITABLE[f.name].label, unit=EDITABLE[f.name].unit)
            planner[f.name] = row
        return {"type": "settings", "planner": planner, "failsafes": self.failsafes,
                "controller": self.controller, "changes": list(self.changes),
                "takes_effect": "at the next plan and upload from this page; the route the boat holds "
                                "and the core's return-to-harbour planner are not changed"}
