"""The live stack compiles every numba kernel before its control loop's first tick: a kernel
compiled inside the loop stalls it for 0.3 s or more (the core's watchdog fires)."""

from __future__ import annotations

import gc
from pathlib import Path

import pytest

from lotsen.runtime.config import load_config
from lotsen.runtime.executor import SimExecutor
from lotsen.stack.launch import build_stack

numba_registry = pytest.importorskip("numba.core.registry")
CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def _signatures() -> dict[str, int]:
    # type(), not isinstance(): the heap holds weak proxies whose referent may be gone, and
    # isinstance() on a dead proxy raises ReferenceError
    return {f"{d.py_func.__module__}.{d.__name__}": len(d.signatures) for d in gc.get_objects()
            if type(d) is numba_registry.CPUDispatcher}


def test_the_core_compiles_nothing_once_its_loop_runs() -> None:
    # the core's parts, as `lotsen run` builds them (realtime=True warms up), on simulated time
    stack = build_stack(load_config(CONFIG), realtime=True, parts=("state", "supervisor"), executor=SimExecutor())
    before = _signatures()
    stack.executor.run_for(5.0)
    after = _signatures()
    compiled = {k: (before.get(k, 0), n) for k, n in after.items() if n != before.get(k, 0)}
    assert not compiled, f"compiled inside the control loop (name: signatures before -> after): {compiled}"
    assert before.get("lotsen.sim.plant._plant_step_py"), "the simulated boat's step was not warmed up"
