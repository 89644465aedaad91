"""Identification judged by what the model is for, on records that are not the grey box's (issue 39).

Rows (lotsen.sysid.identify.identify, the path `lotsen identify` takes; CPU of the identification
alone, one BLAS thread as the command sets it):
  1. lake records of the model's structure whose wind has another form than the estimator's
     (tests/sysid/independent_sim.py `Lake`: quadratic drag per body axis with its own moment arm, or an
     Isherwood-like cos/sin form; gusts, a wandering direction, currents to 0.1 m/s, some varying),
     random boats 20 % off the defaults, 10 min each (quick: 3 records): answered (ok / weak /
     predictive, exit 0), a physical answer right by issue 25's rule (core within 5 %, the rest within
     15 % unless named weak, every coefficient within 3 sigma), the 10-s held-out prediction against the
     defaults', CPU. Targets: >= 90 % answered, no wrong physical answer, CPU <= 18 x the median of the
     same run's calm identifications (row 3). The bar was <= 20 s on the machine it was set on, where a
     calm identification took a median 1.1 s (2026-11-29); a lone timing moves with the machine (a later
     one ran the unchanged calm path 2.2x slower), a ratio to a peer in the same run does not.
  2. following the old advice "fix some of them": eight weakly determined coefficients fixed at the
     documented defaults (11-31 % off the boat's) on a lake record of lotsen's own generator: never a
     wrong physical answer (the issue's case gave verdict ok, Y_v 9 % off at 7.7 sigma).
  3. intervals over repeated records (issue 47): one boat of the model's structure (lake_boat(31),
     lotsen's simulator, calm, 10 min of PRBS each, different inputs and noise per record; quick: 6
     records, else 90), `identify(problem)` on each: per coefficient the reported std over the actual
     error, each record against its own interval: 1 / RMS(error / reported sigma) (target 0.8-1.25 for
     the core eight), with its 95 % bootstrap interval over records, and the truth within 3 reported
     sigma (target >= 97 %). Also shown, not judged: the pooled ratio RMS(reported std) / spread of the
     estimates. The records are not equally informative (a coefficient's reported std differs up to
     6-7x between records: the PRBS's turns differ), and the pooled ratio is then dominated by the few
     widest intervals: on 29 records it read 1.20-1.42 where every record's own error / sigma had an RMS
     of 0.85-1.21 (2026-11-29). 90 records, not 30: the ratio of n records scatters by about
     1 / sqrt(2 n) (0.13 at 30, 0.075 at 90), too much at 30 for a bar of +-25 %: seeds 100-129 gave N_r
     1.25, seeds 130-159 0.88, seeds 160-189 0.99, all 90 1.01 (0.88-1.18) (2026-12-02). The
     per-record form is what an interval claims; a fresh-noise Monte Carlo on one record (40 draws) gave
     the plain covariance 0.92-1.18 of the spread. Only physical
     answers (ok, weak) have intervals to judge: a record answered otherwise is counted and named, not
     averaged in; undetermined coefficients (no interval) are left out and counted. Then, shown and not
     judged, the same records with the yaw-rate offsets estimated (`--gyro-offset`: one per minute;
     the simulator's gyro bias walks), with each coefficient's RMS error in both tables.
  4. records in waves (issue 46 item 4): bench/bench_identify_waves.py (also alone: `python bench/run.py
     identify_waves`).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "sysid"))
sys.path.insert(0, str(ROOT / "bench"))

WEAK_SET = ("Y_r", "Y_uv", "Y_vv", "Y_rv", "N_v", "N_vv", "kappa", "C_N")  # the eight


def _physical_right(ident, true) -> bool:  # type: ignore[no-untyped-def]
    from bench_model_chain import _coefficient_right

    res = ident.result
    weak = ident.verdict.weakly_determined
    return all(_coefficient_right(n, getattr(res.params, n), getattr(true, n), res.std[n], weak)
               for n in res.free_names)


def _lake_cases(quick: bool) -> list[tuple[int, dict]]:
    rng = np.random.default_rng(3900)
    cases = []
    for k in range(3 if quick else 10):
        cur = float(rng.uniform(0.0, 0.1))
        cases.append((3900 + k, dict(current_mps=cur, current_to_deg=float(rng.uniform(0, 360)),
                                     current_variation_mps=float(rng.choice([0.0, 0.02, 0.03])) if cur else 0.0,
                                     wind_mps=float(rng.uniform(1.5, 5.0)), wind_from_deg=float(rng.uniform(0, 360)),
                                     gust_fraction=float(rng.uniform(0.15, 0.3)),
                                     direction_std_deg=float(rng.uniform(5, 20)),
                                     wind_form=str(rng.choice(["axis", "fossen"])))))
    return cases


#: issue 39's <= 20 s, over the calm median of the machine it was set on (1.1 s): row 1's CPU bar
LAKE_OVER_CALM_CPU = 18.0


def lake_rows(calm_cpu_s: float, quick: bool = False) -> list[dict]:
    """Row 1 of the module docstring; `calm_cpu_s`: the median CPU of the same run's calm identifications."""
    from independent_sim import NAMES, Lake, generate, perturbed

    from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
    from lotsen.sysid.identify import identify, split_holdout
    from lotsen.sysid.prediction import improvement
    from lotsen.sysid.problem import IdentificationProblem

    rows: list[dict] = []
    answered = wrong = 0
    cpus = []
    cases = _lake_cases(quick)
    for seed, env in cases:
        params = perturbed(np.random.default_rng(seed), 0.2)
        g = generate(600.0, params=params, seed=seed, style="async", lake=Lake(**env))
        true = VesselParameters.from_vector([params[n] for n in NAMES])
        est, val = split_holdout([g.record], 0.2)
        t0 = time.process_time()
        ident = identify(IdentificationProblem(tuple(est), tuple(val), {"m11": true.m11}, lake=True))
        cpu = time.process_time() - t0
        cpus.append(cpu)
        v = ident.verdict.verdict
        ok = v != "refused"
        answered += ok
        right = _physical_right(ident, true) if v in ("ok", "weak") else None
        wrong += right is False
        pred = ident.prediction or {}
        gain = improvement(pred[ident.chosen], pred["defaults"]) if ident.chosen in pred and "defaults" in pred else math.nan
        rows.append({"table": "lake records of the model's structure, wind of another form (independent generator)",
                     "seed": seed, "wind": f"{env['wind_mps']:.1f} m/s {env['wind_form']}",
                     "current": f"{env['current_mps']:.2f} m/s" + (f" +- {env['current_variation_mps']:.2f}"
                                                                    if env["current_variation_mps"] else ""),
                     "verdict": v, "estimator": ident.estimator, "terms": ",".join(ident.terms) or "-",
                     "physical answer right": right,
                     "10-s prediction (m)": round(pred[ident.chosen].position_at_horizon_m, 3) if ident.chosen in pred else None,
                     "defaults (m)": round(pred["defaults"].position_at_horizon_m, 3) if "defaults" in pred else None,
                     "closer than the defaults": f"{100 * gain:.0f} %", "cpu_s": round(cpu, 1)})
    n = len(cases)
    rows.append({"table": "lake records of the model's structure, wind of another form (independent generator)",
                 "seed": "all", "verdict": f"{answered} of {n} answered", "physical answer right": wrong == 0,
                 "cpu_s": round(max(cpus), 1), "calm cpu_s (median, row 3)": round(calm_cpu_s, 2),
                 "cpu over calm": round(max(cpus) / calm_cpu_s, 1),
                 "target": f">= 90 % answered, no wrong physical answer, CPU <= {LAKE_OVER_CALM_CPU:.0f} x calm",
                 "pass": answered >= 0.9 * n and wrong == 0 and max(cpus) <= LAKE_OVER_CALM_CPU * calm_cpu_s})
    return rows


