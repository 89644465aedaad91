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
    "fusion": 3, "control": 3, "sysid": 3, "bathymetry": 3,
    "runtime": 4,
    "supervisor": 5, "drivers": 5, "logs": 5, "transport": 5, "web": 5, "physics": 5,
    "stack": 6,
    "harness": 7,
    "cli": 8,
    "__main__": 9,
}
# Same-layer arrows that are part of the design (each must stay acyclic).
SIDEWAYS: set[tuple[str, str]] = {
    ("logs", "transport"),  # logs decode recorded messages with the transport's codec
    ("web", "logs"),  # the page's log list and downloads read the files with the logs' MCAP walk
    ("files", "errors"), ("messages", "errors"), ("settings", "errors"),  # the base: errors is the root of all
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
    cycle = find_cycle(package_graph())
    assert cycle is None, "package cycle: " + " -> ".join(cycle)


def test_the_checker_sees_hidden_and_relative_imports(tmp_path):
    """The checker itself can fail: an import inside a function, and a relative one, are both arrows."""
    pkg = tmp_path / "lotsen"
    (pkg / "runtime").mkdir(parents=True)
    module = pkg / "runtime" / "bus.py"
    module.write_text("def f():\n    from lotsen.web import server\n\nfrom ..stack import launch\nfrom . import clock\n")
    assert imported_units(module, pkg) == {"web", "stack", "runtime"}


# What the algorithms share with the simulated boat is the model, never the simulator itself:
# a controller or an estimator that imported lotsen.sim could quietly use the boat's truth.
ALGORITHMS_WITHOUT_SIM = ("model", "planning", "fusion", "control", "sysid", "bathymetry", "supervisor", "runtime")


def test_no_algorithm_imports_the_simulator():
    graph = package_graph()
    bad = sorted(u for u in ALGORITHMS_WITHOUT_SIM if "sim" in graph.get(u, set()))
    assert not bad, f"these packages import lotsen.sim (share the model instead): {bad}"


# The allowed import sets of docs/architecture.md ("imports" column), besides the base (layer 0:
# errors, messages, files, settings), which every package may use. Stack, harness and cli may
# import everything below them (the layer test).
BASE = {"errors", "messages", "files", "settings", "__version__"}
ALLOWED: dict[str, set[str]] = {
    "model": set(),
    "sim": {"model"}, "planning": {"model"},
    "fusion": {"model"}, "control": {"model"}, "sysid": {"model"}, "bathymetry": {"model", "planning"},
    "runtime": {"model"},
    "supervisor": {"runtime", "model", "control", "planning"},
    "drivers": {"runtime", "model", "sim"},
    "logs": {"runtime", "model", "transport", "sysid"},
    "transport": {"runtime", "model"},
    "web": {"runtime", "planning", "logs", "bathymetry"},
    "physics": {"model", "sim"},
}
DOC = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def test_each_package_imports_only_its_documented_set():
    graph = package_graph()
    bad = [f"{unit} imports {sorted(graph.get(unit, set()) - BASE - allowed)} (allowed: {sorted(allowed)})"
           for unit, allowed in ALLOWED.items() if graph.get(unit, set()) - BASE - allowed]
    assert not bad, "imports outside docs/architecture.md's sets:\n" + "\n".join(bad)


def test_the_documented_sets_are_the_ones_tested():
    """The "imports" column of docs/architecture.md names exactly the packages ALLOWED lists."""
    rows = {}
    for line in DOC.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[1].startswith("`lotsen.") and "," not in cells[1]:
            rows[cells[1].strip("`").removeprefix("lotsen.")] = cells[3]
    for unit, allowed in ALLOWED.items():
        assert unit in rows, f"docs/architecture.md has no row for lotsen.{unit}"
        named = {w for w in rows[unit].replace(",", " ").replace(";", " ").replace("(", " ").replace(")", " ").split()
                 if w in LAYERS} - BASE
        assert named == allowed, f"lotsen.{unit}: the doc names {sorted(named)}, the test allows {sorted(allowed)}"


def module_graph(root: Path = ROOT, annotations: bool = False) -> dict[str, set[str]]:
    """Module -> the modules of the same package it imports at run time (module level or inside a
    function; imports under `if TYPE_CHECKING:` are annotations only and do not count, unless
    `annotations`)."""
    def name(p: Path) -> str:
        parts = p.relative_to(root.parent).with_suffix("").parts
        return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)

    modules = {name(p): p for p in root.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for mod, path in modules.items():
        tree = ast.parse(path.read_text())
        hidden = set() if annotations else {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                                            and "TYPE_CHECKING" in ast.unparse(node.test) for n in ast.walk(node)}
        pkg = mod if path.name == "__init__.py" else mod.rsplit(".", 1)[0]
        found: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in hidden:
                continue
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = (".".join(pkg.split(".")[: len(pkg.split(".")) - node.level + 1] + ([node.module] if node.module
                        else [])) if node.level else node.module or "")
                found.add(base)
                found.update(f"{base}.{a.name}" for a in node.names)
        package = ".".join(mod.split(".")[:2])
        graph[mod] = {m for m in found if m in modules and m != mod and m != package
                      and ".".join(m.split(".")[:2]) == package}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
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
            return cycle
    return None


def test_no_module_cycle_inside_a_package():
    cycle = find_cycle(module_graph())
    assert cycle is None, "module cycle inside a package: " + " -> ".join(cycle)


def test_the_supervisors_modules_point_one_way_even_in_their_annotations():
    """issue 41 item 7: node <-> failsafes <-> modes <-> prearm imported each other (under
    TYPE_CHECKING): inputs and modes at the bottom, failsafes, prearm, node above them."""
    graph = {m: deps for m, deps in module_graph(annotations=True).items() if m.startswith("lotsen.supervisor.")}
    cycle = find_cycle(graph)
    assert cycle is None, "supervisor module cycle (annotations counted): " + " -> ".join(cycle)
    assert "lotsen.supervisor.node" not in set().union(*graph.values())


def test_the_module_checker_sees_a_cycle_hidden_in_a_function(tmp_path):
    pkg = tmp_path / "lotsen" / "sysid"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from lotsen.sysid.b import x\n")
    (pkg / "b.py").write_text("def x():\n    from lotsen.sysid import a\n")
    (pkg / "c.py").write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from lotsen.sysid.a import x\n")
    graph = module_graph(tmp_path / "lotsen")
    assert find_cycle(graph) in (["lotsen.sysid.a", "lotsen.sysid.b", "lotsen.sysid.a"],
                                 ["lotsen.sysid.b", "lotsen.sysid.a", "lotsen.sysid.b"])
    assert graph["lotsen.sysid.c"] == set()
