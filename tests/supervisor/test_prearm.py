"""Pre-arm checks as pure functions: each one fails and passes at its threshold."""

import math
from dataclasses import replace

import numpy as np
import pytest

from lotsen.errors import ConfigError
from lotsen.messages import BatteryStatus, GnssFix, GnssFixType, LinkStatus, RcOverride, VesselState
from lotsen.planning.path import Path
from lotsen.planning.route import HarbourNode, Route, RouteNode
from lotsen.runtime.config import from_mapping
from lotsen.supervisor.failsafes import FailsafeConfig
from lotsen.supervisor.prearm import (
    PrearmInputs, blocking, check_battery, check_gnss, check_heading, check_pilot_link, check_position, check_route,
    describe, prearm_failures, route_corridor_m,
)

CFG = FailsafeConfig()
# a 40 m x 10 m area, the path along its middle: 5 m from either edge, 2 m from the ends
ROUTE = Route(harbour=HarbourNode(2.0, 5.0, 0.0), nodes=(RouteNode(38.0, 5.0, 0.0, 0.5),),
              area=((0.0, 0.0), (40.0, 0.0), (40.0, 10.0), (0.0, 10.0)))


def straight_path(n0=2.0, n1=38.0, east=5.0):
    north = np.linspace(n0, n1, 200)
    return Path(north_m=north, east_m=np.full_like(north, east), heading_rad=np.zeros_like(north),
                curvature_1pm=np.zeros_like(north), speed_mps=np.full_like(north, 0.5), s_m=north - n0)


PATH = straight_path()


def good(**changes):
    """Inputs that pass every check: RTK fixed, calibrated, healthy, full battery, pilot present."""
    state = VesselState(stamp_s=10.0, north_m=2.0, east_m=5.0, heading_rad=0.0, u_mps=0.0, v_mps=0.0, r_radps=0.0,
                        source="ekf", std=(0.01, 0.01, 0.005, 0.01, 0.01, 0.01))
    base = PrearmInputs(
        now_s=10.0, escs_armed=True, state=state, position_usable=True, heading_usable=True,
        fix=GnssFix(stamp_s=9.9, lat_deg=48.0, lon_deg=11.0, height_m=500.0, fix_type=GnssFixType.RTK_FIXED,
                    h_acc_m=0.014),
        heading_calibration="file mag.json", battery=BatteryStatus(stamp_s=9.9, voltage_v=12.5, remaining_frac=0.95),
        route=ROUTE, path=PATH, corridor_m=route_corridor_m(ROUTE, PATH),
        link=LinkStatus(stamp_s=9.9, pilot_connected=True, last_heard_s=9.9), link_age_s=0.1)
    return replace(base, **changes)


def ids(failures):
    return [f.id for f in failures]


def test_good_inputs_pass_every_check():
    assert prearm_failures("auto", good(), CFG) == []
    assert prearm_failures("arm", good(), CFG) == []


def test_the_corridor_is_the_paths_clearance_to_the_area_edge():
    assert route_corridor_m(ROUTE, PATH) == pytest.approx(2.0, abs=1e-6)  # the ends, 2 m from north/south edges
    assert route_corridor_m(ROUTE, straight_path(10.0, 30.0, east=9.0)) == pytest.approx(1.0, abs=1e-6)
    assert route_corridor_m(ROUTE, straight_path(10.0, 30.0, east=11.5)) == pytest.approx(-1.5, abs=1e-6)
    assert route_corridor_m(replace(ROUTE, area=None), PATH) == math.inf
    assert route_corridor_m(None, None) == math.inf


@pytest.mark.parametrize("h_acc, fails", [(0.49, False), (0.51, True), (1.4, True)])
def test_position_accuracy_against_the_corridor(h_acc, fails):
    # corridor 2 m x 25 % = 0.5 m needed
    inp = good(fix=replace(good().fix, h_acc_m=h_acc))
    out = check_position(inp, CFG)
    assert bool(out) == fails
    if fails:
        assert out[0].message == (f"position accuracy {h_acc:g} m is worse than the route's corridor needs "
                                  "(0.5 m: 25 % of the path's 2 m clearance)")


