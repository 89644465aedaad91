"""Waves (issue 46): the boat on a lake with wind waves, on lotsen's simulator and on the independent
6-DOF hull (tests/physics/hull6dof.py, its own waves written from the literature), against the same
missions in calm water in the same run.

Cases: the figure eight (examples/routes/figure_eight.yaml) at 0.5 and 1.0 m/s nominal, and station
keeping (a 6-m leg heading into the wind and waves, then 60 s held at its end), each in 0.08 m/s current (to 30 deg) and 4 m/s gusty
wind (20 % gusts, 15 deg wandering direction, from 250 deg), in calm water and in wind seas from the
wind's direction: Hs 3 cm Tp 0.8 s, Hs 6 cm Tp 1.0 s, Hs 10 cm Tp 1.2 s; seeds 0-4 (quick: seed 0,
no 1.0 m/s). The stack's own closed loop on simulated time (`lotsen.harness.mission.run_mission`):
lotsen's sensors, the EKF, the MPC (station keeping: the station keeper), the supervisor with its
failsafes; the default model (neither hull is built like it).

Figures per case and sea: missions completed without any failsafe (and for any that did not, its seed, the
mission's end reason and the failsafes raised); cross-track RMS (and max) of the
true track, its low-frequency part (a 3-s moving average: the motion a controller should act on) and
the rest, the hull's wave-frequency motion, which no controller should chase, also as a share of the
tracking bar (2 x calm: above 1, the waves' own motion alone is over it); the settled hold's RMS distance;
the actuators' activity (`lotsen.sim.activity.actuator_activity`): azimuth travel, propeller speed
change, reversals per second, electrical energy (and where it goes: per propeller, and the share of
the time each azimuth runs astern); each as the ratio to calm water from the same seeds, the tracking
ratio with its 95 % interval over the seeds (a paired bootstrap, `ratio_interval`): how far a verdict on
a ratio near its bar can be trusted.

Targets (issue 46 "done when"): every mission completes with no failsafe; cross-track RMS <= 2x calm;
station keeping <= 5 cm; reversals and azimuth travel per second <= 2x calm, energy <= 1.3x calm.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "physics"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

# the water and air of every case: the lake case of bench hull (issue 39), defined there once
from bench_hull import CURRENT, GUSTS, WANDER_DEG, WIND  # noqa: E402

SEAS = {"calm": None, "Hs 3 cm": (0.03, 0.8), "Hs 6 cm": (0.06, 1.0), "Hs 10 cm": (0.10, 1.2)}
WAVES_FROM_DEG = 250.0
HOLD_S = 60.0
#: the seeds each case and sea is flown with (issue 46: at least 3)
SEEDS = (0, 1, 2, 3, 4)
PLANTS = ("lotsen simulator (lake boat)", "6-DOF hull (tests/physics/hull6dof.py)")
CASES = ("figure eight 0.5 m/s", "figure eight 1.0 m/s", "station keeping")
# station keeping: a 6-m leg at 0.3 m/s heading into the wind and the waves (250 deg), as an operator
# holds head to weather, then 60 s held at its end
STATION_ROUTE = {"harbour": {"north": 21.03, "east": 22.82, "heading_deg": 250.0},
                 "nodes": [{"north": 20.0, "east": 20.0, "heading_deg": 250.0, "speed_mps": 0.3},
                           {"north": 18.97, "east": 17.18, "heading_deg": 250.0, "speed_mps": 0.3}],
                 "area": [[0, 0], [40, 0], [40, 40], [0, 40]]}


def _path(case: str) -> Any:
    from lotsen.files import read_yaml
    from lotsen.planning import plan_route
    from lotsen.planning.io import route_from_dict

    if case == "station keeping":
        return plan_route(route_from_dict(STATION_ROUTE))
    route = read_yaml(REPO / "examples" / "routes" / "figure_eight.yaml")
    speed = 0.5 if "0.5" in case else 1.0
    route["nodes"] = [dict(n, speed_mps=speed) for n in route["nodes"]]
    return plan_route(route_from_dict(route))


def fly(job: tuple[str, str, str, int]) -> dict:
    """One mission: (plant, case, sea, seed) -> its metrics."""
    plant_name, case, sea, seed = job
    from lotsen.control import ControlConfig, make_path_follower
    from lotsen.harness.mission import MissionConfig, make_sim_ekf, run_mission
    from lotsen.model import Environment, VesselModel
    from lotsen.model.environment import Waves

    path = _path(case)
    model = VesselModel()
    hold = HOLD_S if case == "station keeping" else 5.0
    spec = SEAS[sea]
    if plant_name.startswith("lotsen"):
        env = Environment(current_speed_mps=CURRENT[0], current_to_deg=CURRENT[1], wind_speed_mps=WIND[0],
                          wind_from_deg=WIND[1], wind_gust_std_mps=GUSTS * WIND[0], wind_direction_std_deg=WANDER_DEG,
                          waves=Waves(spec[0], spec[1], WAVES_FROM_DEG) if spec else None)
        cfg = MissionConfig(environment=env, seed=seed, hold_s=hold, sensors=True)
        res = run_mission(path, make_path_follower(ControlConfig(), model), cfg, model=model,
                          estimator=make_sim_ekf(cfg, path, model))
    else:
        from hull6dof import HullEnvironment
        from hull_plant import HullPlant

        env6 = HullEnvironment(current_mps=CURRENT[0], current_to_deg=CURRENT[1], wind_mps=WIND[0], wind_from_deg=WIND[1],
                               gust_fraction=GUSTS, wind_wander_deg=WANDER_DEG, seed=seed,
                               wave_hs_m=spec[0] if spec else 0.0, wave_tp_s=spec[1] if spec else 1.0,
                               wave_from_deg=WAVES_FROM_DEG, wave_spreading=10.0)
        cfg = MissionConfig(seed=seed, hold_s=hold, sensors=True)
        plant = HullPlant(environment=env6, dt_s=cfg.sim_dt_s, gnss_antenna_m=(0.1, 0.0), gnss_antenna_height_m=0.2)
        res = run_mission(path, make_path_follower(ControlConfig(), model), cfg, model=model, plant=plant,
                          estimator=make_sim_ekf(cfg, path, model, boat=plant))
    m = dict(res.metrics)
    follow = res.mode == "follow"
    cte = res.cross_track_m[follow]
    if cte.size > 60:
        window = 30  # control ticks: 3 s
        lf = np.convolve(cte, np.ones(window) / window, mode="valid")
        m["cross_track_lf_rms_m"] = float(np.sqrt(np.mean(lf ** 2)))
        # the rest, about each average's centre: the hull's wave-frequency motion
        centre = window // 2 - 1
        m["cross_track_wf_rms_m"] = float(np.sqrt(np.mean((cte[centre:centre + len(lf)] - lf) ** 2)))
    m["no_failsafe"] = bool(res.completed and not m.get("failsafes_triggered"))
    return {"plant": plant_name, "case": case, "sea": sea, "seed": seed, "metrics": m}


def _mean(values: list[float | None]) -> float | None:
    v = [x for x in values if x is not None and math.isfinite(x)]
    return statistics.mean(v) if v else None


def _ratio(a: float | None, b: float | None) -> float | None:
    return round(a / b, 2) if a is not None and b else None


def ratio_interval(sea: dict[int, float], calm: dict[int, float], level: float = 0.95) -> tuple[float, float] | None:
    """A paired seed bootstrap of the ratio of means, sea over calm: every resample of the seeds with
    replacement (n^n of them, exact for the few seeds a bench flies), the same seeds for both means, and
    the central `level` of the ratios. None with fewer than two seeds flown in both. With n seeds the
    bootstrap understates the spread of a mean by about sqrt((n - 1) / n)."""
    seeds = sorted(k for k in sea if sea[k] is not None and calm.get(k) is not None
                   and math.isfinite(sea[k]) and math.isfinite(calm[k]))
    n = len(seeds)
    if n < 2 or n > 7:  # 7^7 = 823543 resamples; a larger bench wants a random bootstrap
        return None
    a = np.array([sea[k] for k in seeds])
    b = np.array([calm[k] for k in seeds])
    idx = np.array(np.meshgrid(*[np.arange(n)] * n, indexing="ij")).reshape(n, -1)
    den = b[idx].sum(axis=0)
    ratios = a[idx].sum(axis=0)[den > 0] / den[den > 0]
    lo, hi = np.quantile(ratios, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return float(lo), float(hi)


#: reversals per second below this count as calm water's: a ratio to a calm figure near zero says little
REVERSAL_FLOOR_PER_S = 0.05


def reversal_ratio(rev: float | None, rev_calm: float | None) -> float | None:
    """Reversals per second against calm water's, each at least REVERSAL_FLOOR_PER_S."""
    return _ratio(max(rev or 0.0, REVERSAL_FLOOR_PER_S), max(rev_calm or 0.0, REVERSAL_FLOOR_PER_S))


