"""The `Stack` (executor, model, simulator, nodes, services) and what every assembly needs once:
the vessel model from the config, the simulator from the config, and the one origin resolution."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from lotsen.errors import ConfigError
from lotsen.files import read_json
from lotsen.messages import ModelInfo
from lotsen.model import (
    Environment, VesselGeometry, VesselModel, VesselParameters, load_parameter_file, parameters_from_file,
)
from lotsen.planning import GeoOrigin
from lotsen.runtime.bus import Bus
from lotsen.runtime.config import LaunchConfig
from lotsen.runtime.executor import Executor, Node
from lotsen.sim import DEFAULT_BOAT, GnssConfig, ImuConfig, Plant, SimConfig, SimulatedBoat, Simulator
from lotsen.sim.lakebed import LakeBed, SounderConfig
from lotsen.stack.config import StackConfig, stack_config

#: the repository's examples (demonstration routes for `make run` and the harnesses)
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def example_route(name: str = "figure_eight") -> str:
    path = EXAMPLES / "routes" / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(f"example route {name!r} not found at {path} (the examples ship with the repository)")
    return str(path)


def example_or_file(text: str, kind: str = "routes") -> str:
    """TEXT as given, or, when no such file exists and it is a bare name, the example of that name
    (examples/KIND/NAME.yaml: a route, an experiment): the README's walkthrough runs from any folder."""
    p = Path(text)
    if p.exists() or p.suffix or len(p.parts) != 1:
        return text
    path = EXAMPLES / kind / f"{text}.yaml"
    if not path.is_file():
        names = ", ".join(sorted(f.stem for f in (EXAMPLES / kind).glob("*.yaml")))
        raise ConfigError(f"{kind[:-1]} {text[:40]!r}: no such file, nor an example {kind[:-1]} of that name ({names})")
    return str(path)


def load_parameters(path: str | None) -> VesselParameters:
    """The coefficients of a parameter file (`load_parameter_file`); the defaults without one."""
    if not path:
        return VesselParameters()
    return load_parameter_file(path).parameters


def describe_parameters(path: str | None) -> str:
    """The model's source as every report names it: the file, with the coefficients it takes from
    the defaults, or 'default coefficients'."""
    return load_parameter_file(path).describe() if path else "default coefficients"


def model_info(config: LaunchConfig, model: VesselModel, stamp_s: float = 0.0) -> ModelInfo:
    """What the model in use is and where it came from, for the logs and the page."""
    path = config.vessel.parameters_file
    std: dict = {}
    verdict, modified, source = "", "", "default coefficients"
    if path:
        data = read_json(path, ConfigError)
        loaded = parameters_from_file(data, str(path))
        raw_std = data.get("std")
        std = {k: float(v) for k, v in (raw_std if isinstance(raw_std, dict) else {}).items()
               if isinstance(v, (int, float)) and not isinstance(v, bool)}
        verdict, source = loaded.verdict, loaded.describe()
        modified = datetime.fromtimestamp(Path(path).stat().st_mtime, tz=timezone.utc).isoformat(timespec="seconds")
    boat = boat_description(config, model) if config.mode == "sim" else ""
    return ModelInfo(stamp_s=stamp_s, source=source, file_modified_utc=modified,
                     parameters=model.params.to_dict(), std=std, verdict=verdict, boat=boat)


def vessel_model(config: LaunchConfig) -> VesselModel:
    geom = VesselGeometry(reverse_thrust_ratio=config.vessel.reverse_thrust_ratio)
    return VesselModel(load_parameters(config.vessel.parameters_file), geom)


