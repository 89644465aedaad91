"""Where the model matters: the lab loop and tracking on the independent 6-DOF hull (issue 39 items 7, 8).

The hull is `tests/physics/hull6dof.py`: a 0.99 m, 13 kg Fossen-style 6-DOF plant that imports
nothing of lotsen's model (added mass and Coriolis, strip-theory cross-flow drag, roll and pitch,
thrust falling with advance speed, a bow thruster fading with speed, lags and rate limits; its own
current, per-axis wind drag, gusts and a wandering wind direction). No coefficient set of lotsen's
3-DOF model is this hull, so identification can at best answer `predictive` (effective
coefficients), and the question is what such a model is worth in closed loop.

1. The lab loop, as a user runs it (every step a `lotsen` command in a temporary folder; CPU is the
   command's, wall clock beside it): `lotsen experiment design --duration 60 --area 30x30` (quick:
   `--iterations 6 --robust-samples 1`, a cheaper design of the same form); the designed experiment
   and, for validation, examples/experiments/prbs_multisine.yaml (66 s, `--seed 1`) run on the hull
   over the seam (`lotsen experiment run ... --physics udp:...` against tests/physics/hull_server.py,
   calm water); `lotsen identify designed.mcap --validate validation.mcap --fix m11=14.2
   --reverse-thrust-ratio 0.75 --out first.json` (m11 as a user gets it: the weighed 13 kg plus the
   surge added mass, 1.2 kg for this hull; astern/ahead thrust from a bollard pull: 0.75); a second
   design for that first answer (`--params first.json`: what an experiment teaches depends on the
   boat), run (`--seed 2 --params first.json`: the run's area check predicts with the model the design
   is for), and `lotsen identify designed.mcap designed2.mcap --validate
   validation.mcap --in-use first.json ... --out identified.json` on both records; refused (effective
   coefficients no better than the first answer's) the first answer stays, as the README's lab loop
   has it; then `lotsen mission` on the
   figure eight at 1.0 m/s over the seam in current and wind (hull_server.py `--current 0.08,30
   --wind 4,250 --gusts 0.2 --wander 15`), with the defaults and with `--params identified.json`. A
   60-s design holds one 10-s prediction window in its last 20 % (identify refuses to judge effective
   coefficients on fewer than 10), hence the second record for validation, as identify advises.
   1b/1c (issue 47's bar, measured as bench_hull_b.py measures it on hull B): the fastest figure eight
   the planner flies (every node at its speed_max_mps, 1.5 m/s; the lobes capped by its lateral limit:
   the speed as flown is shown), over the seam in the same lake, defaults and the loop's answer, seeds
   0-3 (quick: 0) with a fresh server per mission. Target: every mission completes without a failsafe
   and the answer tracks <= 0.8 x the defaults' cross-track RMS (mean over the seeds). 1d (full mode,
   info): the lab loop three times more, its estimation runs with other sensor noise (`--seed` 15/11,
   25/21, 35/31), each answer flown as in 1b: how much of 1c's figure is one loop's luck.
2. Tracking (in-process `HullPlant`, lotsen's sensors, EKF and MPC; the same missions as over the
   protocol, compared once in table 1): the figure eight (40 m) at nominal 0.5, 1.0 and 1.5 m/s with
   the planner's defaults (lateral acceleration <= 0.3 m/s^2 caps the lobes: the planned mean speed is
   shown), and tighter turns with the planner's lateral limit at 0.8 m/s^2 (the hull turns at over
   1 m/s^2): the figure eight at 1.5 m/s, and scaled to half (20 m, turn radii down to 1.1 m) at
   1.0 m/s. Current 0.08 m/s towards 30 deg, wind 4 m/s from 250 deg with 20 % gusts and a 15-deg
   wandering direction; seeds 0 and 1, the judged cases at >= 1.2 m/s seeds 0-3 (issue 47's >= 4 seeds:
   on two, seed 0's bad luck decided the mean; quick: seed 0 and fewer cases). Models: the defaults, the lab
   loop's answer, and (full mode) the answers from the 10-min calm and lake records below. Target
   (issue 39): at nominal >= 1.2 m/s the lab loop's model tracks >= 20 % better than the defaults.
3. Identification records (`hull6dof.record`, a 10-min PRBS on all five channels, lotsen's lake
   record format; quick: 5 min), two calm and two lake (current and wind as above; seeds 1 and 2):
   `lotsen identify REC.csv [--lake] --fix m11=14.2 --reverse-thrust-ratio 0.75`, its verdict, its
   10-s prediction of the held-out 20 % against the defaults' (targets >= 40 % better calm, >= 30 %
   lake), the two records' coefficients within 3 combined sigma (target >= 90 %), and CPU: of
   `lotsen.sysid.identify.identify` alone and of the whole command (targets <= 5 s calm, <= 20 s
   lake, for the identification).

    python bench/run.py hull [--quick]      or      python bench/bench_hull.py [--quick]
"""

