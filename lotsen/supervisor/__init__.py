"""The supervisor (docs/failsafes.md): operator requests, modes as classes (`modes`), failsafes as
monitor objects (`failsafes`), and the one ship_command of the stack (`node.SupervisorNode`)."""

from lotsen.supervisor.failsafes import FailsafeConfig, Monitor, PersistentCondition
from lotsen.supervisor.modes import Mode
from lotsen.supervisor.node import SupervisorConfig, SupervisorInputs, SupervisorNode, path_message

__all__ = ["FailsafeConfig", "Mode", "Monitor", "PersistentCondition", "SupervisorConfig", "SupervisorInputs",
           "SupervisorNode", "path_message"]
