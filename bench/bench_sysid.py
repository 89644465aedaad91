"""System identification benchmark (issues 6 and 16).

Data come from tests/sysid/independent_sim.py: vessel-model.md integrated by its own code (scipy
DOP853), true parameters = the defaults perturbed by up to +-15 % (m11 kept), every estimate started
from the documented defaults with all 17 parameters but m11 free.
Rows:
  1. whole record, 10 min (quick: 2 min): multiple shooting on sample-aligned and on asynchronous
     data (commands at 10 Hz, first-order actuators, achieved values at 50 Hz, GNSS at 8 Hz with a
     phase offset; the achieved values as interval means (input_kind "mean", reconstructed piecewise
     linearly) and, for comparison, held; also held with the actuators logged at 250 Hz); wall and
     CPU time (target <= 20 s),
     max |err| / reported sigma, max |err| / Cramer-Rao bound of the whole record (target < 3), and
     single shooting in 10 s windows for comparison.
  2. Monte Carlo (60 s runs): rms(err / reported sigma) (target 0.8-1.25), share outside the 95 %
     interval, and reported sigma / whole-record bound.
  3. experiment time to 5 % (1.96 sigma / |theta|) on all 17 parameters: standard battery vs a
     robust design (the prior and two parameter sets within +-15 %; worst over the set).
"""

from __future__ import annotations

import dataclasses
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from lotsen.model import DEFAULT_PARAMETERS  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "sysid"))

TRUE = DEFAULT_PARAMETERS

BATTERY = {
    "name": "standard_battery", "area": {"size_m": [400, 400]},
    "pieces": [
        {"type": "steps", "label": "speed steps", "step_duration_s": 8,
         "levels": [{"n_rps": 30}, {"n_rps": 60}, {"n_rps": 90}, {"n_rps": 40}]},
        {"type": "zigzag", "label": "zigzag 10/10", "duration_s": 40, "alpha_deg": 10, "heading_deg": 10, "n_rps": 70},
        {"type": "zigzag", "label": "zigzag 20/20", "duration_s": 40, "alpha_deg": 20, "heading_deg": 20, "n_rps": 70},
        {"type": "turning_circle", "label": "circle stbd", "duration_s": 30, "alpha_deg": 35, "n_rps": 70,
         "direction": "starboard"},
        {"type": "turning_circle", "label": "circle port", "duration_s": 30, "alpha_deg": 35, "n_rps": 70,
         "direction": "port"},
        # the classic battery has no bow-thruster piece; without one mu_t has no information at all
        {"type": "steps", "label": "bow thruster steps", "step_duration_s": 5,
         "levels": [{"n_rps": 20, "nt_rps": 60}, {"n_rps": 20, "nt_rps": -60}, {"n_rps": 20, "nt_rps": 80},
                    {"n_rps": 20, "nt_rps": -80}]},
    ],
}



def _start():  # type: ignore[no-untyped-def]
    from independent_sim import DEFAULTS, NAMES

    from lotsen.model import VesselParameters

    return VesselParameters.from_vector([DEFAULTS[n] for n in NAMES])


