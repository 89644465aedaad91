"""Identification in waves (issue 46 item 4): 10-min records in Hs 6 cm on lotsen's simulator, against
the same boat's calm records.

lotsen simulator, a boat of the model's structure (lotsen.harness.identification.lake_boat(seed): the
core eight 5-25 % off the defaults), 10 min of PRBS on all five inputs (lake_run, no current, no wind),
seeds 0-2: once in calm water, once in a JONSWAP wind sea Hs 6 cm, Tp 1.0 s from 250 deg (spreading
s=10; issue 46's 5 m/s over 500 m), and once in Hs 3 cm, Tp 0.8 s (4 m/s over 300 m). Each record
identified by `identify(problem)` (the path `lotsen identify` takes, m11 fixed at the boat's, the last
20 % held out; the records in waves also with --lake, whose current and wind can take up the waves'
drift), the problem given the record's sea state estimated from its own IMU
(lotsen.harness.identification.record_sea_state). Per record: the sea as estimated (Hs, Tp, from), the
verdict and the estimator written, the verdict the judge gives without the sea (what the sea rule
changed), whether a physical answer is right (issue 25's rule, as bench_identify: core within 5 %, the
rest within 15 % unless named weak, every coefficient within 3 sigma), the largest core error, and the 10-s open-loop prediction error of the written coefficients on a held-out CALM record
of the same boat (5 min, other PRBS inputs and noise), with its ratio to the calm record's answer.

The 6-DOF hull (tests/physics/hull6dof.py over the SITL-JSON seam, `lotsen experiment run --physics
... --out RUN.mcap`, the stack with its estimator and recorder, `identify RUN.mcap`; not in --quick):
seed 0, the same PRBS, calm, Hs 3 cm Tp 0.8 s and Hs 6 cm Tp 1.0 s from 250 deg (spreading 10), a 5-min
calm record with other inputs to judge on; m11 fixed at the default scale (14 kg), as the command does.

Targets (issue 46 "done when"): never a wrong physical answer; a `predictive` answer predicts the
held-out calm record at least as well as the calm record's answer (ratio <= 1).
"""

from __future__ import annotations

import math
import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

SEEDS = (0, 1, 2)
SEAS = {"calm": None, "Hs 6 cm": (0.06, 1.0), "Hs 3 cm": (0.03, 0.8)}
FROM_DEG = 250.0
TABLE = "10-min records in waves, lotsen simulator, boat of the model's structure (seeds 0-2)"


def _physical_right(ident, true) -> bool:  # type: ignore[no-untyped-def]
    """Issue 25's rule, as bench_identify judges physical answers (core within 5 %, the rest within 15 %
    unless named weak, every coefficient within 3 sigma)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_identify import _physical_right as right

    return right(ident, true)


def run(quick: bool = False) -> list[dict]:
    from dataclasses import replace

    from lotsen.harness.identification import lake_boat, lake_run, record_sea_state
    from lotsen.model.environment import Waves
    from lotsen.sysid.identify import identify
    from lotsen.sysid.judge import CORE_PARAMETERS, judge
    from lotsen.sysid.prediction import prediction_score
    from lotsen.sysid.problem import IdentificationProblem, held_out_split

    rows: list[dict] = []
    wrong = worse_predictive = 0
    for seed in SEEDS:
        boat = lake_boat(seed)
        val = lake_run(seed + 1000, 300.0, 0.0, 0.0, boat=boat).run.record  # held-out calm, other inputs
        calm_err = math.nan
        for sea_name, hs_tp in SEAS.items():
            waves = Waves(hs_tp[0], hs_tp[1], FROM_DEG) if hs_tp else None
            rec = lake_run(seed, 600.0, 0.0, 0.0, boat=boat, waves=waves).run.record
            sea = record_sea_state(rec)
            est, v, src, _ = held_out_split([rec], None, 0.2)
            for lake in ((False, True) if hs_tp else (False,)):
                problem = IdentificationProblem(est, v, {"m11": boat.m11}, validation_source=src, sea=sea, lake=lake)
                t0 = time.process_time()
                ident = identify(problem)
                cpu = time.process_time() - t0
                without = judge(replace(problem, sea=None), ident.estimates).verdict.verdict
                verdict = ident.verdict.verdict
                p = ident.result.params
                errs = {n: getattr(p, n) / getattr(boat, n) - 1 for n in CORE_PARAMETERS}
                worst = max(errs, key=lambda n: abs(errs[n]))
                right = _physical_right(ident, boat) if verdict in ("ok", "weak") else None
                if sea_name != "calm":
                    wrong += right is False
                err = prediction_score(p, [val]).position_at_horizon_m
                if sea_name == "calm":
                    calm_err = err
                ratio = err / calm_err if calm_err > 0 else math.nan
                if verdict == "predictive" and sea_name != "calm" and not ratio <= 1.0:
                    worse_predictive += 1
                reason = next((r for r in ident.verdict.reasons if "taken in waves" in r), "")
                rows.append({
                    "table": TABLE, "seed": seed, "model": "--lake" if lake else "calm water",
                    "sea (simulated)": sea_name if hs_tp is None else
                    f"{sea_name}, Tp {hs_tp[1]:g} s, from {FROM_DEG:.0f}",
                    "sea (from the record's IMU)": "calm" if sea is None or sea.hs_m < 0.02 else
                    f"Hs {100 * sea.hs_m:.1f} cm, Tp {sea.tp_s:.2f} s, from {sea.from_deg:.0f}",
                    "verdict": verdict, "without the sea rule": without, "estimator": ident.estimator,
                    "physical answer right": right, "largest core error": f"{worst} {100 * errs[worst]:+.1f} %",
                    "calm held-out 10-s error (m)": round(err, 3), "/ calm record's answer": round(ratio, 2),
                    "names the sea": bool(reason) if sea_name != "calm" else None, "cpu_s": round(cpu, 1)})
    if not quick:
        hull, hull_bad = hull_rows()
        rows += hull
        worse_predictive += hull_bad
    rows.append({"table": TABLE, "seed": "all", "verdict": f"in waves: {wrong} wrong physical answers, "
                 f"{worse_predictive} predictive answers worse than calm on calm data",
                 "target": "no wrong physical answer; predictive <= 1.0 x the calm answer on held-out calm data",
                 "pass": wrong == 0 and worse_predictive == 0})
    return rows


HULL_TABLE = "10-min records in waves, the 6-DOF hull over the seam (seed 0)"


def _hull_record(name: str, hs_tp: tuple[float, float] | None, duration_s: float, seed: int, folder: str) -> tuple:
    """A PRBS on the 6-DOF hull through the stack: (RUN.mcap path, the command's exit code, its words)."""
    import contextlib
    import io
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "physics"))
    from hull6dof import HullEnvironment
    from hull_server import HullServer

    from lotsen.cli.main import main

    exp = Path(folder) / f"{name}.yaml"
    exp.write_text(f"name: prbs\narea: {{size_m: [400, 400]}}\npieces:\n  - {{type: prbs, duration_s: {duration_s}, "
                   f"bit_s: 1.5, seed: {seed}, base: {{n_rps: 55}}, amplitude: {{alpha_deg: 25, nt_rps: 60, "
                   "n1_rps: 25, n2_rps: 25}}\n")
    env = (HullEnvironment(wave_hs_m=hs_tp[0], wave_tp_s=hs_tp[1], wave_from_deg=FROM_DEG, wave_spreading=10.0)
           if hs_tp else HullEnvironment())
    server = HullServer(environment=env, port=0)
    _, stop = server.serve_in_thread()
    out = Path(folder) / f"{name}.mcap"
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            rc = main(["experiment", "run", str(exp), "--physics", f"udp:127.0.0.1:{server.address[1]}",
                       "--out", str(out), "--seed", str(seed)])
    finally:
        stop.set()
    return out, rc, err.getvalue()