def fixed_rows(quick: bool = False) -> list[dict]:
    """The issue's case: the eight weakly determined coefficients fixed at the defaults."""
    from lotsen.harness.identification import lake_run
    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sysid.identify import identify, split_holdout
    from lotsen.sysid.problem import IdentificationProblem

    rows: list[dict] = []
    for seed in ((2500,) if quick else (2500, 1002, 1005)):
        lake = lake_run(seed) if seed != 2500 else lake_run(seed, current_mps=0.08, wind_mps=4.0)
        true = lake.boat
        fixed = {"m11": true.m11, **{n: getattr(DEFAULT_PARAMETERS, n) for n in WEAK_SET}}
        off = {n: 100 * (getattr(DEFAULT_PARAMETERS, n) / getattr(true, n) - 1) for n in WEAK_SET}
        est, val = split_holdout([lake.run.record], 0.2)
        t0 = time.process_time()
        ident = identify(IdentificationProblem(tuple(est), tuple(val), fixed, lake=True))
        cpu = time.process_time() - t0
        v = ident.verdict.verdict
        right = _physical_right(ident, true) if v in ("ok", "weak") else None
        named = ident.fixed_test.contradicted if ident.fixed_test is not None else []
        rows.append({"table": "eight weak coefficients fixed at the defaults (the old advice)", "seed": seed,
                     "fixed off by": f"{min(abs(x) for x in off.values()):.0f}-{max(abs(x) for x in off.values()):.0f} %",
                     "verdict": v, "fixed values contradicted": ", ".join(named) or "-",
                     "physical answer right": right, "cpu_s": round(cpu, 1),
                     "target": "never a wrong physical answer", "pass": right is not False})
    return rows