def _whole_record_row(g, style: str, dur: float) -> list[dict]:  # type: ignore[no-untyped-def]
    from independent_sim import NAMES

    from lotsen.model import VesselParameters
    from lotsen.sysid.estimate import SolverOptions, estimate
    from lotsen.sysid.multiple import estimate_multiple_shooting, record_fisher

    rows = []
    w0, c0 = time.perf_counter(), time.process_time()
    res = estimate_multiple_shooting([g.record], _start(), {"m11": 14.0})
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    true = VesselParameters.from_vector([g.params[n] for n in NAMES])
    bound = np.sqrt(np.diag(np.linalg.inv(record_fisher([g.record], true, res.free_names))))
    err = np.array([getattr(res.params, n) - g.params[n] for n in res.free_names])
    z = err / np.array([res.std[n] for n in res.free_names])
    zb = err / bound
    rel = np.abs(err) / np.abs([g.params[n] for n in res.free_names])
    rows.append({"case": f"multiple shooting, {style}, {dur:.0f} s", "free": len(res.free_names),
                 "rows": len(g.record.t), "iterations": res.iterations, "converged": res.converged,
                 "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                 "max_rel_err_pct": round(100 * float(rel.max()), 2),
                 "worst": res.free_names[int(np.argmax(np.abs(zb)))],
                 "max_err_over_sigma": round(float(np.abs(z).max()), 2),
                 "rms_err_over_sigma": round(float(np.sqrt(np.mean(z ** 2))), 2),
                 "max_err_over_bound": round(float(np.abs(zb).max()), 2),
                 "worst_bound_pct": round(100 * float(np.max(bound / np.abs([g.params[n] for n in res.free_names]))), 2),
                 "target": "<= 20 s CPU, |err| < 3 bound", "pass": bool(cpu <= 20 and np.abs(zb).max() < 3)})
    if style == "aligned":
        w0, c0 = time.perf_counter(), time.process_time()
        r1 = estimate([g.record], _start(), fixed={"m11": 14.0}, options=SolverOptions(window_s=10.0))
        cpu1 = time.process_time() - c0
        e1 = np.array([getattr(r1.params, n) - g.params[n] for n in r1.free_names])
        rel1 = np.abs(e1) / np.abs([g.params[n] for n in r1.free_names])
        rows.append({"case": f"single shooting (10 s windows), {style}, {dur:.0f} s", "free": len(r1.free_names),
                     "rows": len(g.record.t), "iterations": r1.iterations, "converged": r1.converged,
                     "wall_s": round(time.perf_counter() - w0, 2), "cpu_s": round(cpu1, 2),
                     "max_rel_err_pct": round(100 * float(rel1.max()), 2),
                     "worst": r1.free_names[int(np.argmax(rel1))],
                     "max_err_over_sigma": round(float(np.abs(e1 / [r1.std[n] for n in r1.free_names]).max()), 2),
                     "max_err_over_bound": round(float(np.abs(e1 / bound).max()), 2)})
    return rows