from __future__ import annotations

import json
import math
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
PHYSICS = REPO / "tests" / "physics"
sys.path.insert(0, str(PHYSICS))

#: the water and air of the missions and the lake records (issue 39's lake case)
CURRENT = (0.08, 30.0)  # m/s, towards deg
WIND = (4.0, 250.0)  # m/s, from deg
GUSTS, WANDER_DEG = 0.2, 15.0
#: what a lab measures on the hull: the scale (weighed mass + surge added mass) and a bollard pull
REVERSE_THRUST_RATIO = 0.75

# `lotsen identify` as the console script runs it, with the CPU of lotsen.sysid.identify.identify alone
# and of the whole process (start-up and imports included) reported on the last line of stderr
_TIMED_IDENTIFY = r"""
import json, resource, sys

def cpu():
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime

from lotsen.cli.main import single_threaded_blas
single_threaded_blas()  # as `lotsen identify` does, before this script's import of numpy below
import lotsen.cli.identify as cli
spent = []
if hasattr(cli, "identify"):
    inner = cli.identify
    def timed(*a, **k):
        c0 = cpu()
        try:
            return inner(*a, **k)
        finally:
            spent.append(cpu() - c0)
    cli.identify = timed
from lotsen.cli.main import main
rc = main(sys.argv[1:])
print("BENCH_CPU " + json.dumps({"identify_s": sum(spent) if spent else None, "command_s": cpu()}), file=sys.stderr)
sys.exit(rc)
"""


def hull_m11() -> float:
    """m11 as a user gets it for this hull: the weighed mass plus the surge added mass (the fixture's
    own numbers: 13 kg + 1.2 kg). On a real hull the added mass is 5-10 % of the mass for a slender
    hull (e.g. from a strip-theory or empirical formula); docs/sysid.md."""
    from hull6dof import HullParameters

    p = HullParameters()
    return round(p.mass_kg + p.added_mass[0], 3)


def _children_cpu() -> float:
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return c.ru_utime + c.ru_stime


def lotsen(*args: str, cwd: Path) -> tuple[int, str, float, float]:
    """`lotsen ARGS` in `cwd`: exit code, stderr, CPU seconds, wall seconds."""
    c0, t0 = _children_cpu(), time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "lotsen", *args], cwd=cwd, capture_output=True, text=True)
    return p.returncode, p.stderr, _children_cpu() - c0, time.perf_counter() - t0


def timed_identify(*args: str, cwd: Path) -> tuple[int, str, dict]:
    """`lotsen identify ARGS`: exit code, stderr, {"identify_s", "command_s"} CPU seconds."""
    p = subprocess.run([sys.executable, "-c", _TIMED_IDENTIFY, "identify", *args], cwd=cwd, capture_output=True,
                       text=True)
    m = re.search(r"^BENCH_CPU (.*)$", p.stderr, re.M)
    return p.returncode, p.stderr, json.loads(m.group(1)) if m else {}


