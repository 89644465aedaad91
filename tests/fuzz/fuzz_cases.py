"""Cases for the command-line fuzz harness (issue 42): every command, every flag, the project's own
inputs mutated as a careless or hostile user would.

* **Flags** are enumerated from the argparse parsers (`flag_table`), so a new flag is covered
  without touching this file when it is a `settings.Number`, has choices or is a switch; any other
  flag must be classified in `FLAG_KINDS` (a test fails otherwise). Each kind has hostile values.
* **Files**: the seeds are the project's real inputs (examples/, config/, a parameter file, a
  schedule, magnetometer and identification CSVs, a short MCAP recording, the UBX capture of the
  driver tests), mutated in their structure (a number replaced by NaN, 1e308, a denormal, ...) or
  in their bytes (bit flips, cuts, garbage, a wrong encoding, a size over the cap).
* **Outputs** that name an input (the same path, a hard or a symbolic link), a missing folder or a
  folder.

A `Case` says whether its input is certainly invalid (`must_refuse`); `judge` names what went
wrong with an outcome: a traceback, a hang, an input changed, invalid input accepted, a refusal
without a message or slower than the limit.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import yaml

REPO = Path(__file__).resolve().parents[2]

# ------------------------------------------------------------------------------------------------
# seeds

#: name in a case folder -> (kind, how it is made)
SEED_FILES = {
    "route.yaml": "route", "exp.yaml": "experiment", "config.yaml": "config", "params.json": "params",
    "boat.json": "params", "schedule.yaml": "schedule", "mag.csv": "mag_csv", "cal.json": "calibration",
    "data.csv": "data_csv", "run.mcap": "mcap", "capture.ubx": "ubx",
}
EXTRA_ROUTES = ("harbour_approach.yaml", "square_with_obstacle.yaml", "figure_eight_loop.yaml", "survey_lake.yaml")
EXTRA_EXPERIMENTS = ("speed_steps.yaml", "zigzag_10_10.yaml", "prbs_multisine.yaml", "turning_circles.yaml",
                     "bow_thruster_steps.yaml")


def _params(scale: float = 1.0) -> dict:
    from lotsen.model import DEFAULT_PARAMETERS

    d = {k: v * (scale if k.startswith(("X_", "Y_", "N_")) else 1.0) for k, v in DEFAULT_PARAMETERS.to_dict().items()}
    return {**d, "verdict": "ok"}


def _mag_csv(rng: random.Random) -> str:
    rows = ["t,mag_x,mag_y,mag_z"]
    for k in range(200):
        a = 2 * math.pi * k / 180
        rows.append(f"{k * 0.1:.2f},{30 + 40 * math.cos(a) + rng.gauss(0, 0.3):.3f},"
                    f"{-10 + 25 * math.sin(a) + rng.gauss(0, 0.3):.3f},1")
    return "\n".join(rows) + "\n"


def write_text_seeds(folder: Path) -> None:
    """The seeds that need no simulation (the CSV record and the MCAP come from `seed_commands`)."""
    rng = random.Random(42)
    ex = REPO / "examples"
    (folder / "route.yaml").write_text((ex / "routes" / "figure_eight.yaml").read_text())
    (folder / "exp.yaml").write_text((ex / "experiments" / "designed_12s.yaml").read_text())
    cfg = (REPO / "config" / "sim.yaml").read_text()
    cfg = cfg.replace("route: ../examples/routes/figure_eight.yaml", "route: route.yaml")
    cfg = cfg.replace("directory: ../logs", "directory: logs")
    (folder / "config.yaml").write_text(cfg)
    (folder / "params.json").write_text(json.dumps(_params(), indent=1))
    (folder / "boat.json").write_text(json.dumps(_params(1.1), indent=1))
    (folder / "schedule.yaml").write_text("segments:\n  - {duration_s: 0.5, n1_rps: 40, n2_rps: 40}\n"
                                          "  - {duration_s: 0.5, n1_rps: 40, n2_rps: 40, alpha1_deg: -20, alpha2_deg: -20}\n")
    (folder / "mag.csv").write_text(_mag_csv(rng))
    cal = {"center": [30.0, -10.0], "matrix": [[40.0, 0.0], [0.0, 25.0]], "residual_rms": 0.01,
           "coverage_deg": 356.0, "n_points": 200, "heading_offset_rad": 0.0, "units": ""}
    (folder / "cal.json").write_text(json.dumps(cal, indent=1))
    (folder / "capture.ubx").write_bytes((REPO / "tests" / "drivers" / "data" / "capture.ubx").read_bytes())
    for name in EXTRA_ROUTES:
        (folder / f"route_{name}").write_text((ex / "routes" / name).read_text())
    for name in EXTRA_EXPERIMENTS:
        (folder / f"exp_{name}").write_text((ex / "experiments" / name).read_text())


#: command lines (run by the case runner in the seed folder) that make the recorded seeds and the
#: route in the ground stations' formats (QGroundControl .plan, QGC WPL, KML, GPX)
ROUTE_FORMATS = ("route.plan", "route.waypoints", "route.kml", "route.gpx", "route.geojson")
GROUND_STATION_ROUTES = ROUTE_FORMATS[:-1]
SEED_COMMANDS = (["experiment", "run", "exp.yaml", "--sim", "--out", "data.csv"],
                 ["experiment", "run", "exp.yaml", "--sim", "--out", "run.mcap"],
                 *(["plan", "route.yaml", "--export", name, "--origin", "57.6905,11.976"] for name in ROUTE_FORMATS))


@contextmanager
def session(work: Path, seed_timeout_s: float = 300.0) -> Iterator[tuple[Any, dict[str, bytes]]]:
    """A case runner (fuzz_runner.CaseRunner, its runtime folder inside `work`) and the seeds,
    the recorded ones made by the commands themselves (SEED_COMMANDS)."""
    from fuzz_runner import CaseRunner

    seeds_dir = work / "seeds"
    seeds_dir.mkdir(parents=True)
    write_text_seeds(seeds_dir)
    with CaseRunner(env={"LOTSEN_RUNTIME_DIR": str(work / "runtime"), "LOTSEN_CONFIG_DIR": str(work / "config")}) as runner:
        for argv in SEED_COMMANDS:
            made = runner.run(argv, seeds_dir, seed_timeout_s)
            if made.code != 0:
                raise RuntimeError(f"a seed command failed: {made.describe()}")
        yield runner, {p.name: p.read_bytes() for p in seeds_dir.iterdir() if p.is_file()}


def seed_variants(seeds: dict[str, bytes], kind: str) -> list[str]:
    """Names of the seeds of `kind` (the main one and the extra examples)."""
    names = [n for n, k in SEED_FILES.items() if k == kind]
    if kind == "route":
        names += [f"route_{n}" for n in EXTRA_ROUTES] + list(ROUTE_FORMATS)
    if kind == "experiment":
        names += [f"exp_{n}" for n in EXTRA_EXPERIMENTS]
    return [n for n in names if n in seeds]


# ------------------------------------------------------------------------------------------------
# mutations

#: hostile numbers as each format writes them; those before the | are invalid in any number field
#: of a YAML/JSON file (no field takes NaN, infinity, 1e308, a denormal or a 400-digit integer)
HOSTILE_YAML = [".nan", ".inf", "-.inf", "1.0e+308", "-1.0e+308", "1.0e-320", "1" + "0" * 400]
HOSTILE_JSON = ["NaN", "Infinity", "-Infinity", "1e308", "-1e308", "1e-320", "1" + "0" * 400]
ODD_NUMBERS = ["-1", "0", "1.0e+9", "1.0e+7", "0.5", "-0.0", "3"]
TEXT_KEYS = {"name", "label", "description", "type", "units", "verdict", "host", "directory", "route", "mode",
             "fusion", "controller", "direction", "forbidden", "compression", "encoding",
             # a QGroundControl .plan's own fields lotsen does not read (altitudes, numbering, versions)
             "AltitudeMode", "Altitude", "AMSLAltAboveTerrain", "doJumpId", "hoverSpeed", "version", "firmwareType",
             "vehicleType", "globalPlanAltitudeMode"}


@dataclass
class Mutation:
    data: bytes
    note: str
    must_refuse: bool


def _numeric_paths(obj: Any, path: tuple = ()) -> list[tuple]:
    """Paths to every number (not bool) of a parsed document, skipping text-like keys."""
    out: list[tuple] = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            if str(k) in TEXT_KEYS:
                continue
            out += _numeric_paths(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _numeric_paths(v, path + (i,))
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        out.append(path)
    return out


def _set(obj: Any, path: tuple, value: Any) -> None:
    for k in path[:-1]:
        obj = obj[k]
    obj[path[-1]] = value


def _get(obj: Any, path: tuple) -> Any:
    for k in path:
        obj = obj[k]
    return obj


_MARK = "HOSTILEVALUEMARKER"  # a plain scalar: YAML writes it unquoted


def structured_mutation(text: str, fmt: str, rng: random.Random) -> Mutation | None:
    """One number of the document replaced by a hostile or odd value, or a key dropped/renamed,
    or a number turned into text."""
    try:
        data = json.loads(text) if fmt == "json" else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError):  # not this format (a KML, a QGC WPL text): byte-level only
        return None
    paths = _numeric_paths(data)
    if not paths:
        return None
    path = rng.choice(paths)
    where = ".".join(map(str, path))
    r = rng.random()
    if r < 0.6:
        hostile = rng.random() < 0.7
        value = rng.choice((HOSTILE_JSON if fmt == "json" else HOSTILE_YAML) if hostile else ODD_NUMBERS)
        _set(data, path, _MARK)
        dumped = json.dumps(data, indent=1) if fmt == "json" else yaml.safe_dump(data, sort_keys=False, width=200)
        dumped = dumped.replace(f'"{_MARK}"' if fmt == "json" else _MARK, value)
        return Mutation(dumped.encode(), f"{where} = {value[:20]}", hostile)
    if r < 0.75:
        _set(data, path, "fast")
        note, must = f"{where} = 'fast'", True
    elif r < 0.9 and len(path) and isinstance(path[-1], str):
        parent = _get(data, path[:-1])
        del parent[path[-1]]
        note, must = f"{where} removed", False
    else:
        _set(data, path, [1, 2])
        note, must = f"{where} = [1, 2]", True
    dumped = json.dumps(data, indent=1) if fmt == "json" else yaml.safe_dump(data, sort_keys=False, width=200)
    return Mutation(dumped.encode(), note, must)


def csv_mutation(text: str, rng: random.Random) -> Mutation:
    """A cell of a CSV record made hostile, a row cut short, a column renamed, rows swapped."""
    lines = text.splitlines()
    body = [i for i, line in enumerate(lines) if line and not line.startswith("#") and i > 0]
    r = rng.random()
    if r < 0.5 and body:
        i = rng.choice(body)
        cells = lines[i].split(",")
        j = rng.randrange(len(cells))
        value = rng.choice(["1e308", "-1e308", "inf", "1e-320", "abc", "", "1e9", "-1", "0x10", "1" * 400])
        cells[j] = value
        lines[i] = ",".join(cells)
        note = f"line {i + 1} column {j + 1} = {value[:12]!r}"
    elif r < 0.65 and body:
        i = rng.choice(body)
        lines[i] = lines[i][: rng.randrange(max(1, len(lines[i])))]
        note = f"line {i + 1} cut short"
    elif r < 0.8:
        header = lines[0].split(",")
        j = rng.randrange(len(header))
        header[j] = header[j] + "x"
        lines[0] = ",".join(header)
        note = f"header column {j + 1} renamed"
    elif body:
        i, k = rng.choice(body), rng.choice(body)
        lines[i], lines[k] = lines[k], lines[i]
        note = f"lines {i + 1} and {k + 1} swapped"
    else:
        note = "unchanged"
    return Mutation(("\n".join(lines) + "\n").encode(), note, False)


def text_mutation(data: bytes, rng: random.Random, cap: int) -> Mutation:
    """Byte-level damage to a text file; refusals expected where the result is certainly not text
    (NUL, UTF-16) or over the size cap."""
    r = rng.random()
    if r < 0.15:
        k = rng.randrange(len(data) + 1)
        return Mutation(data[:k], f"cut at byte {k}", False)
    if r < 0.3:
        k = rng.randrange(len(data) + 1)
        return Mutation(data[:k] + b"\x00" + data[k:], f"NUL at byte {k}", True)
    if r < 0.4:
        return Mutation(data.decode("utf-8", "replace").encode("utf-16"), "UTF-16 with BOM", True)
    if r < 0.5 and cap <= 1 << 20:  # bigger caps: the "huge" input case of the flags writes such a file
        reps = cap // max(len(data), 1) + 2
        return Mutation(data * reps, f"repeated {reps} times ({len(data) * reps} bytes, over the cap)", True)
    if r < 0.65:
        lines = data.split(b"\n")
        i = rng.randrange(len(lines))
        return Mutation(b"\n".join(lines[:i] + lines[i + 1:]), f"line {i + 1} deleted", False)
    if r < 0.75:
        lines = data.split(b"\n")
        i = rng.randrange(len(lines))
        return Mutation(b"\n".join(lines[:i + 1] + lines[i:]), f"line {i + 1} duplicated", False)
    if r < 0.85:
        k = rng.randrange(len(data) + 1)
        junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
        return Mutation(data[:k] + junk + data[k:], f"{len(junk)} random bytes at {k}", False)
    flips = bytearray(data)
    n = rng.choice((1, 3, 10))
    for _ in range(n):
        if flips:
            flips[rng.randrange(len(flips))] ^= 1 << rng.randrange(8)
    return Mutation(bytes(flips), f"{n} bits flipped", False)


def binary_mutation(data: bytes, rng: random.Random, magic: bytes = b"") -> Mutation:
    """Damage to a recording: bit flips (1 to 1000), a cut, zeroed or random ranges, only the
    magic, random bytes after the magic, an absurd record length."""
    r = rng.random()
    if r < 0.35:
        n = rng.choice((1, 10, 100, 1000))
        b = bytearray(data)
        for _ in range(n):
            b[rng.randrange(len(b))] ^= 1 << rng.randrange(8)
        return Mutation(bytes(b), f"{n} bits flipped", False)
    if r < 0.5:
        k = rng.randrange(len(data))
        return Mutation(data[:k], f"cut at byte {k}", False)
    if r < 0.6:
        k = rng.randrange(len(data))
        n = rng.randint(1, 4096)
        return Mutation(data[:k] + bytes(min(n, len(data) - k)) + data[k + n:], f"{n} bytes zeroed at {k}", False)
    if r < 0.7 and magic:
        return Mutation(magic, "only the magic bytes", False)
    if r < 0.8 and magic:
        n = rng.randint(1, 20000)
        return Mutation(magic + bytes(rng.randrange(256) for _ in range(n)), f"{n} random bytes after the magic", False)
    if r < 0.9 and magic:
        length = rng.choice((2**31 - 1, 2**40, 2**63, len(data) * 3))
        head = bytes([rng.choice((1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))]) + length.to_bytes(8, "little")
        return Mutation(magic + head + data[len(magic) + 9:], f"first record length {length}", False)
    k = rng.randrange(len(data))
    n = rng.randint(1, 2048)
    return Mutation(data[:k] + data[k:k + n] + data[k:], f"{n} bytes repeated at {k}", False)


def mutate(kind: str, data: bytes, rng: random.Random, name: str = "") -> Mutation:
    """One mutation of a seed of `kind` (`name`: its file name, whose suffix says JSON or YAML)."""
    from lotsen.files import MAX_DATA_BYTES, MAX_TEXT_BYTES

    if kind in ("mcap",):
        return binary_mutation(data, rng, b"\x89MCAP0\r\n")
    if kind == "ubx":
        return binary_mutation(data, rng)
    if kind in ("mag_csv", "data_csv"):
        if rng.random() < 0.7:
            return csv_mutation(data.decode(), rng)
        return text_mutation(data, rng, MAX_DATA_BYTES)
    fmt = "json" if kind in ("params", "calibration") or Path(name).suffix in (".json", ".geojson", ".plan") else "yaml"
    m = structured_mutation(data.decode(), fmt, rng) if rng.random() < 0.7 else None
    m = m or text_mutation(data, rng, MAX_TEXT_BYTES)
    if name in GROUND_STATION_ROUTES:
        # a ground station's file carries fields lotsen does not read (altitudes, unused mission
        # parameters, rally altitudes): a hostile value there may be ignored; no crash all the same
        m = Mutation(m.data, m.note, m.must_refuse and ("NUL" in m.note or "UTF-16" in m.note or "cap" in m.note))
    return m


# ------------------------------------------------------------------------------------------------
# commands and flags

@dataclass(frozen=True)
class Command:
    """How a command is run on valid, small inputs (`base`), which seed files it reads
    (`reads`: positional or flag -> seed kind), and whether an accepted run is cheap enough for
    the test suite (`cheap`: seconds, not minutes)."""

    path: tuple[str, ...]
    base: tuple[str, ...]
    reads: dict[str, str] = field(default_factory=dict)  # seed name in `base` -> kind
    cheap: bool = True


COMMANDS: tuple[Command, ...] = (
    Command(("model", "check"), ("model", "check", "--params", "params.json"), {"params.json": "params"}),
    Command(("sim",), ("sim", "--duration", "1", "--config", "config.yaml", "--schedule", "schedule.yaml",
                       "--out", "traj.csv"), {"config.yaml": "config", "schedule.yaml": "schedule"}),
    Command(("run",), ("run", "config.yaml", "--duration", "0.5", "--one-process"), {"config.yaml": "config"},
            cheap=False),
    Command(("plan",), ("plan", "route.yaml", "--out", "path.json"), {"route.yaml": "route"}),
    Command(("mission",), ("mission", "route.yaml", "--sim", "--estimator", "truth", "--hold", "0", "--report", "r.json"),
            {"route.yaml": "route"}, cheap=False),
    Command(("identify",), ("identify", "data.csv", "--out", "p.json", "--max-iter", "2"),
            {"data.csv": "data_csv"}),
    Command(("experiment", "run"), ("experiment", "run", "exp.yaml", "--sim", "--out", "out.csv"), {"exp.yaml": "experiment"}),
    Command(("experiment", "lake"), ("experiment", "lake", "--out", "lake.csv", "--duration", "10")),
    Command(("experiment", "check"), ("experiment", "check", "exp.yaml", "--params", "params.json"),
            {"exp.yaml": "experiment", "params.json": "params"}),
    Command(("experiment", "design"), ("experiment", "design", "--duration", "5", "--iterations", "1",
                                       "--robust-samples", "1", "--out", "d.yaml")),
    Command(("calibrate-mag",), ("calibrate-mag", "mag.csv", "--out", "cal_out.json"), {"mag.csv": "mag_csv"}),
    Command(("replay",), ("replay", "run.mcap", "--fast", "--listen", "tcp/127.0.0.1:0"), {"run.mcap": "mcap"}),
    Command(("export",), ("export", "run.mcap", "--out", "tables"), {"run.mcap": "mcap"}),
    Command(("record",), ("record", "--listen", "tcp/127.0.0.1:0", "--duration", "0.2", "--out", "rec")),
    Command(("gnss-replay",), ("gnss-replay", "capture.ubx", "--out", "fixes.csv"), {"capture.ubx": "ubx"}),
    Command(("check",), ("check", "--emulated", "--duration", "0.2"), cheap=False),
    Command(("recover",), ("recover", "run.mcap", "--out", "fixed.mcap", "--force"), {"run.mcap": "mcap"}),
    Command(("physics-server",), ("physics-server", "config.yaml", "--port", "0", "--duration", "0.3"),
            {"config.yaml": "config"}),
    Command(("pair",), ("pair", "config.yaml"), {"config.yaml": "config"}),
)
COMMAND_BY_PATH = {c.path: c for c in COMMANDS}

#: flags that are neither numbers, choices nor switches: how to fuzz them. Kinds:
#: "in:<seed kind>" an input file, "out" an output file, "out:plot", "out:dir", "text:<name>"
FLAG_KINDS: dict[tuple[tuple[str, ...], str], str] = {
    (("model", "check"), "--params"): "in:params",
    (("sim",), "--schedule"): "in:schedule", (("sim",), "--config"): "in:config", (("sim",), "--out"): "out",
    (("run",), "config"): "in:config", (("run",), "--host"): "text:host", (("run",), "--boat"): "in:params",
    (("run",), "--params"): "in:params",
    (("plan",), "route"): "in:route", (("plan",), "--out"): "out", (("plan",), "--plot"): "out:plot",
    (("plan",), "--return-from"): "text:pose",
    (("mission",), "route"): "in:route", (("mission",), "--current"): "text:speed_dir",
    (("mission",), "--wind"): "text:speed_dir", (("mission",), "--boat"): "in:params",
    (("mission",), "--params"): "in:params", (("mission",), "--report"): "out", (("mission",), "--plot"): "out:plot",
    (("identify",), "data"): "in:data_csv", (("identify",), "--out"): "out", (("identify",), "--fix"): "text:fix",
    (("identify",), "--noise"): "text:noise", (("identify",), "--report"): "out", (("identify",), "--init"): "in:params",
    (("identify",), "--validate"): "in:data_csv", (("identify",), "--in-use"): "in:params", (("identify",), "--reverse-thrust-ratio"): "number",
    (("identify",), "--gnss-antenna"): "text:xy", (("identify",), "--terms"): "text:terms",
    (("experiment", "run"), "experiment"): "in:experiment", (("experiment", "run"), "--config"): "in:config",
    (("experiment", "run"), "--out"): "out", (("experiment", "run"), "--boat"): "in:params",
    (("experiment", "run"), "--params"): "in:params", (("experiment", "run"), "--model-params"): "in:params",
    (("experiment", "lake"), "--out"): "out", (("experiment", "lake"), "--boat"): "out",
    (("experiment", "check"), "experiment"): "in:experiment", (("experiment", "check"), "--params"): "in:params",
    (("experiment", "design"), "--area"): "text:area", (("experiment", "design"), "--out"): "out",
    (("experiment", "design"), "--params"): "in:params", (("experiment", "design"), "--fixed"): "text:names",
    (("calibrate-mag",), "data"): "in:mag_csv", (("calibrate-mag",), "--out"): "out",
    (("replay",), "log"): "in:mcap", (("replay",), "--topics"): "text:topics", (("replay",), "--exclude"): "text:topics",
    (("replay",), "--record"): "out:dir", (("replay",), "--vessel"): "text:name", (("replay",), "--listen"): "text:endpoint",
    (("replay",), "--connect"): "text:endpoint",
    (("export",), "log"): "in:mcap", (("export",), "--topics"): "text:topics", (("export",), "--out"): "out:dir",
    (("export",), "--ros2"): "out:dir", (("export",), "--namespace"): "text:name",
    (("record",), "--out"): "out:dir", (("record",), "--subscribe"): "text:topics", (("record",), "--vessel"): "text:name",
    (("record",), "--listen"): "text:endpoint", (("record",), "--connect"): "text:endpoint",
    (("gnss-replay",), "capture"): "in:ubx", (("gnss-replay",), "--out"): "out",
    (("check",), "config"): "in:config",
    (("recover",), "log"): "in:mcap", (("recover",), "--out"): "out",
    (("run",), "--mavlink"): "text:mavlink", (("run",), "--physics"): "text:physics",
    (("plan",), "--export"): "out", (("plan",), "--origin"): "text:latlon",
    (("plan",), "--current"): "text:speed_dir", (("plan",), "--wind"): "text:speed_dir",
    (("plan",), "--params"): "in:params",
    (("mission",), "--physics"): "text:physics", (("mission",), "--config"): "in:config",
    (("experiment", "run"), "--physics"): "text:physics",
    (("pair",), "config"): "in:config", (("pair",), "--host"): "text:page_host",
    (("physics-server",), "config"): "in:config", (("physics-server",), "--host"): "text:bind",
    (("physics-server",), "--boat"): "in:params", (("physics-server",), "--params"): "in:params",
    (("physics-server",), "--current"): "text:speed_dir", (("physics-server",), "--wind"): "text:speed_dir",
    (("physics-server",), "--waves"): "text:waves", (("mission",), "--waves"): "text:waves",
    (("run",), "--waves"): "text:waves", (("experiment", "run"), "--waves"): "text:waves",
    (("experiment", "check"), "--sea"): "text:waves", (("experiment", "design"), "--sea"): "text:waves",
}

#: hostile text for the composite flags (kind -> values; True: certainly invalid)
TEXT_VALUES: dict[str, list[tuple[str, bool]]] = {
    "host": [("not a host", True), ("8.8.8.8", True), ("", True), ("a" * 300, True)],
    "pose": [("1 2 1e308", True), ("nan 0 0", True), ("1e9 0 0", True), ("0 0 abc", True), ("1e-320 0 0", True)],
    "speed_dir": [("nan,0", True), ("1e308,90", True), ("-1,0", True), ("0.1", True), ("0.1,inf", True),
                  ("0.1,1e-320", True), ("a,b,c", True)],
    "waves": [("nan,1,0", True), ("0.06,1e308,0", True), ("-0.1,1,0", True), ("0.06,1", True), ("0.06,0,250", True),
              ("0.06,1,250,-1", True), ("1e-320,1,0", True), ("0.06,1,inf", True), ("a,b,c", True), ("5,1,0", True)],
    "fix": [("m11=nan", True), ("m11=-1", True), ("m11=1e308", True), ("zz=1", True), ("m11", True),
            ("X_u=1e-320", True), ("m11=", True)],
    "noise": [("r=0", True), ("r=nan", True), ("r=-1", True), ("=1", True), ("r=1e308", True), ("r=1e-320", True)],
    "xy": [("nan,0", True), ("3,0", True), ("0.05", True), ("1e308,0", True), ("a,b", True)],
    "area": [("1e308x30", True), ("0x0", True), ("nanx30", True), ("30", True), ("-5x30", True), ("1e-320x30", True)],
    "names": [("nosuch", True), (",", True), ("m11,zz", True)],
    "terms": [("nosuch", True), (",", True), ("X_uuu,zz", True), ("", True), ("m11", True)],
    "topics": [("", False), ("no/such/topic", False), ("a" * 500, False), ("../../etc", False), ("**/#", False),
               ("$*", False)],
    "name": [("", False), ("a/b", False), ("\u00e9" * 50, False), ("a*b", False), ("#", False)],
    "endpoint": [("tcp/256.1.1.1:1", False), ("nonsense", False), ("tcp/127.0.0.1:99999", False)],
    "mavlink": [("nonsense", True), ("udpout:127.0.0.1:99999", True), ("", True), ("serial:", True)],
    # a physics address: malformed ones refused at once by the flag; one with no physics behind it is
    # refused once extra.physics.connect_timeout_s (10 s) passed without a state (a server may start later)
    "physics": [("nonsense", True), ("udp:127.0.0.1:99999", True), ("udp::1", True), ("tcp:127.0.0.1:9002", True),
                ("", True), ("udp:127.0.0.1:1", False)],
    "latlon": [("91,0", True), ("nan,0", True), ("0", True), ("1e308,1", True), ("a,b", True), ("0,1e-320", True)],
    "page_host": [("", False), ("a b", False), ("\u00e9" * 20, False)],  # only printed in the pairing address
    "bind": [("not a host", True), ("8.8.8.8", True), ("", False), ("a" * 300, True)],
}
NUMBER_VALUES = [("nan", True), ("inf", True), ("-inf", True), ("1e308", True), ("-1e308", True), ("1e-320", True),
                 ("abc", True), ("", True), ("1" * 50, True), ("-1", False), ("0", False), ("1e9", False)]


def flag_table(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[tuple[str, ...], str, argparse.Action]]:
    """(command path, option or positional name, action) of every argument of every command."""
    out = []
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                out += flag_table(sub, prefix + (name,))
        elif isinstance(a, (argparse._HelpAction, argparse._VersionAction)):
            continue
        else:
            out.append((prefix, a.option_strings[0] if a.option_strings else a.dest, a))
    return out


def flag_kind(path: tuple[str, ...], name: str, action: argparse.Action) -> str | None:
    """How a flag is fuzzed: "number", "choice", "switch" from the action itself, else FLAG_KINDS."""
    from lotsen.settings import Number

    if (path, name) in FLAG_KINDS:
        return FLAG_KINDS[(path, name)]
    if isinstance(action.type, Number):
        return "number"
    if action.choices is not None:
        return "choice"
    if isinstance(action, (argparse._StoreTrueAction, argparse._StoreFalseAction)):
        return "switch"
    return None


# ------------------------------------------------------------------------------------------------
# cases

@dataclass
class Case:
    command: tuple[str, ...]
    argv: list[str]
    files: dict[str, bytes]  # written into the case folder
    inputs: list[str]  # names in the folder the command reads: they must not change
    must_refuse: bool
    note: str
    links: dict[str, tuple[str, str]] = field(default_factory=dict)  # name -> ("sym"|"hard", target)
    folders: tuple[str, ...] = ()
    cheap: bool = True

    def label(self) -> str:
        return f"{' '.join(self.command)}: {self.note}"


def _with_flag(base: tuple[str, ...], flag: str, values: list[str]) -> list[str]:
    """`base` with `flag` set to `values` (replacing it when present)."""
    argv = list(base)
    if flag.startswith("-"):
        if flag in argv:
            i = argv.index(flag)
            j = i + 1
            while j < len(argv) and not argv[j].startswith("--"):
                j += 1
            del argv[i:j]
        return argv + [flag, *values]
    return argv  # positionals are replaced by the caller


def _positional_index(cmd: Command, name: str) -> int | None:
    """Index in cmd.base of the positional argument `name` (the first word after the command path
    that is a seed file of the right kind)."""
    k = len(cmd.path)
    if k < len(cmd.base) and not cmd.base[k].startswith("--"):
        return k
    return None


def _base_inputs(cmd: Command) -> list[str]:
    return [a for a in cmd.base if a in SEED_FILES]


def flag_cases(parser: argparse.ArgumentParser, rng: random.Random, per_flag: int = 1,
               seeds: dict[str, bytes] | None = None) -> list[Case]:
    """For every flag of every command, `per_flag` hostile values (cases of every kind)."""
    cases: list[Case] = []
    for path, name, action in flag_table(parser):
        cmd = COMMAND_BY_PATH.get(path)
        if cmd is None:
            continue
        kind = flag_kind(path, name, action)
        for _ in range(per_flag):
            cases.append(_flag_case(cmd, name, action, kind or "", rng))
    return cases


def _flag_case(cmd: Command, name: str, action: argparse.Action, kind: str, rng: random.Random) -> Case:
    """One hostile value for one flag of `cmd`, the rest of the command line as in `cmd.base`."""
    base_inputs = _base_inputs(cmd)
    links: dict[str, tuple[str, str]] = {}
    files: dict[str, bytes] = {}
    shown = ""
    if kind == "number":
        value, must = rng.choice(NUMBER_VALUES)
        values = [value] * (action.nargs if isinstance(action.nargs, int) else 1)
        shown = value
    elif kind == "choice":
        values, must, shown = ["bogus"], True, "bogus"
    elif kind == "switch":
        values, must = [], False
    elif kind.startswith("text:"):
        value, must = rng.choice(TEXT_VALUES[kind[5:]])
        values = value.split(" ") if kind == "text:pose" else [value]
        shown = value[:40]
    elif kind.startswith("in:"):
        values, files, links, must, shown = _input_value(kind[3:], rng)
    elif kind in ("out", "out:plot"):
        values, links, must, shown = _output_value(kind, base_inputs, rng)
    elif kind == "out:dir":
        choice = rng.choice(["file", "no_parent"])
        values = ["route.yaml"] if choice == "file" else ["no_such_dir/sub"]
        # replay --record and record --out create their folder (and its parents) as the recorder does
        must = not (name in ("--record",) or cmd.path == ("record",)) or choice == "file"
        shown = choice
    else:
        raise AssertionError(f"{' '.join(cmd.path)} {name}: no fuzz kind (add it to FLAG_KINDS)")
    if kind == "switch":
        argv = list(cmd.base) + [name]
    elif name.startswith("-"):
        argv = _with_flag(cmd.base, name, values)
    else:
        argv = _replace_positional(cmd, values)
    inputs = sorted((set(base_inputs) - ({cmd.base[len(cmd.path)]} if not name.startswith("-") and
                                         _positional_index(cmd, name) is not None else set()))
                    | {v for v in values if v in SEED_FILES})
    return Case(cmd.path, argv, files, inputs, must, f"{name} {shown}".strip(), links, cheap=cmd.cheap or must)


def _input_value(kind: str, rng: random.Random) -> tuple[list[str], dict, dict, bool, str]:
    """A hostile input file for a flag that reads a `kind` seed: (values, files, links, must, what)."""
    choices = ["missing", "folder", "dev_zero", "empty", "wrong_kind", "fifo", "long_name"] + \
        ([] if kind == "ubx" else ["huge"])
    choice = rng.choice(choices)
    files: dict[str, bytes] = {}
    links: dict[str, tuple[str, str]] = {}
    must = True
    if choice == "missing":
        values = ["no_such_file.x"]
    elif choice == "long_name":  # longer than a file system takes (ENAMETOOLONG)
        values = ["n" * 300 + _suffix(kind)]
    elif choice == "folder":
        values = ["."]
    elif choice == "dev_zero":
        values = ["/dev/zero"]
    elif choice == "fifo":
        values, links = ["pipe.fifo"], {"pipe.fifo": ("fifo", "")}
    elif choice == "empty":
        values, files = ["empty" + _suffix(kind)], {"empty" + _suffix(kind): b""}
        must = kind != "config"  # an empty config is the defaults
    elif choice == "wrong_kind":
        other = rng.choice([n for n in ("run.mcap", "capture.ubx", "route.yaml", "mag.csv", "params.json")
                            if SEED_FILES[n] != kind])
        values = [other]
    else:
        values, files = ["huge" + _suffix(kind)], {"huge" + _suffix(kind): b"0," * (40 * 1024 * 1024)}
    return values, files, links, must, choice


def _suffix(kind: str) -> str:
    return {"params": ".json", "calibration": ".json", "mag_csv": ".csv", "data_csv": ".csv", "mcap": ".mcap",
            "ubx": ".ubx"}.get(kind, ".yaml")


def _output_value(kind: str, base_inputs: list[str], rng: random.Random) -> tuple[list[str], dict, bool, str]:
    """A hostile output name: an input (same path, a link), a missing folder, a folder, a bad plot suffix."""
    links: dict[str, tuple[str, str]] = {}
    options = ["no_dir", "folder", "device", "long_name"] + (["same", "symlink", "hardlink"] if base_inputs else []) + \
        (["bad_ext"] if kind == "out:plot" else [])
    choice = rng.choice(options)
    target = rng.choice(base_inputs) if base_inputs else ""
    if choice == "same":
        values = [target]
    elif choice in ("symlink", "hardlink"):
        link = "link_" + target
        links[link] = ("sym" if choice == "symlink" else "hard", target)
        values = [link]
    elif choice == "no_dir":
        values = ["no_such_dir/out" + (".png" if kind == "out:plot" else ".json")]
    elif choice == "long_name":
        values = ["n" * 300 + (".png" if kind == "out:plot" else ".json")]
    elif choice == "folder":
        values = ["."]
    elif choice == "device":
        values = ["pipe.fifo"]  # a special file (as /dev/null would be: never replaced by a regular file)
        links["pipe.fifo"] = ("fifo", "")
    else:
        values = ["x.nosuchext"]
    return values, links, True, f"{choice} {target}".strip()


def _replace_positional(cmd: Command, values: list[str]) -> list[str]:
    argv = list(cmd.base)
    i = _positional_index(cmd, "")
    if i is None:
        return argv[: len(cmd.path)] + values + argv[len(cmd.path):]
    return argv[:i] + values + argv[i + 1:]


def _seed_of_kind(kind: str) -> str:
    return next((n for n, k in SEED_FILES.items() if k == kind), "")


def file_cases(seeds: dict[str, bytes], rng: random.Random, per_command: int,
               commands: tuple[Command, ...] = COMMANDS) -> list[Case]:
    """`per_command` mutated inputs for each of `commands` that reads a seed."""
    cases = []
    for cmd in commands:
        reads = list(cmd.reads.items())
        if not reads:
            continue
        for _ in range(per_command):
            name, kind = rng.choice(reads)
            variant = rng.choice(seed_variants(seeds, kind) or [name])
            m = mutate(kind, seeds[variant], rng, variant)
            # a variant in another format (route.plan for route.yaml) keeps its name: the suffix says how it is read
            target = variant if Path(variant).suffix != Path(name).suffix else name
            argv = [target if a == name else a for a in cmd.base]
            cases.append(Case(cmd.path, argv, {target: m.data}, sorted(set(_base_inputs(cmd)) | {target}),
                              m.must_refuse, f"{target} ({variant}): {m.note}", cheap=cmd.cheap or m.must_refuse))
    return cases


# ------------------------------------------------------------------------------------------------
# the oracle

def judge(case: Case, outcome: Any, refusal_limit_s: float) -> list[str]:
    """What is wrong with `outcome` (empty: nothing): the issue's done-when as checks."""
    problems = []
    if outcome.hang:
        problems.append(f"hang (killed after {outcome.seconds:.0f} s)")
    if outcome.traceback:
        problems.append("traceback")
    if outcome.changed_inputs:
        problems.append(f"input changed: {', '.join(outcome.changed_inputs)}")
    if not outcome.hang and case.must_refuse and outcome.code == 0:
        problems.append("invalid input accepted (exit 0)")
    if not outcome.hang and outcome.code not in (0, None) and not (outcome.stderr.strip() or outcome.stdout.strip()):
        problems.append("non-zero exit without a message")
    if not outcome.hang and case.must_refuse and outcome.code not in (0, None) and outcome.seconds > refusal_limit_s:
        problems.append(f"refused after {outcome.seconds:.1f} s (limit {refusal_limit_s:g} s)")
    return problems


def prepare(case: Case, folder: Path, seeds: dict[str, bytes]) -> None:
    """Write the seeds, the case's own files and links into `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in seeds.items():
        (folder / name).write_bytes(data)
    for name, data in case.files.items():
        (folder / name).write_bytes(data)
    for name, (how, target) in case.links.items():
        p = folder / name
        if how == "sym":
            p.symlink_to(target)
        elif how == "hard":
            os.link(folder / target, p)
        elif how == "fifo":
            os.mkfifo(p)