def run(quick: bool = False) -> list[dict]:
    from independent_sim import NAMES, generate, perturbed

    from lotsen.model import VesselParameters
    from lotsen.sysid.design import DesignConfig, design_experiment, experiment_information, parameter_samples, \
        time_to_accuracy
    from lotsen.sysid.experiment import parse_experiment
    from lotsen.sysid.multiple import estimate_multiple_shooting, record_fisher

    rows: list[dict] = []
    # compile the kernels once (cached on disk) so that no row pays for it
    g0 = generate(10.0, seed=0, style="aligned")
    estimate_multiple_shooting([g0.record], _start(), {n: v for n, v in g0.params.items()})

    # --- 1: whole record ---------------------------------------------------------------------------
    dur = 120.0 if quick else 600.0
    for style in ("aligned", "async"):
        rng = np.random.default_rng(2)
        g = generate(dur, seed=2, style=style, params=perturbed(rng))
        if style == "async":  # achieved values as interval means (input_kind "mean")
            rows += _whole_record_row(g, "async (achieved inputs: interval means)", dur)
            # the same record with the inputs held (zero-order hold, as for commands): the hold of
            # 50 Hz interval means misplaces the actuators' motion within the intervals during fast
            # transients (tau 60-80 ms), a bias that only the 0.1 % bounds of 10 min reveal
            held = dataclasses.replace(g, record=dataclasses.replace(g.record, input_kind="held"))
            rows += [{**r, "role": "ablation"} for r in _whole_record_row(held, "async (inputs held)", dur)]
        else:
            rows += _whole_record_row(g, style, dur)
    if not quick:
        # the same record with the achieved actuator values logged at 250 Hz, held
        g = generate(dur, seed=2, style="async", params=perturbed(np.random.default_rng(2)), input_hz=250.0)
        g = dataclasses.replace(g, record=dataclasses.replace(g.record, input_kind="held"))
        rows += _whole_record_row(g, "async (actuators logged at 250 Hz, held)", dur)

    # --- 2: Monte Carlo coverage ------------------------------------------------------------------
    n_mc = 4 if quick else 12
    for style in ("aligned", "async"):
        Z, ZB, R, T = [], [], [], []
        for k in range(n_mc if style == "aligned" else max(n_mc // 2, 3)):
            seed = 100 + k
            g = generate(60.0, seed=seed, style=style, params=perturbed(np.random.default_rng(seed)))
            c0 = time.process_time()
            res = estimate_multiple_shooting([g.record], _start(), {"m11": 14.0})
            T.append(time.process_time() - c0)
            true = VesselParameters.from_vector([g.params[n] for n in NAMES])
            bound = np.sqrt(np.diag(np.linalg.inv(record_fisher([g.record], true, res.free_names))))
            err = np.array([getattr(res.params, n) - g.params[n] for n in res.free_names])
            std = np.array([res.std[n] for n in res.free_names])
            Z.append(err / std)
            ZB.append(err / bound)
            R.append(std / bound)
        Z, ZB = np.array(Z), np.array(ZB)
        rms = float(np.sqrt(np.mean(Z ** 2)))
        rows.append({"case": f"Monte Carlo x{len(Z)}, {style}, 60 s each, 17 free", "rms_err_over_sigma": round(rms, 3),
                     "share_outside_95pct": round(float(np.mean(np.abs(Z) > 1.96)), 3),
                     "max_err_over_bound": round(float(np.abs(ZB).max()), 2),
                     "median_sigma_over_bound": round(float(np.median(R)), 3),
                     "mean_cpu_s": round(float(np.mean(T)), 2),
                     "target": "rms 0.8-1.25, |err| < 3 bound (~99.7 %)",
                     "pass": bool(0.8 <= rms <= 1.25 and np.mean(np.abs(ZB) > 3) <= 0.01)})

    # --- 3: experiment time to 5 % on all 17 -------------------------------------------------------
    free = tuple(n for n in NAMES if n != "m11")
    bexp = parse_experiment(BATTERY, "battery")
    t_b = []
    for th in parameter_samples(TRUE, 3, 0.15, seed=1):
        rs, _ = experiment_information(bexp, VesselParameters.from_vector(th), free)
        t_b.append(time_to_accuracy(rs, bexp.duration_s))
    worst_b = max(t_b)
    rows.append({"case": "standard battery, all 17 free (worst of 3 parameter sets)", "duration_s": bexp.duration_s,
                 "time_to_5pct_s": round(worst_b, 1), "per_set_s": ", ".join(f"{v:.0f}" for v in t_b)})
    w0 = time.perf_counter()
    d = design_experiment(TRUE, DesignConfig(duration_s=20.0, segment_s=2.0, iterations=4 if quick else 15, seed=1))
    rows.append({"case": "robust design 20 s (A-optimal over 3 parameter sets), all 17 free",
                 "duration_s": 20.0, "time_to_5pct_s": round(d.time_to_5pct_s, 1),
                 "worst_param": d.free_names[int(np.argmax(d.rel_std_samples.max(axis=0)))],
                 "max_abs_north_east_m": round(float(max(np.abs(X[:, :2]).max() for X in d.trajectories)), 1),
                 "design_compute_s": round(time.perf_counter() - w0, 1),
                 "ratio_to_battery": round(d.time_to_5pct_s / worst_b, 3), "target": "<= 0.333",
                 "pass": bool(d.time_to_5pct_s / worst_b <= 1 / 3)})
    return rows


if __name__ == "__main__":
    import json
    import sys

    for row in run(quick="--quick" in sys.argv):
        print(json.dumps(row))
