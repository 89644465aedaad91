"""Checks before arming and before AUTO (pre-arm checks, as ArduPilot has them).

Pure functions of what the supervisor knows (`PrearmInputs`): each check returns the checks it
failed, each with an id, a message in operator language and whether an expert may override it
(`FailsafeConfig.prearm_override`). Nothing here reads a clock or the bus; the supervisor builds
the inputs and decides what to do with the failures (docs/failsafes.md has the table).

What each request needs:
- `arm`: the ESCs ready (checked by the supervisor itself, with its own message) and the battery
  above the return reserve;
- `auto`: everything: ESCs, battery, a usable position estimate whose accuracy fits the route's
  corridor, a GNSS fix good enough for the failsafes not to stop the run at once, a calibrated
  and healthy heading source, a route planned and inside the navigable area with the boat in it,
  and someone able to take over (the page's pilot or the RC receiver).
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from lotsen.messages import BatteryStatus, GnssFix, GnssFixType, LinkStatus, RcOverride, VesselState
from lotsen.supervisor.failsafes import FailsafeConfig, SkippablePrearmCheck

#: every check id, in the order the failures are listed
CHECK_IDS: tuple[str, ...] = ("escs", "battery", "storage", "position", "gnss", "heading", "route", "pilot_link")
SKIPPABLE: tuple[str, ...] = typing.get_args(SkippablePrearmCheck)
#: the checks each request runs
CHECKS_FOR: dict[str, tuple[str, ...]] = {"arm": ("battery", "storage"), "auto": CHECK_IDS,
                                          "experiment": ("escs", "battery", "storage", "position", "gnss", "heading")}


@dataclass(frozen=True)
class FailedCheck:
    """One failed pre-arm check: `id` (one of CHECK_IDS), the operator's message, and whether
    an expert override may start anyway (not when the boat physically cannot do the job)."""

    id: str
    message: str
    overridable: bool = True


@dataclass(frozen=True)
class PrearmInputs:
    """What the supervisor knows at the moment of the request (runtime clock seconds)."""

    now_s: float
    escs_armed: bool = False
    state: VesselState | None = None
    position_usable: bool = False  # the supervisor's position_ok(): finite, std bounded, integrity ok
    heading_usable: bool = False  # finite heading the integrity monitor trusts
    health: Any = None  # EstimatorHealth, when the estimator publishes one
    fix: GnssFix | None = None
    heading_calibration: str = ""  # where the magnetometer calibration in use came from; "" = none
    battery: BatteryStatus | None = None
    route: Any = None  # lotsen.planning.Route (navigable area), or None
    path: Any = None  # the planned lotsen.planning.Path AUTO would follow, or None
    corridor_m: float = math.inf  # route_corridor_m(route, path)
    link: LinkStatus | None = None
    link_age_s: float = math.inf  # since the pilot's LinkStatus arrived
    rc: RcOverride | None = None
    storage: str = ""  # failsafes.storage_problem: what is wrong with the log disk ("" = fine)


def route_corridor_m(route: Any, path: Any) -> float:
    """The route's corridor: the smallest distance from the planned path to non-navigable water
    (m). Negative when the path leaves the navigable area (by that much); inf without an area
    or obstacles."""
    if route is None or path is None or (route.area is None and not route.obstacles):
        return math.inf
    free = route.free_region()
    pts = shapely.points(np.asarray(path.north_m, float), np.asarray(path.east_m, float))
    d = shapely.distance(free.boundary, pts)
    inside = shapely.contains_xy(free, np.asarray(path.north_m, float), np.asarray(path.east_m, float))
    signed = np.where(inside, d, -d)
    return float(np.min(signed)) if signed.size else math.inf


def _m(x: float) -> str:
    """A distance the way an operator reads it: 0.05, 0.5, 1.4, 1.01, 12.3 (no trailing zeros)."""
    return f"{x:.2f}".rstrip("0").rstrip(".") if abs(x) < 10.0 else f"{x:.1f}"


# ---------------------------------------------------------------------------- the checks
def check_escs(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    if inp.escs_armed:
        return []
    return [FailedCheck("escs", "the ESCs are not armed (they need neutral for a few seconds)", False)]


def check_battery(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    b = inp.battery
    if b is None:
        return [FailedCheck("battery", "battery: no reading from the battery monitor")]
    out = []
    v, frac = b.voltage_v, b.remaining_frac
    if not math.isfinite(v):
        out.append(FailedCheck("battery", "battery: the voltage reading is not a number"))
    elif v < cfg.battery_low_v:
        out.append(FailedCheck("battery", f"battery {v:.2f} V is below the return threshold {cfg.battery_low_v:g} V "
                                          "(battery_low_v)"))
    if math.isfinite(frac) and frac < cfg.prearm_battery_reserve_frac:
        out.append(FailedCheck("battery", f"battery {100 * frac:.0f} % is below the return reserve "
                                          f"{100 * cfg.prearm_battery_reserve_frac:.0f} %"))
    return out


def position_accuracy_m(inp: PrearmInputs) -> float:
    """The horizontal accuracy of the position the boat would navigate on: the larger of the
    estimate's north/east standard deviation and the GNSS receiver's own accuracy (h_acc). The
    simulator's truth as the estimate is exact."""
    s = inp.state
    if s is not None and s.source == "truth":
        return 0.0
    acc = 0.0
    if s is not None and len(s.std) >= 2:
        acc = max(acc, float(s.std[0]), float(s.std[1]))
    if inp.fix is not None and inp.fix.usable:
        acc = max(acc, float(inp.fix.h_acc_m))
    return acc if math.isfinite(acc) else math.inf


