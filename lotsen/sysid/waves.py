"""Records taken in waves (issue 46 item 4; docs/sysid.md "Records in waves").

The record's sea state is estimated from its own IMU by the boat's sea-state estimator
(lotsen.fusion.seastate.record_sea_state; the command and the harness call it, sysid does not import
fusion) and handed to the identification problem (`IdentificationProblem.sea`). This module holds what
identification makes of it: the record's heading and speed for that estimator, whether the record is
"in waves", and the words the judge and the experiment's checks use.

Why a sea changes the verdict (lotsen's simulator, boats of the model's structure, 10-min PRBS records,
bench/bench_identify_waves.py, seeds 0-2): the wave-frequency yaw rate (0.1 rad/s RMS in 0.5-3 Hz, 15
times a calm record's, in Hs 6 cm) and the waves' mean drift (0.045 m/s over a record) are not in the
3-DOF hull model. No estimate came near the calm-water coefficients: the calm-water output-error estimate
did not converge; the equation-error fit (the derivatives of wave-frequency motion in its regressors) was
17-85 % off in its worst core coefficient; with the lake model (current and wind standing in for the
drift) the output-error estimate came within 1-7 % only when started at the boat's own coefficients, and
from the equation-error start or the defaults stopped 13-35 % off; low-passing the data at 0.3-0.5 Hz
did not help (it biased the yaw inertia by 40 % instead). Effective coefficients from these records did
predict a held-out calm record far better than the defaults (0.19-0.83 m after 10 s against 1.8 m), but
2.1-4.1 times worse than the same boat's calm record's answer in Hs 3 cm and 7.8-8.3 times worse in Hs
6 cm (with the lake model 2.1-3.3 and 6.4-7.3 times). So a record in waves (IN_WAVES_HS_M and above) gets no effective coefficients: they would be the
hull in that sea, not in calm water ("predictive" is refused with the sea state named, and the advice
says how to record instead); a physical answer is still given when it passes every check of one (none
did in waves). With the simulator's wave effects switched off one at a time (seed 0), the drift alone
left the answer 29 % off, the first-order loads alone 216 %: the wave-frequency loads, more than the
drift, put the calm coefficients out of reach (docs/sysid.md "Records in waves").
"""

from __future__ import annotations

import math

import numpy as np

from lotsen.messages import SeaState
from lotsen.model.environment import wind_sea_hs_floor_m
from lotsen.sysid.data import IdRecord

#: from this significant height on the record is "in waves" and gets no effective coefficients (module
#: docstring: in Hs 3 cm they predicted calm water 2.1-4.1 x worse than a calm record's answer); below it
#: calm water (calm records read 0 on lotsen's simulator; Hs 3 cm read 2.8 cm). The calmest wind sea of
#: issue 46 is Hs 3 cm (4 m/s over 300 m of fetch)
IN_WAVES_HS_M = 0.02
#: a reading below this share of the lowest height a wind sea of its period has
#: (lotsen.model.environment.wind_sea_hs_floor_m) is no wind sea: the growth laws scatter by tens of
#: percent and the IMU's Tp reads short (bench identify's records in waves: Hs 6 cm, Tp 1.0 s read 6.8-7.8
#: cm at 0.78-0.95 s, 2.0-3.0 x the floor; Hs 3 cm, Tp 0.8 s read 2.7-3.6 cm at 0.78-0.85 s, 0.97-1.5 x,
#: on lotsen's simulator and the 6-DOF hull alike). The 6-DOF hull's own manoeuvres in calm water (a
#: designed experiment, bench hull's lab loop) read Hs 2.1 cm at Tp 2.8 s: 0.07 x
WIND_SEA_FLOOR_SHARE = 0.25
SPEED_SPAN_S = 1.0  # the speed over ground from fixes this far apart


def heading_and_velocity(record: IdRecord) -> tuple[np.ndarray, np.ndarray]:
    """Per row of `record`: the heading (its psi output, NaN before the first) and the velocity over
    ground north and east (K x 2) from the position fixes SPEED_SPAN_S apart (NaN where not known): what
    the sea-state estimator needs to put the IMU's axes on the map and to undo the encounter frequency."""
    names = record.output_names
    y = record.outputs
    K = len(record.t)
    psi = np.full(K, math.nan)
    velocity = np.full((K, 2), math.nan)
    if "psi" not in names or "north" not in names or "east" not in names:
        return psi, velocity
    jp, jn, je = names.index("psi"), names.index("north"), names.index("east")
    ok = np.isfinite(y[:, jp])
    if ok.any():
        idx = np.maximum.accumulate(np.where(ok, np.arange(K), 0))
        psi = np.where(np.arange(K) >= np.argmax(ok), y[idx, jp], math.nan)
    fix = np.flatnonzero(np.isfinite(y[:, jn]) & np.isfinite(y[:, je]))
    if len(fix) < 3:
        return psi, velocity
    tf = record.t[fix]
    a = np.searchsorted(tf, tf - SPEED_SPAN_S / 2)
    b = np.minimum(np.searchsorted(tf, tf + SPEED_SPAN_S / 2, side="right") - 1, len(fix) - 1)
    dt = tf[b] - tf[a]
    with np.errstate(invalid="ignore", divide="ignore"):
        vn = np.where(dt > 0, (y[fix[b], jn] - y[fix[a], jn]) / dt, math.nan)
        ve = np.where(dt > 0, (y[fix[b], je] - y[fix[a], je]) / dt, math.nan)
    velocity[fix, 0], velocity[fix, 1] = vn, ve
    return psi, velocity


