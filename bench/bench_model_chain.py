"""The model-based chain on a boat that is not its model: identify the boat, then control it.

Every boat here differs from the default model: the lake boat (`lotsen.sim.DEFAULT_BOAT`,
coefficients 11-20 % away, plus a thrust dead band, weaker astern thrust, 30 ms latency, slower
ESCs and servos, an offset GNSS antenna) and boats with coefficients randomised 10-40 % away from
the defaults (seeded), with the lake boat's unmodelled effects.

Identification on lake records (`identification_rows`): `lotsen identify --lake` on 10-min PRBS
records (`lotsen.harness.identification.lake_run`: a boat 5-40 % off the defaults, m11 kept as the scale, a
constant current up to 0.1 m/s, gusty wind up to 5 m/s, the simulator's noisy asynchronous
sensors), 20 seeds (3 quick): per coefficient the error and the share of 3-sigma intervals holding
the truth; the answers (coverage, answers given, wrong answers: exit 0 with a coefficient outside the
done-when rule, `_coefficient_right`: core within 5 %, the rest within 15 % unless reported weak, all
within 3 sigma) against a peer, the same estimate without the average over two
gust models (its first, 2-s estimate alone with its sandwich covariance); and the issue's case (10 min, 0.08 m/s
current, 4 m/s gusty wind).

Tracking with three models on the same boat: the defaults (the prior), the boat's exact
coefficients, and the coefficients `lotsen identify` finds from designed experiments recorded on
that boat (the lab loop, `lotsen.harness.lab_loop`: `lotsen experiment run --sim --out RUN.mcap`, then `lotsen identify
RUN.mcap`, the scale fixed by m11 as a lab would from the weighed hull, the antenna position and
the astern/ahead thrust ratio given as measured on the hull) — unless identify refuses
them (its verdict: the record does not support the model), then the chain has no identified row. The tracking
table takes the lake boat and random boats the lab loop answers (16, and 18 in full); the lab-loop table
runs the loop on random boats 11-18 and reports every answer and refusal. Missions: the figure
eight on the EKF in 0.1 m/s current and 3 m/s wind (`lotsen mission ... --current 0.1,90
--wind 3,45`), several seeds. Targets (issue 25): the exact model tracks no worse than the
defaults; the identified model within 20 % of the exact model's cross-track RMS.

The same chain on a hull that is not built like the model at all (the independent 6-DOF hull of
tests/physics, over the physics seam, at 0.5-1.5 m/s and in tight turns) is bench/bench_hull.py.

    python bench/run.py model_chain      or      python bench/bench_model_chain.py [--quick]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from lotsen.harness.lab_loop import identify_on, track_with_model as mission


def _identify(lake):  # type: ignore[no-untyped-def]
    """`lotsen identify --lake` on the record (m11 fixed), and its peer: the first of its two
    estimates alone (2-s gust intervals; no average over the gust models)."""
    from lotsen.sysid.estimators import Estimate
    from lotsen.sysid.judge import physical_checks
    from lotsen.sysid.multiple import average_over_model_choice, estimate_lake_two_gust_models

    c0 = time.process_time()
    alone, other = estimate_lake_two_gust_models([lake.run.record], fixed={"m11": 14.0})
    res = average_over_model_choice(alone, other)
    cpu = time.process_time() - c0
    v = physical_checks(Estimate("output error", res, None, res.details))
    v_alone = physical_checks(Estimate("output error", alone, None, alone.details))
    return res, v.verdict, v.reasons, v.weakly_determined, cpu, alone, v_alone


def _coverage(results: list, boats: list) -> tuple[np.ndarray, np.ndarray, list[str]]:
    names = results[0][0].free_names
    errs, zs = [], []
    for (res, *_), boat in zip(results, boats):
        true = np.array([getattr(boat, n) for n in names])
        est = np.array([getattr(res.params, n) for n in names])
        sd = np.array([res.std[n] for n in names])
        errs.append((est - true) / np.abs(true))
        zs.append((est - true) / np.maximum(sd, 1e-300))
    return np.array(errs), np.array(zs), list(names)


def _answers_right(results: list, boats: list) -> list[bool]:
    """Per record (result, verdict, weakly determined names): every coefficient right by the
    done-when rule (`_coefficient_right`), whatever the verdict."""
    return [all(_coefficient_right(n, getattr(res.params, n), getattr(boat, n), res.std[n], weak)
                for n in res.free_names) for (res, _, weak), boat in zip(results, boats)]


def _summary(label: str, Z: np.ndarray, verdicts: list[str], right: list[bool], n_seeds: int,
             cpu: float | None) -> dict:
    cover = float(np.mean(np.abs(Z) <= 3.0))
    accepted = np.array([v != "refused" for v in verdicts])
    cover_acc = float(np.mean(np.abs(Z[accepted]) <= 3.0)) if accepted.any() else None
    # an answer given (exit 0) with a coefficient the done-when rule does not accept
    wrong = sum(1 for a, r in zip(accepted, right) if a and not r)
    return {"table": "identification on lake records: the answers", "estimate": label, "seeds": n_seeds,
            "within_3_sigma": round(cover, 3),
            "within_3_sigma_accepted": None if cover_acc is None else round(cover_acc, 3),
            "answered": int(accepted.sum()), "wrong_answers": wrong,
            "verdicts": ", ".join(f"{v}: {verdicts.count(v)}" for v in ("ok", "weak", "refused")),
            "cpu_s_per_record": None if cpu is None else round(cpu, 1)}


def _coefficient_right(name: str, estimate: float, true: float, std: float, weak: Sequence[str]) -> bool:
    """Issue 25's bar for one coefficient of an answer: within 3 reported sigma, and within 5 % for the
    core eight, 15 % for the rest unless identify named it weakly determined."""
    from lotsen.sysid.judge import CORE_PARAMETERS

    bound = 0.05 if name in CORE_PARAMETERS else (None if name in weak else 0.15)
    return abs(estimate - true) <= 3 * std and (bound is None or abs(estimate - true) <= bound * abs(true))


def identification_rows(quick: bool = False) -> list[dict]:
    from lotsen.harness.identification import lake_run
    from lotsen.sysid.judge import CORE_PARAMETERS

    rows: list[dict] = []
    n_seeds = 3 if quick else 20
    checked, alone, boats_, cpus = [], [], [], []
    for k in range(n_seeds):
        lake = lake_run(1000 + k)
        res, verdict, _, weak, cpu, res1, v1 = _identify(lake)
        checked.append((res, verdict, weak))
        alone.append((res1, v1.verdict, v1.weakly_determined))
        boats_.append(lake.boat)
        cpus.append(cpu)
    E, Z, names = _coverage(checked, boats_)
    for j, n in enumerate(names):
        rows.append({"table": "identification on lake records, per coefficient", "parameter": n,
                     "core": n in CORE_PARAMETERS, "seeds": n_seeds,
                     "mean_abs_err_pct": round(100 * float(np.mean(np.abs(E[:, j]))), 1),
                     "max_abs_err_pct": round(100 * float(np.max(np.abs(E[:, j]))), 1),
                     "within_3_sigma": round(float(np.mean(np.abs(Z[:, j]) <= 3.0)), 2)})
    _, Z1, _ = _coverage(alone, boats_)
    peer = _summary("peer: one gust model (2-s intervals), sandwich covariance", Z1, [v for _, v, _ in alone],
                    _answers_right(alone, boats_), n_seeds, None)  # timed with the pair
    ours = _summary("lotsen identify --lake (2-s and 3-s gust intervals, averaged)", Z,
                    [v for _, v, _ in checked], _answers_right(checked, boats_), n_seeds, float(np.mean(cpus)))
    ours["target"] = ">= 95 % within 3 sigma (all, and answers given); no wrong answer"
    ours["pass"] = bool(ours["within_3_sigma"] >= 0.95 and (ours["within_3_sigma_accepted"] or 1.0) >= 0.95
                        and ours["wrong_answers"] == 0)
    rows += [peer, ours]
    # the done-when case
    lake = lake_run(2500, current_mps=0.08, wind_mps=4.0)
    res, verdict, reasons, weak, cpu, _, _ = _identify(lake)
    ok_all = True
    for n in res.free_names:
        t, v, s = getattr(lake.boat, n), getattr(res.params, n), res.std[n]
        err = 100 * (v - t) / abs(t)
        rel_sigma = 100 * s / max(abs(v), 1e-300)
        good = _coefficient_right(n, v, t, s, weak)
        ok_all &= good
        rows.append({"table": "done-when: 10 min, 0.08 m/s current, 4 m/s gusty wind", "parameter": n,
                     "core": n in CORE_PARAMETERS, "err_pct": round(err, 1), "rel_sigma_pct": round(rel_sigma, 1),
                     "err_over_sigma": round((v - t) / max(s, 1e-300), 2), "weak": n in weak, "pass": bool(good)})
    rows.append({"table": "done-when: 10 min, 0.08 m/s current, 4 m/s gusty wind", "parameter": "ALL",
                 "verdict": verdict, "reasons": "; ".join(reasons), "cpu_s": round(cpu, 1),
                 "target": "core within 5 %, rest within 15 % or weak (<= 4), all within 3 sigma; or refused",
                 "pass": bool(ok_all and verdict != "refused") or verdict == "refused",
                 "answer_given": verdict != "refused"})
    return rows


LAB_LOOP_BOATS = tuple(range(11, 19))  # random boats 10-40 % off the defaults, through the lab loop
_lab_loop: dict[str, tuple] = {}
_missions: dict[tuple[str, str, int], dict] = {}


def identified_on(boat) -> tuple:  # type: ignore[no-untyped-def]
    """`identify_on(boat)` once per bench run: the tracking and the lab-loop tables share the answer."""
    if boat.name not in _lab_loop:
        with tempfile.TemporaryDirectory(prefix="lotsen-chain-") as tmp:
            _lab_loop[boat.name] = identify_on(boat, Path(tmp))
    return _lab_loop[boat.name]


def tracked(boat, model: str, params, seed: int) -> dict:  # type: ignore[no-untyped-def]
    """The mission of `boat` with `params` (named `model`: defaults, exact, identified), once per run."""
    key = (boat.name, model, seed)
    if key not in _missions:
        _missions[key] = mission(boat, params, seed)
    return _missions[key]


def lab_loop_rows(quick: bool = False) -> list[dict]:
    """The lab loop (designed battery on the simulated stack -> `lotsen identify`) on random boats
    10-40 % off the defaults with the lake boat's unmodelled effects, every one of LAB_LOOP_BOATS:
    the answer or the refusal, and for an answer whether it is right (core within 5 %, the rest
    within 15 % or named weak, all within 3 sigma) and what it tracks (figure eight, EKF, current
    and wind, seed 0) against the exact model. A refusal is an honest outcome, a wrong answer is not."""
    from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
    from lotsen.sim import parameter_mismatch, random_boat
    from lotsen.sysid.judge import CORE_PARAMETERS

    table = "the lab loop on random boats 10-40 % off the defaults (battery -> identify -> track)"
    rows: list[dict] = []
    answered = wrong = tracked_ok = 0
    for seed in LAB_LOOP_BOATS:
        boat = random_boat(seed)
        identified, ident = identified_on(boat)
        raw = VesselParameters(**{k: float(ident[k]) for k in DEFAULT_PARAMETERS.to_dict()})
        err = parameter_mismatch(raw, boat.parameters)
        weak = ident.get("identification", {}).get("weakly_determined", [])
        std = ident.get("std", {})
        z = {n: (ident[n] - getattr(boat.parameters, n)) / s for n, s in std.items() if s > 0}
        core_err = max(abs(err[n]) for n in CORE_PARAMETERS) * 100
        other_err = max((abs(err[n]) for n in std if n not in CORE_PARAMETERS and n not in weak), default=0.0) * 100
        row = {"table": table, "boat": boat.name, "verdict": ident.get("verdict"),
               "reasons": "; ".join(r.split(":")[0] for r in ident.get("identification", {}).get("reasons", [])),
               "weak": ",".join(weak), "core_err_max_pct": round(core_err, 1),
               "other_err_max_pct": round(other_err, 1), "z_max": round(max(abs(v) for v in z.values()), 1)}
        if identified is not None:
            answered += 1
            right = all(_coefficient_right(n, ident[n], getattr(boat.parameters, n), s, weak) for n, s in std.items())
            wrong += not right
            exact = tracked(boat, "exact", boat.parameters, 0)["cross_track_rms_m"] * 100
            ident_cm = tracked(boat, "identified", identified, 0)["cross_track_rms_m"] * 100
            tracked_ok += ident_cm <= 1.2 * exact
            row.update(answer_right=right, exact_cm=round(exact, 2), identified_cm=round(ident_cm, 2))
            row["pass"] = right and ident_cm <= 1.2 * exact
        else:
            row["pass"] = True  # refused: nothing wrong was said
        rows.append(row)
    rows.append({"table": table, "boat": f"all {len(LAB_LOOP_BOATS)}", "answered": answered, "wrong_answers": wrong,
                 "identified_within_20_pct_of_exact": tracked_ok,
                 "target": "no wrong answer; every answer tracks within 1.2 x the exact model",
                 "pass": wrong == 0 and tracked_ok == answered})
    return rows


def boats(quick: bool) -> list:
    from lotsen.sim import DEFAULT_BOAT, random_boat

    # the lake boat and boats the lab loop answers (lab_loop_rows shows which it refuses, and why)
    return [DEFAULT_BOAT] + [random_boat(seed) for seed in ((16,) if quick else (16, 18))]


def tracking_rows(quick: bool = False) -> list[dict]:
    from lotsen.model import DEFAULT_PARAMETERS, VesselParameters
    from lotsen.sim import parameter_mismatch

    seeds = (0,) if quick else (0, 1, 2)
    rows: list[dict] = []
    for boat in boats(quick):
        identified, ident = identified_on(boat)
        models = {"defaults": DEFAULT_PARAMETERS, "exact": boat.parameters}
        if identified is not None:
            models["identified"] = identified
        mismatch = parameter_mismatch(boat.parameters, DEFAULT_PARAMETERS)
        raw = VesselParameters(**{k: float(ident[k]) for k in DEFAULT_PARAMETERS.to_dict()})  # even if refused
        id_err = parameter_mismatch(raw, boat.parameters)
        cte: dict[str, list[float]] = {k: [] for k in models}
        cte.setdefault("identified", [])
        for seed in seeds:
            for name, params in models.items():
                m = tracked(boat, name, params, seed)
                cte[name].append(m["cross_track_rms_m"] * 100)
                rows.append({"table": "tracking by model on a boat that is not its model (figure eight, EKF, "
                                      "current 0.1 + wind 3)",
                             "boat": boat.name, "model": name, "seed": seed, "completed": m["completed"],
                             "cross_track_rms_cm": round(m["cross_track_rms_m"] * 100, 2),
                             "cross_track_max_cm": round(m["cross_track_max_m"] * 100, 2),
                             "speed_error_rms_mps": m["speed_error_rms_mps"],
                             "reversals_per_s": m.get("reversals_per_s"),
                             "failsafes": ",".join(m.get("failsafes_triggered", [])) or "none"})
        exact = statistics.mean(cte["exact"])
        ident_cm = statistics.mean(cte["identified"]) if cte.get("identified") else None
        rows.append({"table": "the chain's verdict per boat (mean over seeds)", "boat": boat.name,
                     "boat_vs_defaults_pct": f"{min(abs(v) for v in mismatch.values()) * 100:.0f}-"
                                             f"{max(abs(v) for v in mismatch.values()) * 100:.0f}",
                     "identify_verdict": ident.get("verdict"),
                     "identify_reasons": "; ".join(r.split(":")[0] for r in ident.get("identification", {})
                                                   .get("reasons", [])),
                     "identified_error_max_pct": round(max(abs(v) for v in id_err.values()) * 100, 1),
                     "defaults_cm": round(statistics.mean(cte["defaults"]), 2), "exact_cm": round(exact, 2),
                     "identified_cm": None if ident_cm is None else round(ident_cm, 2),
                     "target": "exact <= defaults; identified <= 1.2 x exact",
                     "pass": exact <= statistics.mean(cte["defaults"]) * 1.0001
                     and ident_cm is not None and ident_cm <= 1.2 * exact})
    return rows


MODEL_ERRORS = (0.0, 0.05, 0.10, 0.15, 0.25)


def model_quality_rows(quick: bool = False) -> list[dict]:
    """Issue 25 item 3: tracking against model error on the lake boat. The controller's and the EKF's
    model is the boat's coefficients each scaled by (1 +- e), random signs per seed; e = 0 is the exact
    model. Targets: tracking no better as e grows (mean over seeds, within the seeds' spread), with 25 %
    within 1.5x the exact model's; <= 0.7 cm and <= 0.1 reversals/s with the exact model. The end points
    (exact, 25 %) again on seeds 0-8: the spread of a 1.5x bar over draws of the error signs."""
    from lotsen.sim import DEFAULT_BOAT
    from lotsen.sim.boat import scaled_parameters

    boat = DEFAULT_BOAT
    # the whole sweep in quick mode too: 15 missions, ~3 min of CPU (the identification is what is long)
    seeds = (0, 1, 2)
    errors = MODEL_ERRORS
    rows: list[dict] = []
    mean: dict[float, float] = {}
    spread: dict[float, float] = {}
    per_seed: dict[float, list[float]] = {}  # cross-track RMS (cm) per seed, in the order of `seeds`

    def run_at(e: float, seed: int) -> dict:  # the mission with the model e off, signs drawn by seed
        params = scaled_parameters(boat.parameters, e, np.random.default_rng(1000 + seed))
        return mission(boat, params, seed)

    for e in errors:
        cte, rev, fs = [], [], []
        for seed in seeds:
            m = run_at(e, seed)
            cte.append(m["cross_track_rms_m"] * 100)
            rev.append(m["reversals_per_s"])
            fs += m.get("failsafes_triggered", [])
        per_seed[e] = cte
        mean[e] = statistics.mean(cte)
        spread[e] = statistics.stdev(cte) / len(cte) ** 0.5 if len(cte) > 1 else 0.0
        rows.append({"table": "tracking against model error (lake boat, figure eight, EKF, current 0.1 + wind 3)",
                     "model_error_pct": round(e * 100), "seeds": len(seeds),
                     "cross_track_rms_cm": [round(v, 2) for v in cte], "mean_cm": round(mean[e], 3),
                     "reversals_per_s_max": round(max(rev), 3), "failsafes": ",".join(sorted(set(fs))) or "none"})
    es = sorted(mean)
    # no better as the model gets worse: each level's mean at least the previous minus the standard
    # error of the two means (missions on the EKF differ by seed by ~0.05 cm)
    monotone = all(mean[b] >= mean[a] - (spread[a] ** 2 + spread[b] ** 2) ** 0.5 for a, b in zip(es, es[1:]))
    rows.append({"table": "model-quality verdict", "exact_cm": round(mean[0.0], 3),
                 "worst_cm": round(mean[es[-1]], 3), "ratio_worst_to_exact": round(mean[es[-1]] / mean[0.0], 2),
                 "monotone": monotone,
                 "target": "no better with a worse model; 25 % within 1.5x exact; exact <= 0.7 cm",
                 "pass": monotone and mean[es[-1]] <= 1.5 * mean[0.0] and mean[0.0] <= 0.7})
    # the same two end points on more draws of the error signs: three seeds do not settle a 1.5x bar
    # (single missions at 25 % move by up to 0.5 cm with small weight changes)
    more = (3, 4, 5, 6, 7, 8)
    wide = {e: per_seed[e] + [run_at(e, seed)["cross_track_rms_m"] * 100 for seed in more]
            for e in (0.0, 0.25)}
    ex, wr = statistics.mean(wide[0.0]), statistics.mean(wide[0.25])
    rows.append({"table": "model-quality verdict on seeds 0-8 (exact and 25 % only)", "seeds": len(wide[0.0]),
                 "exact_cm": round(ex, 3), "error_25_cm": round(wr, 3), "ratio": round(wr / ex, 2),
                 "worst_seed_ratio": round(max(w / x for w, x in zip(wide[0.25], wide[0.0])), 2),
                 "target": "25 % within 1.5x exact; exact <= 0.7 cm", "pass": wr <= 1.5 * ex and ex <= 0.7})
    return rows


def defaults_vs_exact_rows(quick: bool = False) -> list[dict]:
    """Issue 25's done-when without identification: on boats 10-40 % from the defaults (randomised,
    seeded, with the lake boat's unmodelled effects) the exact model tracks no worse than the defaults."""
    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sim import random_boat

    rows: list[dict] = []
    for boat_seed in ((21, 22) if quick else (21, 22, 23)):
        boat = random_boat(boat_seed)
        res = {name: mission(boat, p, boat_seed) for name, p in
               (("defaults", DEFAULT_PARAMETERS), ("exact", boat.parameters))}
        rows.append({"table": "exact model against the defaults on randomised boats (figure eight, EKF, "
                              "current 0.1 + wind 3)", "boat": boat.name,
                     "defaults_cm": round(res["defaults"]["cross_track_rms_m"] * 100, 2),
                     "exact_cm": round(res["exact"]["cross_track_rms_m"] * 100, 2),
                     "reversals_per_s": [res[k]["reversals_per_s"] for k in ("defaults", "exact")],
                     "failsafes": ",".join(sorted({*res["defaults"]["failsafes_triggered"],
                                                   *res["exact"]["failsafes_triggered"]})) or "none",
                     "target": "exact <= defaults",
                     "pass": res["exact"]["cross_track_rms_m"] <= res["defaults"]["cross_track_rms_m"]})
    return rows


def run(quick: bool = False) -> list[dict]:
    return (identification_rows(quick) + model_quality_rows(quick) + defaults_vs_exact_rows(quick)
            + tracking_rows(quick) + lab_loop_rows(quick))


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)
