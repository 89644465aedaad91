"""Wire nodes into a running stack from a validated `LaunchConfig`.

`build_stack` creates the executor (simulated time or wall clock), the boat (simulated, or the
hardware drivers), and every node the config asks for. Parts that live in optional subpackages
(fusion, control, supervisor, web, logs, drivers) are added by `_ADDERS`, each a small function,
so the wiring stays readable in one place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

from lotsen.errors import ConfigError
from lotsen.files import read_json
from lotsen.messages import Topic
from lotsen.model import Environment, VesselGeometry, VesselModel, VesselParameters
from lotsen.runtime.bus import Bus
from lotsen.runtime.config import LaunchConfig
from lotsen.runtime.executor import Executor, Node, RealtimeExecutor, SimExecutor
from lotsen.runtime.nodes.sim_boat import SimulatedBoatNode
from lotsen.sim import ImuConfig, GnssConfig, SimConfig, Simulator


def load_parameters(path: str | None) -> VesselParameters:
    if not path:
        return VesselParameters()
    return VesselParameters.from_dict(read_json(path, ConfigError), source=str(path))


def vessel_model(config: LaunchConfig) -> VesselModel:
    geom = VesselGeometry(reverse_thrust_ratio=config.vessel.reverse_thrust_ratio)
    return VesselModel(load_parameters(config.vessel.parameters_file), geom)


def simulator_from_config(config: LaunchConfig, model: VesselModel | None = None) -> Simulator:
    s = config.sim
    e = s.environment
    env = Environment(current_speed_mps=e.current_speed_mps, current_to_deg=e.current_to_deg,
                      wind_speed_mps=e.wind_speed_mps, wind_from_deg=e.wind_from_deg,
                      wave_force_std_N=e.wave_force_std_N)
    cfg = SimConfig(dt_s=s.dt_s, seed=config.seed, imu=ImuConfig(rate_hz=s.imu_rate_hz),
                    gnss=GnssConfig(rate_hz=s.gnss_rate_hz), environment=env)
    return Simulator(model or vessel_model(config), config=cfg, x0=s.initial_state)


@dataclass
class Stack:
    config: LaunchConfig
    executor: Executor
    model: VesselModel
    simulator: Simulator | None = None
    nodes: dict[str, Node] = field(default_factory=dict)
    services: dict[str, Any] = field(default_factory=dict)  # web server, recorder, ... (non-node parts)

    @property
    def bus(self) -> Bus:
        return self.executor.bus

    def add(self, node: Node) -> Node:
        self.nodes[node.name] = node
        return self.executor.add_node(node)


Adder = Callable[[Stack], None]
_ADDERS: list[tuple[str, Adder]] = []


def register_part(name: str, adder: Adder) -> None:
    """Optional parts (fusion, control, supervisor, web, logs) register how they join a stack."""
    _ADDERS[:] = [(n, a) for n, a in _ADDERS if n != name] + [(name, adder)]


def build_stack(config: LaunchConfig, realtime: bool, parts: tuple[str, ...] | None = None) -> Stack:
    """The whole stack for `config`. `parts` limits the optional parts (None = all registered)."""
    executor: Executor = RealtimeExecutor() if realtime else SimExecutor()
    model = vessel_model(config)
    stack = Stack(config=config, executor=executor, model=model)
    if config.mode == "sim":
        stack.simulator = simulator_from_config(config, model)
        stack.add(SimulatedBoatNode(stack.simulator, command_deadline_s=config.nodes.command_deadline_s))
    else:
        from lotsen.drivers import add_hardware_boat, hardware_config_from_launch

        add_hardware_boat(stack, emulated=bool(config.extra.get("emulated", False)),
                          config=hardware_config_from_launch(config.extra))
    _load_builtin_parts()
    for name, adder in _ADDERS:
        if parts is None or name in parts:
            adder(stack)
    return stack


def _load_builtin_parts() -> None:
    """Import the modules that register parts; a part whose subpackage is absent is skipped."""
    import importlib

    for module in ("lotsen.runtime.nodes.parts",):
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name != module:
                raise


def summary(stack: Stack) -> str:
    """One-line state of the boat for the console."""
    truth = stack.bus.latest.get(Topic.TRUTH)
    t = stack.executor.clock.now()
    if truth is None:
        return f"t={t:7.1f} s  (no state yet)"
    return (f"t={t:7.1f} s  N={truth.north_m:8.2f} m  E={truth.east_m:8.2f} m  "
            f"heading={math.degrees(truth.heading_rad) % 360:6.1f} deg  speed={truth.speed_mps:5.2f} m/s")
