"""The supervisor (docs/failsafes.md): operator requests, modes as classes (`modes`), failsafes as
monitor objects (`failsafes`), and the one ship_command of the stack (`node.SupervisorNode`).

The names below load their module on first use: the web server and the launcher read
`failsafes.FailsafeConfig` and must not import the controllers (OSQP, scipy) with it."""

from __future__ import annotations

from typing import Any

__all__ = ["FailsafeConfig", "Mode", "Monitor", "PersistentCondition", "SupervisorConfig", "SupervisorInputs",
           "SupervisorNode", "path_message"]


def __getattr__(name: str) -> Any:
    if name in ("FailsafeConfig", "Monitor", "PersistentCondition"):
        from lotsen.supervisor import failsafes as module
    elif name == "Mode":
        from lotsen.supervisor import modes as module
    elif name == "SupervisorInputs":
        from lotsen.supervisor import inputs as module
    elif name in ("SupervisorConfig", "SupervisorNode", "path_message"):
        from lotsen.supervisor import node as module
    else:
        raise AttributeError(f"module 'lotsen.supervisor' has no attribute {name!r}")
    return getattr(module, name)