def hull_rows() -> tuple[list[dict], int]:
    import tempfile
    from dataclasses import replace

    from lotsen.harness.identification import record_sea_state
    from lotsen.logs.export import sysid_record
    from lotsen.model import DEFAULT_PARAMETERS
    from lotsen.sysid.identify import identify
    from lotsen.sysid.judge import judge
    from lotsen.sysid.prediction import prediction_score
    from lotsen.sysid.problem import IdentificationProblem, held_out_split

    rows: list[dict] = []
    worse = 0
    with tempfile.TemporaryDirectory() as folder:
        val_path, _, _ = _hull_record("val", None, 300.0, 1000, folder)
        val = sysid_record(val_path)
        defaults_err = prediction_score(DEFAULT_PARAMETERS, [val]).position_at_horizon_m
        calm_err = math.nan
        for sea_name, hs_tp in SEAS.items():
            path, rc, words = _hull_record(sea_name.replace(" ", "_"), hs_tp, 600.0, 0, folder)
            rec = sysid_record(path)
            aborted = next((ln.split("ABORTED: ")[1].rstrip(")") for ln in words.splitlines() if "ABORTED" in ln), "")
            sea = record_sea_state(rec)
            est, v, src, _ = held_out_split([rec], None, 0.2)
            problem = IdentificationProblem(est, v, {"m11": 14.0}, validation_source=src, sea=sea)
            t0 = time.process_time()
            try:
                ident = identify(problem)
            except Exception as exc:  # a record too short to identify: say so in the row
                rows.append({"table": HULL_TABLE, "seed": 0, "sea (simulated)": sea_name,
                             "record": f"{rec.duration_s:.0f} s" + (f" (aborted: {aborted[:80]})" if aborted else ""),
                             "verdict": f"error: {str(exc)[:80]}"})
                continue
            cpu = time.process_time() - t0
            without = judge(replace(problem, sea=None), ident.estimates).verdict.verdict
            err = prediction_score(ident.result.params, [val]).position_at_horizon_m
            if sea_name == "calm":
                calm_err = err
            ratio = err / calm_err if calm_err > 0 else math.nan
            if ident.verdict.verdict == "predictive" and sea_name != "calm" and not ratio <= 1.0:
                worse += 1
            rows.append({
                "table": HULL_TABLE, "seed": 0,
                "sea (simulated)": sea_name if hs_tp is None else f"{sea_name}, Tp {hs_tp[1]:g} s, from {FROM_DEG:.0f}",
                "record": f"{rec.duration_s:.0f} s" + (f" (aborted: {aborted[:80]})" if aborted else ""),
                "sea (from the record's IMU)": "calm" if sea is None or sea.hs_m < 0.02 else
                f"Hs {100 * sea.hs_m:.1f} cm, Tp {sea.tp_s:.2f} s, from {sea.from_deg:.0f}",
                "verdict": ident.verdict.verdict, "without the sea rule": without, "estimator": ident.estimator,
                "calm held-out 10-s error (m)": round(err, 3), "/ calm record's answer": round(ratio, 2),
                "defaults (m)": round(defaults_err, 3),
                "names the sea": any("taken in waves" in r for r in ident.verdict.reasons) if hs_tp else None,
                "cpu_s": round(cpu, 1)})
    return rows, worse
