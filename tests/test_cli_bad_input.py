"""Bad input at the command line: clear errors within seconds, never a traceback or a hang."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from lotsen.cli.main import main
from lotsen.planning import budget as budget_module
from lotsen.runtime.lifetime import RUNTIME_DIR_ENV

REPO = Path(__file__).resolve().parents[1]
HEAD = "harbour: {north: 0, east: 0, heading_deg: 0}\n"


def _plan(tmp_path, text: str, capsys) -> tuple[int, str, float]:
    path = tmp_path / "r.yaml"
    path.write_text(text)
    t0 = time.monotonic()
    code = main(["plan", str(path)])
    return code, capsys.readouterr().err, time.monotonic() - t0


@pytest.mark.parametrize("text, expected", [
    (HEAD + "nodes: [{north: 20, east: 0, heading_deg: 0, speed_mps: 0.5}]\n"
            "area: [[-10, -10], [1.0e+308, -10], [40, 10], [-10, 10]]\n", "area[1].north"),
    (HEAD + "nodes: [{north: 127000, east: 0, heading_deg: 0, speed_mps: 0.5}]\n", "nodes[0].north"),
    (HEAD + "nodes: [{north: 20, east: 0, heading_deg: 1.0e+308, speed_mps: 0.5}]\n", "heading_deg"),
    (HEAD + "nodes: [{north: 20, east: 0, heading_deg: 0, speed_mps: 0.5}]\nnodes: []\n", "duplicate key 'nodes'"),
])
def test_lotsen_plan_refuses_hostile_routes_at_once(tmp_path, capsys, text, expected):
    code, err, took_s = _plan(tmp_path, text, capsys)
    assert code == 2 and expected in err and "Traceback" not in err, err
    assert took_s < 2.0


def test_lotsen_plan_has_the_pages_time_budget(tmp_path, capsys, monkeypatch):
    """The route plans in the planner worker with the page's budget; here a budget of 0.1 s is
    too short for the figure eight flown six times over (72 legs, ~0.6 s of planning on an idle
    machine: the single 12-leg loop plans in about 0.1 s, too close to the budget to be sure of
    the outcome), and the command says so instead of running on."""
    import lotsen.cli.plan

    monkeypatch.setattr(lotsen.cli.plan, "planning_budget", lambda: budget_module.PlanningBudget(time_s=0.1))
    lines = (REPO / "examples" / "routes" / "figure_eight.yaml").read_text().splitlines()
    harbour, area = (next(line for line in lines if line.startswith(key)) for key in ("harbour", "area"))
    nodes = [line for line in lines if line.strip().startswith("- {north")]
    route = "\n".join([harbour, "nodes:", *nodes, *nodes[1:] * 5, area]) + "\n"
    code, err, took_s = _plan(tmp_path, route, capsys)
    assert code == 2 and "longer than its budget of 0.1 s" in err, err
    assert took_s < 30.0  # the worker's start-up (an interpreter) and 0.1 s of planning


def test_lotsen_plan_refuses_a_route_over_the_size_budget(tmp_path, capsys):
    nodes = ", ".join(f"{{north: {k * 1.5 + 1.5}, east: 0, heading_deg: 0, speed_mps: 0.5}}" for k in range(250))
    code, err, took_s = _plan(tmp_path, HEAD + f"nodes: [{nodes}]\n", capsys)
    assert code == 2 and "planning budget" in err and "extra.planning.max_nodes" in err, err
    assert took_s < 2.0


@pytest.mark.parametrize("host, expected", [("not a host", "is not a host name or address"),
                                            ("8.8.8.8", "is not an address of this machine")])
def test_a_bad_web_host_is_one_clear_error_before_any_process_starts(tmp_path, capsys, monkeypatch, host, expected):
    monkeypatch.setenv(RUNTIME_DIR_ENV, str(tmp_path / "rt"))
    cfg = tmp_path / "c.yaml"
    cfg.write_text(f"mode: sim\nlogging: {{enabled: false}}\nweb:\n  host: {host}\n  port: 0\n")
    t0 = time.monotonic()
    code = main(["run", str(cfg)])
    captured = capsys.readouterr()
    assert code == 2
    assert captured.err.strip() == f"error: web.host: {host!r} {expected}" + captured.err.strip().split(expected, 1)[1]
    assert "Traceback" not in captured.err and "processes:" not in captured.out
    assert time.monotonic() - t0 < 5.0