def needed_accuracy_m(inp: PrearmInputs, cfg: FailsafeConfig) -> tuple[float, str]:
    """The accuracy AUTO needs on this route, and the operator's words for what sets it: a
    fraction of the route's corridor, or the cap when the corridor is wide (or there is none)."""
    cap = cfg.prearm_max_position_accuracy_m
    c = inp.corridor_m
    if 0.0 < c < math.inf and cfg.prearm_corridor_fraction * c <= cap:
        need = cfg.prearm_corridor_fraction * c
        return need, (f"the route's corridor needs ({_m(need)} m: {100 * cfg.prearm_corridor_fraction:.0f} % "
                      f"of the path's {_m(c)} m clearance)")
    return cap, f"the {_m(cap)} m AUTO allows (prearm_max_position_accuracy_m)"


def check_position(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    if not inp.position_usable:
        return [FailedCheck("position", "no usable position estimate", False)]
    acc = position_accuracy_m(inp)
    need, what = needed_accuracy_m(inp, cfg)
    if acc > need:
        return [FailedCheck("position", f"position accuracy {_m(acc)} m is worse than {what}")]
    return []


def check_gnss(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    s = inp.state
    if s is not None and s.source == "truth":
        return []  # the simulator's truth is the estimate: no receiver in the loop
    fix = inp.fix
    if fix is None:
        return [FailedCheck("gnss", "GNSS: no fix received")]
    if not fix.usable:
        return [FailedCheck("gnss", f"GNSS: no usable fix ({GnssFixType(fix.fix_type).name})")]
    age = inp.now_s - fix.stamp_s
    if age > cfg.gnss_lost_s:
        return [FailedCheck("gnss", f"GNSS: the last fix is {age:.1f} s old")]
    # below the failsafe's minimum, AUTO would be held within gnss_degraded_s of starting
    need = cfg.min_fix_type if cfg.gnss_degraded_action != "continue" else GnssFixType.FIX_3D
    if fix.fix_type < need:
        return [FailedCheck("gnss", f"GNSS fix {GnssFixType(fix.fix_type).name}, AUTO needs {need.name} or better "
                                    "(gnss_min_fix)")]
    return []


def check_heading(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    out = []
    s = inp.state
    truth = s is not None and s.source == "truth"
    if not inp.heading_calibration and not truth:
        out.append(FailedCheck("heading", "heading: magnetometer not calibrated (run calibrate_mag, or give "
                                          "nodes.mag_calibration_file)"))
    if not inp.heading_usable:
        faults = "; ".join(getattr(inp.health, "faults", ())[:2]) if inp.health is not None else ""
        out.append(FailedCheck("heading", "no trustworthy heading estimate" + (f" ({faults})" if faults else ""),
                               False))
        return out
    std = math.nan
    if s is not None and len(s.std) >= 3:
        std = float(s.std[2])
    elif inp.health is not None:
        std = float(getattr(inp.health, "heading_std_rad", math.nan))
    if math.isfinite(std) and math.degrees(std) > cfg.prearm_max_heading_std_deg:
        out.append(FailedCheck("heading", f"heading uncertainty {math.degrees(std):.1f} deg is above "
                                          f"{cfg.prearm_max_heading_std_deg:g} deg"))
    return out


def check_route(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    if inp.path is None:
        return [FailedCheck("route", "no route loaded", False)]
    out = []
    if inp.corridor_m < 0.0:
        out.append(FailedCheck("route", f"route: the path leaves the navigable area by {_m(-inp.corridor_m)} m"))
    s, route = inp.state, inp.route
    if route is not None and (route.area is not None or route.obstacles) and s is not None \
            and math.isfinite(s.north_m) and math.isfinite(s.east_m):
        free = route.free_region()
        if not shapely.contains_xy(free, s.north_m, s.east_m):
            d = free.distance(shapely.Point(s.north_m, s.east_m))
            if d > cfg.geofence_margin_m:
                out.append(FailedCheck("route", f"the boat is {_m(d)} m outside the navigable area"))
    return out


def check_storage(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    """The log disk: a run whose recording stops (or cannot start) leaves nothing to learn from."""
    return [FailedCheck("storage", f"storage: {inp.storage}")] if inp.storage else []


def check_pilot_link(inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    """Someone can take over: the page's pilot heard within link_timeout_s, or the RC receiver."""
    link_ok = inp.link is not None and inp.link.pilot_connected and inp.link_age_s <= cfg.link_timeout_s
    rc_ok = inp.rc is not None and inp.now_s - inp.rc.stamp_s <= cfg.link_timeout_s
    if link_ok or rc_ok:
        return []
    return [FailedCheck("pilot_link", "no pilot link or RC: nobody could take over (take the controls on the "
                                      "page, or switch on the RC transmitter)")]


CHECKS: dict[str, Any] = {"escs": check_escs, "battery": check_battery, "position": check_position,
                          "gnss": check_gnss, "heading": check_heading, "route": check_route,
                          "pilot_link": check_pilot_link, "storage": check_storage}


def prearm_failures(action: str, inp: PrearmInputs, cfg: FailsafeConfig) -> list[FailedCheck]:
    """Every failed check `action` ("arm", "auto" or "experiment") needs, in the order of CHECK_IDS. A check in
    cfg.prearm_skip reports only what no override could start anyway (no position estimate, no
    route). Other actions have no pre-arm checks."""
    out: list[FailedCheck] = []
    for cid in CHECKS_FOR.get(action, ()):
        failed = CHECKS[cid](inp, cfg)
        out.extend(f for f in failed if not (cid in cfg.prearm_skip and f.overridable))
    return out


def blocking(failures: list[FailedCheck], cfg: FailsafeConfig) -> list[FailedCheck]:
    """The failures that refuse the request: all of them, or with prearm_override only those no
    override can start anyway."""
    return [f for f in failures if not (cfg.prearm_override and f.overridable)]


def describe(failures: list[FailedCheck]) -> str:
    """The failures as one line for the refusal alert and the page's button."""
    return "; ".join(f.message for f in failures)