def high_enough(hs_m: float) -> bool:
    """A significant height that counts as waves (IN_WAVES_HS_M or more), whatever its period."""
    return math.isfinite(hs_m) and hs_m >= IN_WAVES_HS_M


def wind_sea(hs_m: float, tp_s: float) -> bool:
    """A height and period a wind sea can have together (WIND_SEA_FLOOR_SHARE; an unknown period: yes)."""
    return not math.isfinite(tp_s) or tp_s <= 0.0 or hs_m >= WIND_SEA_FLOOR_SHARE * wind_sea_hs_floor_m(tp_s)


def in_waves(sea: SeaState | None) -> bool:
    """The record was taken in a wind sea: its IMU reads IN_WAVES_HS_M or more, at a period a sea of that
    height can have."""
    return sea is not None and sea.valid and high_enough(sea.hs_m) and wind_sea(sea.hs_m, sea.tp_s)


def describe(sea: SeaState | None) -> str:
    """The record's sea in words (from its IMU)."""
    if sea is None:
        return "sea state unknown (the record has no IMU)"
    if not sea.valid:
        return f"sea state unknown (the record's IMU holds {sea.window_s:.0f} s, too little)"
    if not in_waves(sea):
        if high_enough(sea.hs_m):  # no wind sea at that period (`wind_sea`)
            return (f"calm water (the record's IMU reads Hs {100 * sea.hs_m:.1f} cm at Tp {sea.tp_s:.1f} s, no "
                    f"wind sea: one of that period stands {100 * wind_sea_hs_floor_m(sea.tp_s):.0f} cm or more; "
                    "the hull's own motion in its manoeuvres, or a passing wake)")
        return f"calm water (Hs {100 * max(sea.hs_m, 0.0):.1f} cm from the record's IMU)"
    frm = f", from {sea.from_deg:.0f} deg" if math.isfinite(sea.from_deg) else ""
    tp = f", Tp {sea.tp_s:.1f} s" if math.isfinite(sea.tp_s) else ""
    return f"in waves: Hs {100 * sea.hs_m:.1f} cm{tp}{frm} (from the record's IMU)"


def sea_advice(sea: SeaState | None) -> str:
    """What to do about a sea too high for a trustworthy record."""
    frm = (f" (they come from {sea.from_deg:.0f} deg: start the experiment heading {sea.from_deg:.0f} deg)"
           if sea is not None and math.isfinite(sea.from_deg) else "")
    return (f"record in a calmer moment (Hs below {100 * IN_WAVES_HS_M:.0f} cm: wind sea builds with wind and fetch, "
            f"so early morning or the lee shore), head to the sea{frm}, and make the manoeuvres larger and the "
            "record longer, so that the boat's own motion stands out of the wave motion")


def sea_to_json(sea: SeaState | None) -> dict | None:
    if sea is None:
        return None

    def num(x: float, nd: int) -> float | None:
        return round(float(x), nd) if math.isfinite(x) else None

    return {"valid": sea.valid, "in_waves": in_waves(sea), "hs_m": num(sea.hs_m, 4), "tp_s": num(sea.tp_s, 2),
            "tp_encounter_s": num(sea.tp_encounter_s, 2), "from_deg": num(sea.from_deg, 0),
            "window_s": num(sea.window_s, 0), "source": "the record's IMU"}


def experiment_sea_warning(hs_m: float, tp_s: float = math.nan, from_deg: float = math.nan,
                           measured: bool = True) -> str | None:
    """The experiment's check of the sea it will run in (`lotsen experiment run --waves`, `check --sea`)
    or ran in (`measured`: read by the boat's IMU, where a long period at a small height is the hull's own
    motion, `wind_sea`): None in calm water (below IN_WAVES_HS_M); in waves a warning with what to do
    (identification will give no effective coefficients from the record, and a physical answer only if
    every check of one passes)."""
    if not high_enough(hs_m) or (measured and not wind_sea(hs_m, tp_s)):
        return None
    sea = SeaState(stamp_s=0.0, valid=True, hs_m=hs_m, tp_s=tp_s, tp_encounter_s=math.nan, from_deg=from_deg,
                   heave_std_m=math.nan, roll_std_deg=math.nan, pitch_std_deg=math.nan)
    words = describe(sea).replace(" (from the record's IMU)", "")
    return (f"WARNING: the sea is too high for a trustworthy identification record ({words}; from Hs "
            f"{100 * IN_WAVES_HS_M:.0f} cm on, identification gives no effective coefficients, and a physical answer "
            f"only if every check of one passes): {sea_advice(sea)}")