def test_position_accuracy_uses_the_estimate_std_and_the_cap_without_an_area():
    std = (0.6, 0.6, 0.005, 0.01, 0.01, 0.01)
    assert ids(check_position(good(state=replace(good().state, std=std)), CFG)) == ["position"]
    wide = good(route=replace(ROUTE, area=None), corridor_m=math.inf, fix=replace(good().fix, h_acc_m=0.99))
    assert check_position(wide, CFG) == []
    out = check_position(replace(wide, fix=replace(wide.fix, h_acc_m=1.01)), CFG)
    assert out and out[0].message == ("position accuracy 1.01 m is worse than the 1 m AUTO allows "
                                      "(prearm_max_position_accuracy_m)")
    assert check_position(wide, FailsafeConfig(prearm_max_position_accuracy_m=0.5)) != []


def test_no_usable_position_cannot_be_overridden():
    out = check_position(good(position_usable=False), CFG)
    assert out[0].message == "no usable position estimate" and not out[0].overridable


def test_gnss_fix_type_age_and_absence():
    fix = good().fix
    assert check_gnss(good(fix=replace(fix, fix_type=GnssFixType.RTK_FLOAT)), CFG) == []  # the failsafe minimum
    out = check_gnss(good(fix=replace(fix, fix_type=GnssFixType.FIX_3D)), CFG)
    assert out[0].message == "GNSS fix FIX_3D, AUTO needs RTK_FLOAT or better (gnss_min_fix)"
    assert check_gnss(good(fix=replace(fix, fix_type=GnssFixType.FIX_3D)),
                      FailsafeConfig(gnss_degraded_action="continue")) == []
    assert check_gnss(good(fix=replace(fix, stamp_s=10.0 - 1.4)), CFG) == []  # gnss_lost_s 1.5 s
    assert "1.6 s old" in check_gnss(good(fix=replace(fix, stamp_s=10.0 - 1.6)), CFG)[0].message
    assert check_gnss(good(fix=None), CFG)[0].message == "GNSS: no fix received"
    assert "NO_FIX" in check_gnss(good(fix=replace(fix, fix_type=GnssFixType.NO_FIX)), CFG)[0].message
    truth = good(fix=None, state=replace(good().state, source="truth", std=()))
    assert check_gnss(truth, CFG) == [] and check_position(truth, CFG) == []


def test_heading_calibration_health_and_uncertainty():
    out = check_heading(good(heading_calibration=""), CFG)
    assert out[0].message.startswith("heading: magnetometer not calibrated") and out[0].overridable
    out = check_heading(good(heading_usable=False), CFG)
    assert out[0].message == "no trustworthy heading estimate" and not out[0].overridable
    st = good().state
    std_ok = replace(st, std=st.std[:2] + (math.radians(4.9),) + st.std[3:])
    std_bad = replace(st, std=st.std[:2] + (math.radians(5.1),) + st.std[3:])
    assert check_heading(good(state=std_ok), CFG) == []
    assert check_heading(good(state=std_bad), CFG)[0].message == "heading uncertainty 5.1 deg is above 5 deg"


@pytest.mark.parametrize("frac, volts, expect", [
    (0.26, 12.0, []),
    (0.24, 12.0, ["battery 24 % is below the return reserve 25 %"]),
    (0.9, 10.79, ["battery 10.79 V is below the return threshold 10.8 V (battery_low_v)"]),
    (math.nan, 10.81, []),
])
def test_battery_against_the_return_reserve(frac, volts, expect):
    b = BatteryStatus(stamp_s=9.9, voltage_v=volts, remaining_frac=frac)
    assert [f.message for f in check_battery(good(battery=b), CFG)] == expect


def test_battery_reserve_threshold_is_configurable_and_a_missing_monitor_fails():
    b = BatteryStatus(stamp_s=9.9, voltage_v=12.0, remaining_frac=0.18)
    assert check_battery(good(battery=b), FailsafeConfig(prearm_battery_reserve_frac=0.15)) == []
    assert ids(check_battery(good(battery=None), CFG)) == ["battery"]