def sim_config(config: LaunchConfig) -> SimConfig:
    s = config.sim
    env = s.environment.environment()
    gnss = GnssConfig(rate_hz=s.gnss_rate_hz)
    if config.origin is not None:  # the simulated receiver sits where the config says the lake is
        o = config.origin
        gnss = GnssConfig(rate_hz=s.gnss_rate_hz, origin_lat_deg=o.lat_deg, origin_lon_deg=o.lon_deg,
                          origin_height_m=o.height_m)
    lakebed, sounder = None, SounderConfig()
    if s.lakebed.depths_m:
        b = s.lakebed
        lakebed = LakeBed(b.depths_m, b.origin_m, b.cell_m)
        # the true transducer: the simulated boat's antenna plus the measured offset from it
        antenna = simulated_boat(config).gnss_antenna_m
        offset = config.vessel.antenna_to_transducer_m
        sounder = SounderConfig(rate_hz=b.sounder_rate_hz, noise_std_m=b.sounder_noise_m,
                                dropout_probability=b.sounder_dropout, max_range_m=b.sounder_max_range_m,
                                transducer_m=(antenna[0] + offset[0], antenna[1] + offset[1]),
                                draft_m=config.vessel.transducer_draft_m)
    return SimConfig(dt_s=s.dt_s, seed=config.seed, imu=ImuConfig(rate_hz=s.imu_rate_hz), gnss=gnss, environment=env,
                     lakebed=lakebed, sounder=sounder)


def simulated_boat(config: LaunchConfig, model: VesselModel | None = None) -> SimulatedBoat:
    """The simulated boat of `sim.boat`: the lake boat with the section's changes, or the model
    in use itself (`ideal: true`)."""
    b = config.sim.boat
    model = model or vessel_model(config)
    if b.ideal:
        return SimulatedBoat.ideal_for(model)
    boat = DEFAULT_BOAT
    if b.parameters_file:
        loaded = load_parameter_file(b.parameters_file)
        # a file that takes some coefficients from the defaults says so in every report of the boat
        boat = boat.with_parameters(loaded.parameters,
                                    name=f"{boat.name} with {loaded.describe()}" if loaded.defaults_for else None)
    if b.parameters:
        boat = boat.with_parameters(VesselParameters.from_dict({**boat.parameters.to_dict(), **b.parameters},
                                                               source="sim.boat.parameters"))
    changes: dict[str, Any] = {}
    if b.name is not None:
        changes["name"] = b.name
    if b.thrust_dead_band_rps is not None:
        changes["thrust_dead_band_rps"] = b.thrust_dead_band_rps
    if b.command_latency_s is not None:
        changes["command_latency_s"] = b.command_latency_s
    if b.gnss_antenna_m is not None:
        changes["gnss_antenna_m"] = b.gnss_antenna_m
    if b.gnss_antenna_height_m is not None:
        changes["hull"] = replace(boat.hull, gnss_antenna_height_m=b.gnss_antenna_height_m)
    if b.reverse_thrust_ratio is not None:
        changes["geometry"] = replace(boat.geometry, reverse_thrust_ratio=b.reverse_thrust_ratio)
    limits = boat.limits
    if b.motor_time_constant_s is not None:
        limits = replace(limits, motor_time_constant_s=b.motor_time_constant_s)
    if b.alpha_rate_max_deg_s is not None:
        limits = replace(limits, alpha_rate_max_radps=math.radians(b.alpha_rate_max_deg_s))
    return replace(boat, limits=limits, **changes)


def physics_plant(config: LaunchConfig, realtime: bool = False) -> Plant | None:
    """The external physics of `extra.physics.address` as a plant (not yet connected: it connects
    when the simulator places the boat), or None: lotsen's own simulated boat. `realtime`: at
    wall-clock pace (a frame's wait holds up the control loop)."""
    physics = stack_config(config).extra.physics
    if physics.address is None:
        return None
    from lotsen.physics.client import UdpPhysics  # sockets only on this path

    return UdpPhysics(physics, dt_s=config.sim.dt_s, realtime=realtime)


