"""The package graph points down only (docs/architecture.md): a test that fails on any upward import or cycle.

Every import counts, module-level or inside a function: an import hidden in a function is still an arrow.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2] / "lotsen"

# Layer of each top-level unit; an import may only go to a lower layer, or sideways where listed in SIDEWAYS.
LAYERS: dict[str, int] = {
    "errors": 0, "messages": 0, "files": 0, "settings": 0,
    "model": 1,
    "sim": 2, "planning": 2,
    "fusion": 3, "control": 3, "sysid": 3,
    "runtime": 4,
    "supervisor": 5, "drivers": 5, "logs": 5, "transport": 5, "web": 5,
    "stack": 6,
    "harness": 7,
    "cli": 8,
    "__main__": 9,
}
# Same-layer arrows that are part of the design (each must stay acyclic).
SIDEWAYS: set[tuple[str, str]] = {
    ("logs", "transport"),  # logs decode recorded messages with the transport's codec
    ("files", "errors"), ("messages", "errors"),  # the base: errors is the root of all
}


def unit_of(path: Path, root: Path = ROOT) -> str:
    rel = path.relative_to(root)
    return rel.parts[0].removesuffix(".py") if rel.parts else ""


def imported_units(path: Path, root: Path = ROOT) -> set[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    package = ".".join(("lotsen",) + path.relative_to(root).with_suffix("").parts[:-1])
    found: set[str] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import: resolve against this module's package
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                names = [".".join(base + ([node.module] if node.module else []))]
            else:
                names = [node.module or ""]
            if names[0] == "lotsen":  # "from lotsen import x": x is the unit
                names = [f"lotsen.{a.name}" for a in node.names]
        for name in names:
            parts = name.split(".")
            if parts[0] == "lotsen" and len(parts) > 1:
                found.add(parts[1])
    return found


def package_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in ROOT.rglob("*.py"):
        unit = unit_of(path)
        if unit == "__init__":
            continue
        graph.setdefault(unit, set()).update(u for u in imported_units(path) if u not in (unit, "__init__"))
    return graph


def test_every_unit_has_a_layer():
    missing = sorted(set(package_graph()) - set(LAYERS))
    assert not missing, f"give these packages a layer in LAYERS (and docs/architecture.md): {missing}"


def test_no_upward_or_undeclared_sideways_import():
    bad = []
    for unit, targets in package_graph().items():
        for target in targets:
            if target not in LAYERS:
                continue
            if LAYERS[target] > LAYERS[unit] or (LAYERS[target] == LAYERS[unit] and (unit, target) not in SIDEWAYS):
                bad.append(f"{unit} (layer {LAYERS[unit]}) imports {target} (layer {LAYERS[target]})")
    assert not bad, "imports against the layer order:\n" + "\n".join(sorted(bad))


def test_the_package_graph_has_no_cycle():
    graph = package_graph()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(u: str) -> list[str] | None:
        state[u] = 1
        stack.append(u)
        for v in sorted(graph.get(u, ())):
            if state.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in state and (cycle := visit(v)):
                return cycle
        state[u] = 2
        stack.pop()
        return None

    for u in sorted(graph):
        if u not in state and (cycle := visit(u)):
            pytest.fail("package cycle: " + " -> ".join(cycle))


def test_the_checker_sees_hidden_and_relative_imports(tmp_path):
    """The checker itself can fail: an import inside a function, and a relative one, are both arrows."""
    pkg = tmp_path / "lotsen"
    (pkg / "runtime").mkdir(parents=True)
    module = pkg / "runtime" / "bus.py"
    module.write_text("def f():\n    from lotsen.web import server\n\nfrom ..stack import launch\nfrom . import clock\n")
    assert imported_units(module, pkg) == {"web", "stack", "runtime"}


# What the algorithms share with the simulated boat is the model, never the simulator itself:
# a controller or an estimator that imported lotsen.sim could quietly use the boat's truth.
ALGORITHMS_WITHOUT_SIM = ("model", "planning", "fusion", "control", "sysid", "supervisor", "runtime")


def test_no_algorithm_imports_the_simulator():
    graph = package_graph()
    bad = sorted(u for u in ALGORITHMS_WITHOUT_SIM if "sim" in graph.get(u, set()))
    assert not bad, f"these packages import lotsen.sim (share the model instead): {bad}"