@contextmanager
def hull_server(*args: str, realtime: bool = False) -> Iterator[str]:
    """tests/physics/hull_server.py on a free port: its address udp:127.0.0.1:PORT. `realtime`: for a live
    run at wall-clock pace (its `--realtime`)."""
    proc = subprocess.Popen([sys.executable, str(PHYSICS / "hull_server.py"), "--port", "0", *args,
                             *(["--realtime"] if realtime else [])],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        line = proc.stdout.readline() if proc.stdout else ""
        m = re.search(r"listening on (udp:\S+)", line)
        if not m:
            raise RuntimeError(f"hull_server.py did not start: {line!r}")
        yield m.group(1)
    finally:
        proc.terminate()
        proc.wait(10)


def lake_server_args(seed: int = 0) -> list[str]:
    return ["--current", f"{CURRENT[0]},{CURRENT[1]}", "--wind", f"{WIND[0]},{WIND[1]}", "--gusts", str(GUSTS),
            "--wander", str(WANDER_DEG), "--seed", str(seed)]


def lake_environment(seed: int) -> Any:
    from hull6dof import HullEnvironment

    return HullEnvironment(current_mps=CURRENT[0], current_to_deg=CURRENT[1], wind_mps=WIND[0], wind_from_deg=WIND[1],
                           gust_fraction=GUSTS, wind_wander_deg=WANDER_DEG, seed=seed)


# ------------------------------------------------------------------------------------------------
# routes

def figure_eight(speed_mps: float, scale: float = 1.0) -> dict:
    """examples/routes/figure_eight.yaml at `speed_mps`, scaled about its crossing by `scale`."""
    from lotsen.files import read_yaml

    route = read_yaml(REPO / "examples" / "routes" / "figure_eight.yaml")

    def s(v: float) -> float:
        return round(20.0 + scale * (v - 20.0), 3)

    route["harbour"] = dict(route["harbour"], north=s(route["harbour"]["north"]), east=s(route["harbour"]["east"]))
    route["nodes"] = [dict(n, north=s(n["north"]), east=s(n["east"]), speed_mps=speed_mps) for n in route["nodes"]]
    return route


#: (case, route scale, nominal speed m/s, planner lateral acceleration limit m/s^2)
CASES = (("figure eight 40 m, 0.5 m/s", 1.0, 0.5, 0.3),
         ("figure eight 40 m, 1.0 m/s", 1.0, 1.0, 0.3),
         ("figure eight 40 m, 1.5 m/s", 1.0, 1.5, 0.3),
         ("tight: figure eight 40 m, 1.5 m/s, a_lat 0.8", 1.0, 1.5, 0.8),
         ("tight: figure eight 20 m, 1.0 m/s, a_lat 0.8", 0.5, 1.0, 0.8))
QUICK_CASES = (CASES[0], CASES[2], CASES[4])


def planned(scale: float, speed_mps: float, a_lat_mps2: float) -> Any:
    from lotsen.planning import PlannerConfig, plan_route
    from lotsen.planning.io import route_from_dict

    return plan_route(route_from_dict(figure_eight(speed_mps, scale)), PlannerConfig(a_lat_max_mps2=a_lat_mps2))


_missions: dict[tuple, dict] = {}


def fly(case: tuple, model_name: str, params: Any, seed: int) -> dict:
    """The mission of `case` on the hull with `params` (None: the defaults), in current and wind, on the
    EKF; once per bench run."""
    key = (case[0], model_name, seed)
    if key not in _missions:
        import numpy as np
        from hull_plant import fly_path

        from lotsen.model import VesselModel

        _, scale, speed, a_lat = case
        path = planned(scale, speed, a_lat)
        res = fly_path(path, VesselModel(params) if params is not None else VesselModel(),
                       environment=lake_environment(seed), seed=seed)
        m = dict(res.metrics)
        follow = res.mode == "follow"
        m["speed_mean_mps"] = round(float(np.mean(res.speed_mps[follow])), 3) if follow.any() else None
        m["planned_mean_mps"] = round(float(np.mean(path.speed_mps)), 3)
        _missions[key] = m
    return _missions[key]


# ------------------------------------------------------------------------------------------------
# 1. the lab loop through the commands

def _prediction(out: dict) -> tuple[str | None, float | None, float | None]:
    """(the model written, its 10-s held-out position error, the defaults'), from a parameter file."""
    pred = out.get("prediction") or {}
    models = pred.get("models", {})
    chosen = pred.get("chosen")

    def at10(name: str | None) -> float | None:
        return (models.get(name) or {}).get("position_rms_m", {}).get("10") if name else None

    return chosen, at10(chosen), at10("defaults")


def _reasons(out: dict) -> str:
    """The verdict's reasons, each cut to its first clause (a predictive answer prefixes every physical
    reason with "not the hull's physical coefficients: ")."""
    out_ = []
    for r in out.get("identification", {}).get("reasons", []):
        r = r.removeprefix("not the hull's physical coefficients: ")
        out_.append(re.split(r"[:(]", r, maxsplit=1)[0].strip())
    return "; ".join(out_)


def step_row(table: str, name: str, command: str, rc: int, cpu: float, wall: float, **extra: Any) -> dict:
    """One command of a lab loop as a row of `table`."""
    return {"table": table, "step": name, "command": command, "exit": rc, "cpu_s": round(cpu, 1),
            "wall_s": round(wall, 1), **extra}


def lab_identify(work: Path, quick: bool, table: str, m11: float, reverse_thrust_ratio: float,
                 server: tuple[str, ...] = (), record_seeds: tuple[int, int] = (0, 2)
                 ) -> tuple[list[dict], dict | None, Any]:
    """The lab loop up to the model, through the commands (module docstring, 1), as the README runs it: a
    design at the defaults, it and the validation experiment run on the hull over the seam
    (hull_server.py `server` flags, calm, seed 0), identify with the lab's m11 and bollard-pull ratio
    (first.json); a second design for that first answer (`--params first.json`: the information an
    experiment gives depends on the boat), run, and identify on both records (identified.json). Returns
    the rows of `table`, the final parameter file ({} without one; None when a step before identify
    failed) and its parameters (None when identify refused or did not run). `record_seeds`: the two
    estimation runs' `--seed` (lotsen's sensor noise); the validation run's is 1."""
    from lotsen.stack.stack import load_parameters

    rows: list[dict] = []
    validation = str(REPO / "examples" / "experiments" / "prbs_multisine.yaml")
    lab = ["--validate", "validation.mcap", "--fix", f"m11={m11:g}", "--reverse-thrust-ratio", f"{reverse_thrust_ratio:g}"]
    records: list[str] = []
    out: dict = {}
    rc = first_rc = 1
    for k, (designed, record, answer) in enumerate((("designed.yaml", "designed.mcap", "first.json"),
                                                    ("designed2.yaml", "designed2.mcap", "identified.json"))):
        design = ["experiment", "design", "--duration", "60", "--area", "30x30", "--out", designed]
        if k and first_rc == 0:  # for the first answer (a refused one: the defaults again)
            design += ["--params", "first.json"]
        if quick:
            design += ["--iterations", "6", "--robust-samples", "1"]
        rc, err, cpu, wall = lotsen(*design, cwd=work)
        summary = err.strip().splitlines()[-1] if err.strip() else ""
        rows.append(step_row(table, "design" if k == 0 else "design again (for the first answer)", "lotsen " + " ".join(design),
                             rc, cpu, wall, result=summary.split(": ", 1)[-1][:160]))
        if rc != 0:
            return rows, None, None
        # the second design is for first.json: its run's area check and estimator use it (--params)
        runs = [("run (estimation)" if k == 0 else "run (estimation, second design)", designed, record,
                 ["--seed", str(record_seeds[k])] + (["--params", "first.json"] if k and first_rc == 0 else []))]
        if k == 0:
            runs.append(("run (validation)", validation, "validation.mcap", ["--seed", "1"]))
        with hull_server(*server, "--seed", "0") as address:
            for name, exp, rec, extra in runs:
                args = ["experiment", "run", exp, "--physics", address, "--out", rec, *extra]
                rc, err, cpu, wall = lotsen(*args, cwd=work)
                rows.append(step_row(table, name, "lotsen " + " ".join(args).replace(str(REPO) + "/", ""), rc, cpu, wall,
                                     result=(err.strip().splitlines() or [""])[-1][:160]))
                if rc != 0:
                    return rows, None, None
        records.append(record)
        # the second answer must predict better than the first (--in-use), else the first stays the answer
        ident = [*records, *lab, "--out", answer] + (["--in-use", "first.json"] if k and first_rc == 0 else []) \
            + (["--report", "report.html"] if k else [])
        t0 = time.perf_counter()
        rc, err, cpu = timed_identify(*ident, cwd=work)
        wall = time.perf_counter() - t0
        out = json.loads((work / answer).read_text()) if (work / answer).is_file() else {}
        chosen, p10, d10 = _prediction(out)
        rows.append(step_row(table, "identify" if k == 0 else "identify (both records)", "lotsen identify " + " ".join(ident),
                             rc, cpu.get("command_s", math.nan), wall, verdict=out.get("verdict"), written=chosen,
                             pred_10s_m=p10, defaults_10s_m=d10,
                             better_than_defaults_pct=round(100 * (1 - p10 / d10)) if p10 and d10 else None,
                             identify_cpu_s=round(cpu["identify_s"], 1) if cpu.get("identify_s") is not None else None,
                             result=_reasons(out)[:300]))
        if k and rc == 1 and first_rc == 0:  # refused against the first answer: keep it, as the README does
            shutil.copy(work / "first.json", work / "identified.json")
            out = json.loads((work / "identified.json").read_text())
            rows.append(step_row(table, "keep the first answer", "cp first.json identified.json", 0, 0.0, 0.0,
                                 verdict=out.get("verdict"), result="the second answer did not predict better"))
            rc = 0
        first_rc = rc
    return rows, out, load_parameters(str(work / "identified.json")) if rc == 0 else None


def write_route(work: Path, name: str, speed_mps: float, scale: float = 1.0) -> str:
    """The figure eight at `speed_mps` as a route file in `work`; its name there."""
    import yaml

    (work / name).write_text(yaml.safe_dump(figure_eight(speed_mps, scale), sort_keys=False))
    return name


def mission_over_seam(work: Path, route: str, address: str, report: str, *extra: str
                      ) -> tuple[str, int, dict, float, float]:
    """`lotsen mission ROUTE --physics ADDRESS EXTRA --report REPORT` in `work`: (the command, exit code,
    the report ({} without one), CPU s, wall s)."""
    args = ["mission", route, "--physics", address, *extra, "--report", report]
    rc, _, cpu, wall = lotsen(*args, cwd=work)
    rep = json.loads((work / report).read_text()) if (work / report).is_file() else {}
    return "lotsen " + " ".join(args), rc, rep, cpu, wall


def lab_loop_rows(work: Path, quick: bool) -> tuple[list[dict], Any]:
    """The lab loop through the commands (module docstring, 1). Returns its rows and the identified
    parameters (None when identify refused)."""
    table = "1. the lab loop on the 6-DOF hull, command by command (design -> run over the seam -> identify -> fly)"
    rows, out, params = lab_identify(work, quick, table, hull_m11(), REVERSE_THRUST_RATIO)
    if out is None:
        return rows, None
    # fly: the figure eight at 1.0 m/s in current and wind over the seam, the defaults and the identified model
    case = CASES[1]
    route = write_route(work, "figure_eight_1mps.yaml", case[2], case[1])
    flown: dict[str, dict] = {}
    with hull_server(*lake_server_args(0)) as address:
        for name, extra in (("defaults", []), ("identified", ["--params", "identified.json"])):
            if name == "identified" and params is None:
                continue
            command, rc, rep, cpu, wall = mission_over_seam(work, route, address, f"mission_{name}.json", *extra)
            flown[name] = rep
            inproc = fly(case, "lab loop" if name == "identified" else "defaults", params if name == "identified" else None, 0)
            rows.append(step_row(table, f"fly ({name})", command, rc, cpu, wall,
                                 cross_track_rms_cm=_cm(rep.get("cross_track_rms_m")),
                                 cross_track_max_cm=_cm(rep.get("cross_track_max_m")),
                                 failsafes=", ".join(rep.get("failsafes_triggered", [])) or "none",
                                 in_process_rms_cm=_cm(inproc["cross_track_rms_m"]),
                                 model=rep.get("model"), boat=rep.get("boat")))
    if "identified" in flown and "defaults" in flown:
        a, b = flown["defaults"].get("cross_track_rms_m"), flown["identified"].get("cross_track_rms_m")
        ratio = b / a if a and b else None
        rows.append({"table": table, "step": "the loop's answer", "verdict": out.get("verdict"),
                     "identified_over_defaults": None if ratio is None else round(ratio, 2),
                     "target": "identify answers (exit 0); the identified model tracks better than the defaults",
                     "pass": bool(ratio is not None and ratio < 1.0)})
    else:
        rows.append({"table": table, "step": "the loop's answer", "verdict": out.get("verdict"),
                     "target": "identify answers (exit 0); the identified model tracks better than the defaults",
                     "pass": False})
    if params is not None:  # issue 47's bar, as bench_hull_b.py measures it on hull B
        rows += fastest_figure_eight_rows(
            work, out, "6-DOF (tests/physics/hull6dof.py)", (0,) if quick else (0, 1, 2, 3),
            "1b. the fastest figure eight on the 6-DOF hull over the seam, by seed and model (current 0.08 m/s, "
            "wind 4 m/s gusty)", "1c. the lab loop's answer on the 6-DOF hull: identified against defaults, mean over seeds",
            m11=hull_m11(), reverse_thrust_ratio=REVERSE_THRUST_RATIO)
        if not quick:
            rows += repeated_lab_loop_rows(work, rows)
    return rows, params


#: the estimation runs' sensor seeds of the repeated lab loops (1d); the bench's own loop is (0, 2)
REPEATED_RECORD_SEEDS = ((15, 11), (25, 21), (35, 31))


def repeated_lab_loop_rows(work: Path, rows: list[dict]) -> list[dict]:
    """1d: the lab loop again on records whose only difference is lotsen's sensor noise (the runs'
    `--seed`), each answer flown on the fastest figure eight, seeds 0-3, against the defaults' flights
    of 1b: how much of 1c's ratio is the one loop's luck."""
    table = ("1d. the lab loop repeated: the same commands, the estimation runs with other sensor noise "
             "(their --seed), the answer on the fastest figure eight (seeds 0-3) against 1b's defaults")
    defaults = {r["seed"]: r["cross_track_rms_cm"] for r in rows if r.get("model") == "defaults" and "seed" in r}
    own = next((r for r in rows if "identified_over_defaults" in r and "per_seed_ratio" in r), {})
    out_rows: list[dict] = [{"table": table, "record_seeds": "0, 2 (1c)", "verdict": own.get("verdict"),
                             "per_seed_ratio": own.get("per_seed_ratio"),
                             "identified_over_defaults": own.get("identified_over_defaults")}]
    ratios = [own["identified_over_defaults"]] if own.get("identified_over_defaults") is not None else []
    for rs in REPEATED_RECORD_SEEDS:
        sub = work / f"repeat_{rs[0]}_{rs[1]}"
        sub.mkdir()
        steps, out, params = lab_identify(sub, False, table, hull_m11(), REVERSE_THRUST_RATIO, record_seeds=rs)
        kept_first = any(r.get("step") == "keep the first answer" for r in steps)
        row = {"table": table, "record_seeds": f"{rs[0]}, {rs[1]}", "verdict": (out or {}).get("verdict"),
               "first answer kept": kept_first}
        if params is not None:
            cte = {}
            for seed in sorted(defaults):
                _, _, rep, _, _, ok = fly_fastest_figure_eight(sub, "identified", seed)
                if ok:
                    cte[seed] = 100 * rep["cross_track_rms_m"]
            if len(cte) == len(defaults) and defaults:
                r = statistics.mean(cte.values()) / statistics.mean(defaults.values())
                ratios.append(r)
                row.update(per_seed_ratio=", ".join(f"{cte[k] / defaults[k]:.2f}" for k in sorted(defaults)),
                           identified_over_defaults=round(r, 2))
        out_rows.append(row)
    out_rows.append({"table": table, "record_seeds": "all", "loops": len(ratios),
                     "identified_over_defaults": round(statistics.mean(ratios), 2) if ratios else None,
                     "spread": f"{min(ratios):.2f}-{max(ratios):.2f}" if ratios else None})
    return out_rows


def fly_fastest_figure_eight(work: Path, model: str, seed: int, server: tuple[str, ...] = ()
                             ) -> tuple[str, int, dict, float, float, bool]:
    """The fastest figure eight the planner flies (every node at its speed_max_mps) over the seam in the
    lake (`lake_server_args(seed)`, a fresh hull_server.py with `server` flags), with the defaults
    (`model` "defaults") or `work`/identified.json ("identified"): (the command, exit code, report, CPU s,
    wall s, completed without a failsafe)."""
    from lotsen.planning import PlannerConfig

    route = write_route(work, "figure_eight_fastest.yaml", PlannerConfig().speed_max_mps)
    extra = ("--params", "identified.json") if model == "identified" else ()
    with hull_server(*server, *lake_server_args(seed)) as address:
        command, rc, rep, cpu, wall = mission_over_seam(work, route, address, f"mission_{model}_{seed}.json",
                                                        "--seed", str(seed), *extra)
    return command, rc, rep, cpu, wall, bool(rc == 0 and rep.get("completed") and not rep.get("failsafes_triggered"))


def fastest_figure_eight_rows(work: Path, out: dict, hull: str, seeds: tuple[int, ...], flights: str, summary: str,
                              server: tuple[str, ...] = (), m11: float | None = None,
                              reverse_thrust_ratio: float | None = None) -> list[dict]:
    """Issue 47's bar for the lab loop's answer (`work`/identified.json, the parameter file `out`): the
    fastest figure eight the planner flies (every node at its speed_max_mps; the lobes capped by its
    lateral acceleration, so the speed as flown is shown), over the seam in the lake (`lake_server_args`)
    with the defaults and with the answer, per seed a fresh hull_server.py (`server` flags) so that both
    models meet the same water. Rows of `flights` per seed and model, and one of `summary`."""
    from lotsen.harness.mission import planned_duration_s
    from lotsen.planning import PlannerConfig

    planner = PlannerConfig()
    speed = planner.speed_max_mps
    path = planned(1.0, speed, planner.a_lat_max_mps2)
    rows: list[dict] = []
    cte: dict[str, list[float]] = {"defaults": [], "identified": []}
    done = True
    for seed in seeds:
        for name in ("defaults", "identified"):
            command, rc, rep, cpu, wall, ok = fly_fastest_figure_eight(work, name, seed, server)
            done = done and ok
            if rep.get("cross_track_rms_m") is not None:
                cte[name].append(rep["cross_track_rms_m"])
            flown = rep["path_length_m"] / rep["duration_s"] if ok else None
            rows.append({"table": flights, "seed": seed, "model": name, "exit": rc,
                         "completed, no failsafe": ok, "cross_track_rms_cm": _cm(rep.get("cross_track_rms_m")),
                         "cross_track_max_cm": _cm(rep.get("cross_track_max_m")),
                         "failsafes": ", ".join(rep.get("failsafes_triggered", [])) or "none",
                         "speed_flown_mps": None if flown is None else round(flown, 3),
                         "duration_s": rep.get("duration_s"), "cpu_s": round(cpu, 1), "wall_s": round(wall, 1),
                         "command": command})
    d, i = cte["defaults"], cte["identified"]
    flown_all = [r["speed_flown_mps"] for r in rows if r["speed_flown_mps"]]
    r_mean = statistics.mean(i) / statistics.mean(d) if d and i and len(d) == len(i) == len(seeds) else None
    estimated_on = " + ".join(r for r in out.get("recorded_on", {}) if r != "validation.mcap")
    rows.append({"table": summary, "hull": hull, "estimated on": f"{estimated_on} (60-s designs, calm, over the seam)",
                 "judged on": (out.get("identification") or {}).get("judged_on") or "?",
                 "verdict": out.get("verdict"), "m11": m11, "reverse_thrust_ratio": reverse_thrust_ratio,
                 "nominal_mps": speed, "planned_mps": round(path.length_m / planned_duration_s(path), 3),
                 "speed_flown_mps": round(statistics.mean(flown_all), 3) if flown_all else None,
                 "seeds": len(seeds), "defaults_cm": round(100 * statistics.mean(d), 2) if d else None,
                 "identified_cm": round(100 * statistics.mean(i), 2) if i else None,
                 "per_seed_ratio": ", ".join(f"{b / a:.2f}" for a, b in zip(d, i)),
                 "identified_over_defaults": None if r_mean is None else round(r_mean, 2),
                 "target": "every mission completes without a failsafe; identified <= 0.8 x the defaults' "
                           "cross-track RMS (mean over >= 4 seeds)",
                 "pass": bool(done and r_mean is not None and r_mean <= 0.8 and len(seeds) >= 4)})
    return rows


def _cm(v: float | None) -> float | None:
    return None if v is None else round(100 * v, 2)


# ------------------------------------------------------------------------------------------------
# 3. identification records: two calm, two lake

def _agreement(a: dict, b: dict) -> tuple[int, int, list[str], list[str]]:
    """Two parameter files of one hull: (coefficients within 3 combined sigma, coefficients compared,
    those outside with their distance, those without an interval in either file). A coefficient
    without an interval (undetermined in either file: at a physical bound, or an interval through zero)
    is left out of the count: an interval that says nothing cannot agree."""
    within, outside, no_interval = 0, [], []
    names = list(a.get("std", {}))
    for n in names:
        sa, sb = a["std"].get(n), (b.get("std") or {}).get(n)
        if sa is None or sb is None or not (math.isfinite(sa) and math.isfinite(sb)):
            no_interval.append(n)
            continue
        s = math.hypot(sa, sb)
        z = abs(a[n] - b[n]) / s if s > 0 else (0.0 if a[n] == b[n] else math.inf)
        if z <= 3.0:
            within += 1
        else:
            outside.append(f"{n} {z:.1f} sigma")
    return within, len(names) - len(no_interval), outside, no_interval


def record_rows(work: Path, quick: bool) -> tuple[list[dict], dict[str, Any]]:
    """Module docstring, 3. Returns the rows and the parameters of the first calm and lake answers."""
    from hull6dof import record

    from lotsen.stack.stack import load_parameters

    duration = 300.0 if quick else 600.0
    rows: list[dict] = []
    models: dict[str, Any] = {}
    m11 = hull_m11()
    for kind, lake in (("calm", False), ("lake", True)):
        table = (f"3. identification records of the hull ({kind}, {duration / 60:g} min PRBS"
                 + (f", current {CURRENT[0]} m/s, wind {WIND[0]:g} m/s gusty and wandering" if lake else "") + ")")
        target_gain, target_cpu = (0.30, 20.0) if lake else (0.40, 5.0)
        files: dict[int, dict] = {}
        cpus: list[float | None] = []
        for seed in (1, 2):
            env = dict(current_mps=CURRENT[0], current_to_deg=CURRENT[1], wind_mps=WIND[0], wind_from_deg=WIND[1],
                       gust_fraction=GUSTS, wind_wander_deg=WANDER_DEG) if lake else {}
            c0 = time.process_time()
            rec = record(seed=seed, duration_s=duration, **env)
            csv = work / f"{kind}{seed}.csv"
            rec.save_csv(csv)
            record_cpu = time.process_time() - c0
            out_file = work / f"{kind}{seed}.json"
            args = [csv.name, *(["--lake"] if lake else []), "--fix", f"m11={m11:g}",
                    "--reverse-thrust-ratio", str(REVERSE_THRUST_RATIO), "--out", out_file.name]
            t0 = time.perf_counter()
            rc, err, cpu = timed_identify(*args, cwd=work)
            wall = time.perf_counter() - t0
            out = json.loads(out_file.read_text()) if out_file.is_file() else {}
            files[seed] = out
            chosen, p10, d10 = _prediction(out)
            gain = 1 - p10 / d10 if p10 and d10 else None
            ident_cpu = cpu.get("identify_s")
            rows.append({"table": table, "seed": seed, "exit": rc, "verdict": out.get("verdict"), "written": chosen,
                         "pred_10s_m": p10, "defaults_10s_m": d10,
                         "better_than_defaults_pct": None if gain is None else round(100 * gain),
                         "identify_cpu_s": None if ident_cpu is None else round(ident_cpu, 1),
                         "command_cpu_s": round(cpu.get("command_s", math.nan), 1), "wall_s": round(wall, 1),
                         "record_cpu_s": round(record_cpu, 1), "reasons": _reasons(out)[:240],
                         "target": f"an answer (exit 0), >= {100 * target_gain:.0f} % better than the defaults "
                                   "after 10 s",
                         "pass": bool(rc == 0 and gain is not None and gain >= target_gain)})
            cpus.append(ident_cpu)
            if seed == 1 and rc == 0:
                models[kind] = load_parameters(str(out_file))
        rows.append({"table": table, "seed": "CPU", "identify_cpu_s": ", ".join(
                         "?" if c is None else f"{c:.1f}" for c in cpus),
                     "target": f"identification (lotsen.sysid.identify.identify) <= {target_cpu:g} s CPU",
                     "pass": bool(all(c is not None and c <= target_cpu for c in cpus))})
        within, n, outside, no_interval = _agreement(files[1], files[2])
        rows.append({"table": table, "seed": "1 vs 2", "agree_within_3_sigma": f"{within} of {n} with an interval"
                     + (f" ({len(no_interval)} undetermined in either record, left out)" if no_interval else ""),
                     "outside": ", ".join(outside) or "none",
                     "no_interval": ", ".join(no_interval) or "none",
                     "target": ">= 90 % of the coefficients within 3 combined sigma",
                     "pass": bool(n and within >= 0.9 * n)})
    return rows, models


# ------------------------------------------------------------------------------------------------
# 2. tracking

def tracking_rows(models: dict[str, Any], quick: bool) -> list[dict]:
    """Module docstring, 2: every case with every model, per seed, then the ratio per case."""
    cases = QUICK_CASES if quick else CASES
    rows: list[dict] = []
    table = ("2. tracking on the hull by model (EKF + MPC; current 0.08 m/s, wind 4 m/s gusty, wandering)")
    summary = "2. the identified model against the defaults per case (mean over seeds)"
    for case in cases:
        # the judged cases (>= 1.2 m/s) on four seeds, as issue 47's bar (1c) has it: seed 0 alone is the
        # unlucky one over the seam in every loop of 1d (0.93-1.06 against 0.59-0.78 for seeds 1-3)
        seeds = (0,) if quick else (0, 1, 2, 3) if case[2] >= 1.2 else (0, 1)
        cte: dict[str, list[float]] = {}
        for name, params in models.items():
            for seed in seeds:
                m = fly(case, name, params, seed)
                cte.setdefault(name, []).append(100 * m["cross_track_rms_m"])
                rows.append({"table": table, "case": case[0], "model": name, "seed": seed,
                             "completed": m["completed"], "cross_track_rms_cm": _cm(m["cross_track_rms_m"]),
                             "cross_track_max_cm": _cm(m["cross_track_max_m"]),
                             "failsafes": ", ".join(m.get("failsafes_triggered", [])) or "none",
                             "planned_mean_mps": m["planned_mean_mps"], "speed_mean_mps": m["speed_mean_mps"],
                             "speed_error_rms_mps": m["speed_error_rms_mps"], "duration_s": m["duration_s"]})
        d = statistics.mean(cte["defaults"])
        fs = sorted({f for r in rows if r["table"] == table and r["case"] == case[0] for f in
                     ([] if r["failsafes"] == "none" else r["failsafes"].split(", "))})
        done = all(r["completed"] for r in rows if r["table"] == table and r["case"] == case[0])
        row: dict[str, Any] = {"table": summary, "case": case[0], "nominal_mps": case[2], "seeds": len(seeds),
                               "all_completed": done, "failsafes": ", ".join(fs) or "none",
                               "defaults_cm": round(d, 2)}
        for name in models:
            if name != "defaults":
                row[f"{name}_cm"] = round(statistics.mean(cte[name]), 2)
                row[f"{name}_ratio"] = round(statistics.mean(cte[name]) / d, 2)
        if "lab loop" in models:
            ratio = statistics.mean(cte["lab loop"]) / d
            if case[2] >= 1.2:
                row.update(target="at >= 1.2 m/s the lab loop's model tracks >= 20 % better (ratio <= 0.8)",
                           **{"pass": bool(ratio <= 0.8)})
        rows.append(row)
    return rows


def run(quick: bool = False) -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="lotsen-hull-bench-") as tmp:
        work = Path(tmp)
        lab, identified = lab_loop_rows(work, quick)
        records, record_models = record_rows(work, quick)
    models: dict[str, Any] = {"defaults": None}
    if identified is not None:
        models["lab loop"] = identified
    if not quick:
        for kind in ("calm", "lake"):
            if kind in record_models:
                models[f"{kind} record"] = record_models[kind]
    return lab + tracking_rows(models, quick) + records


if __name__ == "__main__":
    import pprint

    pprint.pprint(run(quick="--quick" in sys.argv))