def repeated_records_rows(quick: bool = False) -> list[dict]:
    """Row 3 of the module docstring; then the same records with the yaw-rate offsets estimated
    (`--gyro-offset`, one per minute: lotsen's simulator walks the gyro's bias), shown, not judged."""
    from lotsen.harness.identification import lake_boat, lake_run
    from lotsen.sysid.estimate import SolverOptions
    from lotsen.sysid.identify import identify
    from lotsen.sysid.problem import IdentificationProblem, held_out_split

    boat = lake_boat(31)
    answers, offsets, cpus = [], [], []
    for seed in range(100, 106 if quick else 190):
        rec = lake_run(seed, 600.0, 0.0, 0.0, boat=boat).run.record
        est, val, src, _ = held_out_split([rec], None, 0.2)
        t0 = time.process_time()
        answers.append((seed, identify(IdentificationProblem(est, val, {"m11": boat.m11}, validation_source=src))))
        cpus.append(time.process_time() - t0)
        offsets.append((seed, identify(IdentificationProblem(est, val, {"m11": boat.m11}, validation_source=src,
                                                             solver=SolverOptions(gyro_bias=True)))))
    table = "intervals over repeated records: one boat of the model's structure, calm, 10 min each (ideal model)"
    shown = _interval_rows(table + ", with --gyro-offset (not judged)", offsets, boat, None)
    return _interval_rows(table, answers, boat, cpus) + [dict(r, role="peer") for r in shown]


def _interval_rows(table: str, answers: list, boat, cpus: list[float] | None) -> list[dict]:  # type: ignore[no-untyped-def]
    """Per coefficient: each record's error against its own reported sigma (row 3 of the module
    docstring); `cpus`: each identification's CPU seconds, if measured."""
    from lotsen.sysid.judge import CORE_PARAMETERS

    # only a physical answer states intervals of the boat's coefficients
    idents = [i for _, i in answers if i.verdict.verdict in ("ok", "weak")]
    other = [f"{seed} ({i.verdict.verdict})" for seed, i in answers if i.verdict.verdict not in ("ok", "weak")]
    rng = np.random.default_rng(47)
    rows: list[dict] = []
    inside = total = undetermined = 0
    for n in (idents[0].result.free_names if idents else ()):
        kept = [i for i in idents if n not in i.undetermined]
        undetermined += len(idents) - len(kept)
        if len(kept) < 3:
            continue
        v = np.array([getattr(i.result.params, n) for i in kept])
        sd = np.array([i.result.std[n] for i in kept])
        z = np.abs(v - getattr(boat, n)) / sd
        inside, total = inside + int(np.sum(z <= 3.0)), total + len(z)
        ratio = float(1.0 / np.sqrt(np.mean(z ** 2)))
        draws = rng.integers(0, len(v), (2000, len(v)))  # records resampled with replacement
        lo, hi = np.percentile(1.0 / np.sqrt(np.mean(z[draws] ** 2, axis=1)), [2.5, 97.5])
        core = n in CORE_PARAMETERS
        rows.append({"table": table, "coefficient": n, "records": len(kept), "reported / empirical std": round(ratio, 2),
                     "95 % interval of the ratio": f"{lo:.2f}-{hi:.2f}",
                     "pooled: RMS reported std / spread (not judged)": round(float(np.sqrt(np.mean(sd ** 2))
                                                                                   / np.std(v, ddof=1)), 2),
                     "reported std, widest / narrowest record": round(float(sd.max() / sd.min()), 1),
                     "largest error / sigma": round(float(z.max()), 1),
                     "RMS error % of the truth": round(100 * float(np.sqrt(np.mean((v / getattr(boat, n) - 1) ** 2))), 3),
                     "mean error %": round(100 * float(v.mean() / getattr(boat, n) - 1), 2),
                     "target": "0.8-1.25" if core else "(not a core coefficient)",
                     "pass": (0.8 <= ratio <= 1.25) if core else None})
    rows.append({"table": table, "coefficient": "all", "records": len(answers),
                 "truth within 3 sigma": f"{inside} of {total} ({100 * inside / max(total, 1):.1f} %)",
                 "undetermined (left out)": undetermined,
                 "not physical answers (left out)": ", ".join(other) or "none",
                 "verdicts": ", ".join(sorted({i.verdict.verdict for _, i in answers})),
                 "cpu_s (median)": round(float(np.median(cpus)), 2) if cpus else None,
                 "target": ">= 97 % within 3 sigma", "pass": inside >= 0.97 * total})
    return rows


def run(quick: bool = False) -> list[dict]:
    from bench_identify_waves import run as waves_rows  # 4. records in waves (its own module docstring)

    repeated = repeated_records_rows(quick)
    calm_cpu_s = next(r["cpu_s (median)"] for r in repeated if r.get("cpu_s (median)") is not None)
    return lake_rows(calm_cpu_s, quick) + fixed_rows(quick) + repeated + waves_rows(quick)