def _row(plant: str, case: str, sea: str, runs: list[dict], calm: list[dict]) -> dict:
    ms = [r["metrics"] for r in runs]
    station = case == "station keeping"

    def avg(key: str, src: list[dict] = ms, sub: str | None = None) -> float | None:
        return _mean([(m.get(sub) or {}).get(key) if sub else m.get(key) for m in src])

    cm = [r["metrics"] for r in calm]
    sub = "hold" if station else None
    row: dict[str, Any] = {"table": f"{case}, {plant}", "sea": sea,
                           "completed, no failsafe": f"{sum(m['no_failsafe'] for m in ms)} of {len(ms)}"}
    # which seed did not, and why: an abort is the first symptom, the count alone does not say
    row["not completed (seed: reason, failsafes)"] = "; ".join(
        f"{r['seed']}: {r['metrics'].get('reason')}, {', '.join(r['metrics'].get('failsafes_triggered') or []) or 'none'}"
        for r in runs if not r["metrics"]["no_failsafe"])
    if station:
        row["hold RMS cm"] = round(100 * (avg("hold_position_error_rms_m") or math.nan), 2)
        row["hold max cm"] = round(100 * (avg("hold_position_error_max_m") or math.nan), 2)
    else:
        row["cross-track RMS cm"] = round(100 * (avg("cross_track_rms_m") or math.nan), 2)
        row["low-freq. cm"] = round(100 * (avg("cross_track_lf_rms_m") or math.nan), 2)
        row["wave-freq. cm"] = round(100 * (avg("cross_track_wf_rms_m") or math.nan), 2)
        row["max cm"] = round(100 * (avg("cross_track_max_m") or math.nan), 1)
    row["azimuth travel deg/s"] = round(avg("azimuth_travel_deg_per_s", sub=sub) or math.nan, 1)
    row["reversals /s"] = round(avg("reversals_per_s", sub=sub) or 0.0, 3)
    row["energy J"] = round(avg("energy_J", sub=sub) or math.nan)
    # where the energy goes (lotsen.sim.activity.actuator_activity): an azimuth pushing astern against
    # the other or a steady bow push shows here
    src = [(m.get(sub) or {}) if sub else m for m in ms]
    by_prop = [_mean([(x.get("energy_J_by_propeller") or [None] * 3)[i] for x in src]) for i in range(3)]
    row["energy J az 1 / az 2 / bow"] = " / ".join("-" if e is None else f"{e:.0f}" for e in by_prop)
    astern = [_mean([(x.get("azimuth_astern_share") or [None] * 2)[i] for x in src]) for i in range(2)]
    row["azimuths astern %"] = " / ".join("-" if a is None else f"{100 * a:.0f}" for a in astern)
    if sea != "calm":
        key = "hold_position_error_rms_m" if station else "cross_track_rms_m"
        if not station:
            calm_rms = avg(key, cm)
            row["x calm (tracking)"] = _ratio(avg(key), calm_rms)
            ci = ratio_interval({r["seed"]: r["metrics"].get(key) for r in runs},
                                {r["seed"]: r["metrics"].get(key) for r in calm})
            # how far the seeds flown let the verdict on a ratio near its bar be trusted
            row["x calm (tracking), 95 % over seeds"] = f"{ci[0]:.2f}-{ci[1]:.2f}" if ci else ""
            # the hull's wave-frequency motion alone, which the controllers are not to chase (issue 46
            # item 3), against the tracking bar: above 1, no controller that leaves it alone meets the bar
            row["wave-freq. / (2 x calm)"] = _ratio(avg("cross_track_wf_rms_m"), 2 * calm_rms if calm_rms else None)
        row["x calm (travel)"] = _ratio(avg("azimuth_travel_deg_per_s", sub=sub), avg("azimuth_travel_deg_per_s", cm, sub))
        rev, rev_calm = avg("reversals_per_s", sub=sub), avg("reversals_per_s", cm, sub)
        row["x calm (reversals)"] = reversal_ratio(rev, rev_calm)
        row["x calm (energy)"] = _ratio(avg("energy_J", sub=sub), avg("energy_J", cm, sub))
        ok = all(m["no_failsafe"] for m in ms)
        if station:
            ok = ok and (avg("hold_position_error_rms_m") or math.inf) <= 0.05
        else:
            ok = ok and (row["x calm (tracking)"] or math.inf) <= 2.0
        ok = ok and (row["x calm (travel)"] or math.inf) <= 2.0 and (row["x calm (reversals)"] or math.inf) <= 2.0
        ok = ok and (row["x calm (energy)"] or math.inf) <= 1.3
        row["pass"] = ok
        row["target"] = ("completes, no failsafe; hold <= 5 cm; travel, reversals <= 2x calm; energy <= 1.3x calm"
                         if station else "completes, no failsafe; tracking, travel, reversals <= 2x calm; energy "
                                         "<= 1.3x calm")
    else:
        row["pass"] = all(m["no_failsafe"] for m in ms)
        row["target"] = "completes, no failsafe"
    row["seeds"] = len(ms)
    return row


def run(quick: bool = False) -> list[dict]:
    seeds = (0,) if quick else SEEDS
    cases = ("figure eight 0.5 m/s", "station keeping") if quick else CASES
    jobs = [(p, c, s, seed) for p in PLANTS for c in cases for s in SEAS for seed in seeds]
    workers = max(1, min(len(jobs), os.cpu_count() or 1))
    with ProcessPoolExecutor(workers) as pool:
        results = list(pool.map(fly, jobs))
    rows = []
    for p in PLANTS:
        for c in cases:
            calm = [r for r in results if (r["plant"], r["case"], r["sea"]) == (p, c, "calm")]
            for s in SEAS:
                runs = [r for r in results if (r["plant"], r["case"], r["sea"]) == (p, c, s)]
                rows.append(_row(p, c, s, runs, calm))
    return rows


if __name__ == "__main__":
    import pprint

    pprint.pprint(run(quick="--quick" in sys.argv))
