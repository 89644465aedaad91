"""The README's lab-loop walkthrough, run as a new user runs it: every command of its block, in a
folder of its own (nothing of the checkout in reach but the installed `lotsen`), on the boat file it
writes (not the default boat). The boat file must be named in every report, identify must answer,
and the missions must fly with the answer and with the defaults.

Two additions keep it a test and not a benchmark: `lotsen experiment design` gets `--iterations 3
--robust-samples 1` (the full design is 3-4 min of CPU; its form, and the loop after it, are the
same), and the endless `lotsen run` gets a free port and `--duration`. With
LOTSEN_WALKTHROUGH_EXACT=1 the design runs exactly as written (the run's port and duration stay).
bench/results/hull.md runs the same loop with the full design on the independent 6-DOF hull.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from lotsen.stack.roles import free_port

ROOT = Path(__file__).resolve().parents[1]


def walkthrough_commands(readme: str) -> list[str]:
    """The shell commands of the first ```sh block under "## The lab loop", continuation lines
    joined, comments dropped."""
    section = readme[readme.index("## The lab loop"):]
    block = section[section.index("```sh") + len("```sh"):]
    block = block[:block.index("```")]
    block = re.sub(r"\\\n\s*", "", block)
    out = []
    for line in block.splitlines():
        line = re.sub(r"\s+#\s.*$", "", line).strip()
        if line and not line.startswith("#"):
            out.append(line)
    return out


def test_the_walkthrough_is_parsed_into_its_commands():
    cmds = walkthrough_commands((ROOT / "README.md").read_text())
    assert cmds[0].startswith("echo ") and cmds[0].endswith("> myboat.json")
    lotsen = [c.split()[1] for c in cmds[1:]]
    assert lotsen == ["experiment", "experiment", "experiment", "identify", "mission", "mission", "run"], cmds
    runs_the_boat = [c for c in cmds if c.split()[1] in ("mission", "run") or " run " in c]
    assert runs_the_boat and all("--boat myboat.json" in c for c in runs_the_boat), runs_the_boat
    assert not any("examples/" in c or "config/" in c for c in cmds), "the walkthrough must run from any folder"


@pytest.mark.slow
def test_the_readme_walkthrough_runs_as_written_on_a_boat_that_is_not_the_default(tmp_path):
    cmds = walkthrough_commands((ROOT / "README.md").read_text())
    exact = os.environ.get("LOTSEN_WALKTHROUGH_EXACT") == "1"
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
               LOTSEN_RUNTIME_DIR=str(tmp_path / ".runtime"), LOTSEN_CONFIG_DIR=str(tmp_path / ".config"))
    said: dict[str, str] = {}
    for cmd in cmds:
        if cmd.startswith("lotsen experiment design") and not exact:
            cmd += " --iterations 3 --robust-samples 1"
        if cmd.startswith("lotsen run "):
            cmd += f" --port {free_port()} --duration 12"
        p = subprocess.run(cmd, shell=True, executable="/bin/bash", cwd=tmp_path, env=env, capture_output=True,
                           text=True, timeout=900)
        assert p.returncode == 0, f"{cmd}\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}"
        said[cmd] = p.stdout + p.stderr
    boat = "lake boat with myboat.json"
    # the experiment's lines, identify's output, report and parameter file name the boat file
    experiment_lines = [out for cmd, out in said.items() if cmd.startswith("lotsen experiment run")]
    assert len(experiment_lines) == 2 and all(boat in out for out in experiment_lines)
    identified = json.loads((tmp_path / "params.json").read_text())
    assert identified["verdict"] in ("ok", "weak", "predictive"), identified.get("identification")
    assert set(identified["recorded_on"]) == {"run.mcap", "check.mcap"}
    assert all(v.startswith(boat) for v in identified["recorded_on"].values())
    assert boat in (tmp_path / "report.html").read_text()
    # both missions flew the boat file's boat, one with the answer, one with the defaults
    with_id = json.loads((tmp_path / "with_identified.json").read_text())
    with_def = json.loads((tmp_path / "with_defaults.json").read_text())
    assert with_id["boat"].startswith(boat) and with_def["boat"].startswith(boat)
    assert with_id["model"] == "params.json" and with_def["model"] == "default coefficients"
    assert with_id["completed"] and with_def["completed"]
    # at the figure eight's 0.5 m/s the two track alike (0.65 and 0.66 cm as written, measured): the answer
    # may not be worse; where the model matters (speed, tight turns) is bench/results/hull.md's
    assert with_id["cross_track_rms_m"] <= 1.1 * with_def["cross_track_rms_m"]
    # the stack at wall-clock pace: the boat file and the answer as the model in use
    run_out = next(out for cmd, out in said.items() if cmd.startswith("lotsen run "))
    assert f"simulated boat: {boat}" in run_out and "params.json" in run_out