def simulator_from_config(config: LaunchConfig, model: VesselModel | None = None,
                          realtime: bool = False) -> Simulator:
    """The simulated boat of the config (never the model object the controllers use): lotsen's own
    (`sim.boat`), or the external physics of `extra.physics` behind lotsen's sensor models."""
    plant = physics_plant(config, realtime)
    if plant is not None:
        try:
            return Simulator(plant, config=sim_config(config), x0=config.sim.initial_state)
        except Exception:
            plant.close()
            raise
    return Simulator(simulated_boat(config, model), config=sim_config(config), x0=config.sim.initial_state)


def boat_description(config: LaunchConfig, model: VesselModel | None = None) -> str:
    """One line for reports and the page: the simulated boat, or the external physics."""
    address = stack_config(config).extra.physics.address
    if address:
        return f"external physics at {address}"
    model = model or vessel_model(config)
    return simulated_boat(config, model).describe(model.params)


def physics_antenna_mismatch(config: LaunchConfig) -> str:
    """'' or a warning: the external physics's receiver (extra.physics.gnss_antenna_*, where lotsen's
    receiver model places the fixes on that hull) is not where vessel.gnss_antenna_* tells the
    estimator it is. The estimator then corrects the fixes for a lever arm they do not have: with a
    25 cm antenna height it is 4 mm a degree of roll, sideways, and on the 6-DOF hull that error fed
    the helm, the helm rolled the hull, and the estimate left its 3 sigma (docs/physics.md)."""
    stack = stack_config(config)
    physics, vessel = stack.extra.physics, stack.vessel
    if physics.address is None:
        return ""
    there = (*physics.gnss_antenna_m, physics.gnss_antenna_height_m)
    believed = (*vessel.gnss_antenna_m, vessel.gnss_antenna_height_m)
    if max(abs(a - b) for a, b in zip(there, believed)) <= 1e-3:
        return ""
    return (f"the physics's GNSS antenna (extra.physics.gnss_antenna_m {list(physics.gnss_antenna_m)}, "
            f"gnss_antenna_height_m {physics.gnss_antenna_height_m:g}) is not where the estimator places it "
            f"(vessel.gnss_antenna_m {list(vessel.gnss_antenna_m)}, gnss_antenna_height_m "
            f"{vessel.gnss_antenna_height_m:g}): the fixes will be corrected for a lever arm they do not have")


def resolve_origin(config: StackConfig) -> GeoOrigin | None:
    """The geodetic origin of the local frame, resolved once for every part of a stack: the
    config's `origin`, else the simulated receiver's origin in simulation, else None (the
    estimator takes the first usable fix on the boat)."""
    if config.origin is not None:
        o = config.origin
        return GeoOrigin(o.lat_deg, o.lon_deg, o.height_m)
    if config.mode == "sim" or config.extra.emulated:
        g = sim_config(config).gnss
        return GeoOrigin(g.origin_lat_deg, g.origin_lon_deg, g.origin_height_m)
    return None


@dataclass
class Stack:
    config: StackConfig
    executor: Executor
    model: VesselModel
    origin: GeoOrigin | None = None
    simulator: Simulator | None = None
    nodes: dict[str, Node] = field(default_factory=dict)
    services: dict[str, Any] = field(default_factory=dict)  # web server, recorder, ... (non-node parts)

    def __post_init__(self) -> None:
        self.config = stack_config(self.config)  # a LaunchConfig's extra sections typed (a StackConfig as it is)

    @property
    def bus(self) -> Bus:
        return self.executor.bus

    def add(self, node: Node) -> Node:
        self.nodes[node.name] = node
        return self.executor.add_node(node)

    def banner(self, line: str) -> None:
        self.services.setdefault("banner", []).append(line)

    def on_shutdown(self, fn: Any) -> None:
        self.services.setdefault("on_shutdown", []).append(fn)

    def shutdown(self) -> None:
        """Close the services (recorder, servers, bridges) in reverse order of attachment."""
        for close in reversed(self.services.pop("on_shutdown", [])):
            try:
                close()
            except Exception as exc:  # noqa: BLE001 - keep closing the rest; say what failed
                print(f"lotsen: shutdown of {getattr(close, '__qualname__', close)} failed: {exc!r}", flush=True)