def test_route_loaded_inside_the_area_and_the_boat_in_it():
    out = check_route(good(path=None), CFG)
    assert out[0].message == "no route loaded" and not out[0].overridable
    outside = straight_path(10.0, 30.0, east=11.5)
    out = check_route(good(path=outside, corridor_m=route_corridor_m(ROUTE, outside)), CFG)
    assert [f.message for f in out] == ["route: the path leaves the navigable area by 1.5 m"]
    away = replace(good().state, east_m=-0.4)
    assert [f.message for f in check_route(good(state=away), CFG)] == ["the boat is 0.4 m outside the navigable area"]
    assert check_route(good(state=away), FailsafeConfig(geofence_margin_m=0.5)) == []


def test_pilot_link_or_rc():
    assert check_pilot_link(good(link_age_s=1.4), CFG) == []  # link_timeout_s 1.5 s
    assert ids(check_pilot_link(good(link_age_s=1.6), CFG)) == ["pilot_link"]
    assert ids(check_pilot_link(good(link=replace(good().link, pilot_connected=False)), CFG)) == ["pilot_link"]
    rc_only = good(link=None, link_age_s=math.inf, rc=RcOverride(stamp_s=9.5, active=False))
    assert check_pilot_link(rc_only, CFG) == []
    assert ids(check_pilot_link(replace(rc_only, rc=RcOverride(stamp_s=8.0, active=False)), CFG)) == ["pilot_link"]


def test_every_failure_is_listed_and_arm_checks_only_the_battery():
    poor = good(fix=replace(good().fix, fix_type=GnssFixType.FIX_3D, h_acc_m=1.4), heading_calibration="",
                battery=BatteryStatus(stamp_s=9.9, voltage_v=11.5, remaining_frac=0.18), link=None)
    assert ids(prearm_failures("auto", poor, CFG)) == ["battery", "position", "gnss", "heading", "pilot_link"]
    assert ids(prearm_failures("arm", poor, CFG)) == ["battery"]
    assert prearm_failures("hold", poor, CFG) == []
    text = describe(prearm_failures("auto", poor, CFG))
    assert "battery 18 % is below the return reserve 25 %" in text and "position accuracy 1.4 m" in text


def test_skip_and_override_never_start_what_cannot_work():
    inp = good(link=None, heading_calibration="", path=None)
    skip = FailsafeConfig(prearm_skip=("pilot_link", "heading", "route"))
    assert [f.message for f in prearm_failures("auto", inp, skip)] == ["no route loaded"]
    over = FailsafeConfig(prearm_override=True)
    failed = prearm_failures("auto", inp, over)
    assert ids(failed) == ["heading", "route", "pilot_link"]
    assert [f.message for f in blocking(failed, over)] == ["no route loaded"]
    assert blocking(prearm_failures("auto", replace(inp, path=PATH), over), over) == []
    assert len(blocking(failed, CFG)) == 3


def test_prearm_settings_are_validated():
    cfg = from_mapping(FailsafeConfig, {"prearm_skip": ["pilot_link"], "prearm_battery_reserve_frac": 0.3})
    assert cfg.prearm_skip == ("pilot_link",) and cfg.prearm_battery_reserve_frac == 0.3
    with pytest.raises(ConfigError, match="prearm_skip\\[0\\]: 'escs' is not one of"):
        from_mapping(FailsafeConfig, {"prearm_skip": ["escs"]}, "extra.failsafes")
    with pytest.raises(ConfigError, match="prearm_corridor_fraction: 2.0 outside the allowed range"):
        from_mapping(FailsafeConfig, {"prearm_corridor_fraction": 2.0}, "extra.failsafes")
    with pytest.raises(ConfigError, match="prearm_override: expected true or false"):
        from_mapping(FailsafeConfig, {"prearm_override": "yes"}, "extra.failsafes")
