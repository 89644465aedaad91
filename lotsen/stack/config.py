"""The launch configuration of a stack, typed and validated once, when it is loaded.

`lotsen.runtime.config.LaunchConfig` holds the sections the runtime knows (mode, sim, vessel,
nodes, web, logging, origin); its `extra` sections belong to the parts above the runtime
(processes, planner, failsafes, recorder, web server, bridges, drivers). `StackConfig` is the same
config with every `extra` section a typed field (`ExtraConfig`), built from the YAML by
`load_stack_config` (or from a `LaunchConfig` by `stack_config`) in one pass: a bad value of any
section is a ConfigError naming its key path (``extra.failsafes.link_timeout_s: ...``) before
any process starts, and the parts read typed attributes (`config.extra.failsafes`).

The keys users write are unchanged: ``extra: {processes: ..., failsafes: ..., web: ...}``.
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from lotsen.drivers.config import HardwareConfig
from lotsen.errors import ConfigError
from lotsen.logs.recorder import RecorderConfig
from lotsen.messages import Topic
from lotsen.physics.config import PhysicsConfig
from lotsen.planning import PlannerConfig
from lotsen.planning.budget import PlanningBudget
from lotsen.runtime.config import LaunchConfig, from_mapping, load_config
from lotsen.settings import value_range as _r
from lotsen.supervisor.failsafes import FailsafeConfig
from lotsen.transport.ros2_bridge import Ros2BridgeConfig
from lotsen.transport.zenoh_bridge import BridgeConfig
from lotsen.web.mavlink.options import MavlinkExtra
from lotsen.web.options import WebExtra

#: what the ROS 2 process publishes to ROS 2 by default (the seed's Table 3 and the status)
ROS2_DEFAULT_PUBLISH = (Topic.IMU_RAW, Topic.IMU_MAG, Topic.GNSS, Topic.RPM, Topic.STATE, Topic.SENS_FUS,
                        Topic.PATH, Topic.SHIP_COMMAND, Topic.VELOCITY_COMMAND, Topic.ANGLE_COMMAND,
                        Topic.SUPERVISOR, Topic.BATTERY, Topic.ALERT, Topic.PROGRESS)


@dataclass(frozen=True)
class ProcessOptions:
    """`extra.processes`: the processes of `lotsen run` (docs/architecture.md)."""

    zenoh_port: int = field(default=0, metadata=_r(0, 65535))  # 0: a free port on 127.0.0.1
    core_cpu: int | None = field(default=None, metadata=_r(0, 1023))  # pin the core here; None: the last CPU no other run's real-time core holds (2 or more CPUs)
    core_nice: int = field(default=-10, metadata=_r(-20, 19))  # applied when permitted
    # SCHED_FIFO for the core when permitted (0: off). Needed, not a luxury: with the kernel's
    # autogroups a nice value only counts inside one terminal session, so any busy program
    # elsewhere takes half the CPU from a niced core (stalls of 0.3-0.5 s measured under load)
    realtime_priority: int = field(default=10, metadata=_r(0, 98))
    lock_memory: bool = True  # mlockall in the core (no page faults in the control loop)
    recorder_nice: int = field(default=0, metadata=_r(-20, 19))
    web_nice: int = field(default=5, metadata=_r(-20, 19))
    watchdog_s: float = field(default=0.3, metadata=_r(0.05, 5.0))  # core loop silent this long: neutral
    watchdog_exit_s: float = field(default=3.0, metadata=_r(0.2, 60.0))  # ... this long: the core exits
    restart_backoff_s: float = field(default=1.0, metadata=_r(0.1, 60.0))
    ready_timeout_s: float = field(default=60.0, metadata=_r(1.0, 600.0))


@dataclass(frozen=True)
class ExtraConfig:
    """The `extra` sections, each typed; a section left out is its defaults (or absent: None)."""

    processes: ProcessOptions = field(default_factory=ProcessOptions)
    planning: PlanningBudget = field(default_factory=PlanningBudget)  # the planner worker's budget
    planner: PlannerConfig = field(default_factory=PlannerConfig)  # the one planner configuration of a run
    failsafes: FailsafeConfig = field(default_factory=FailsafeConfig)
    logs: RecorderConfig | None = None  # None: the recorder's defaults, in `logging.directory`
    web: WebExtra = field(default_factory=WebExtra)
    mavlink: MavlinkExtra = field(default_factory=MavlinkExtra)  # ground stations (endpoints: none by default)
    zenoh: BridgeConfig | None = None  # None: no bridge to other machines
    ros2: Ros2BridgeConfig | None = None  # present: the ROS 2 process runs (its pilot token: the run's)
    hardware: HardwareConfig = field(default_factory=HardwareConfig)  # devices and pins (`--hardware`)
    emulated: bool = False  # with mode hardware: emulated devices speaking the real protocols
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)  # an external physics (address) instead of the own boat


@dataclass(frozen=True)
class StackConfig(LaunchConfig):
    """A `LaunchConfig` whose `extra` sections are typed (`ExtraConfig`)."""

    extra: ExtraConfig = field(default_factory=ExtraConfig)  # type: ignore[assignment]


SECTIONS = tuple(f.name for f in dataclasses.fields(ExtraConfig))


def extra_sections(raw: Any, config: LaunchConfig) -> ExtraConfig:
    """The `extra` mapping of `config` as typed sections: the one place they are parsed. A
    section's defaults that depend on the rest of the config are filled in here (the recorder's
    directory is `logging.directory`; ROS 2 publishes the seed's topics unless told otherwise)."""
    if isinstance(raw, ExtraConfig):
        return raw
    if raw is None:
        raw = {}
    if not isinstance(raw, Mapping):
        raise ConfigError(f"extra: expected a mapping of sections ({', '.join(SECTIONS)}), got {raw!r:.60}")
    unknown = sorted(str(k) for k in raw if k not in SECTIONS)
    if unknown:
        close = difflib.get_close_matches(unknown[0], SECTIONS, n=1, cutoff=0.5)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ConfigError(f"extra: unknown section(s) {unknown} (known: {', '.join(SECTIONS)}){hint}")
    data = dict(raw)
    logs = data.get("logs")
    if isinstance(logs, Mapping):
        if "geo_origin" in logs:  # one origin for every part of a stack (lotsen.stack.stack.resolve_origin)
            raise ConfigError("extra.logs.geo_origin: not configurable; the log's map views use the local frame's "
                              "origin, set by the config's `origin` (else the simulated receiver's, or the first fix)")
        data["logs"] = {"directory": config.logging.directory, **logs}
    zenoh = data.get("zenoh")
    if isinstance(zenoh, Mapping):
        zenoh = dict(zenoh)
        enabled = zenoh.pop("enabled", True)
        if not isinstance(enabled, bool):
            raise ConfigError(f"extra.zenoh.enabled: expected true or false, got {enabled!r}")
        data["zenoh"] = zenoh if zenoh and enabled else None
    if "ros2" in data:
        ros2 = data["ros2"]
        ros2 = {} if ros2 is None else ros2
        if isinstance(ros2, Mapping):
            if "pilot_token" in ros2:
                raise ConfigError("extra.ros2.pilot_token: not configurable; ROS 2 commands need the run's pilot "
                                  "token (web.pilot_token or the one printed at start)")
            ros2 = {"publish": list(ROS2_DEFAULT_PUBLISH), "subscribe": [Topic.OPERATOR], **ros2}
        data["ros2"] = ros2
    return from_mapping(ExtraConfig, data, "extra")


def stack_config(config: LaunchConfig) -> StackConfig:
    """`config` with its `extra` sections typed (a StackConfig is returned as it is)."""
    if isinstance(config, StackConfig):
        return config
    base = {f.name: getattr(config, f.name) for f in dataclasses.fields(LaunchConfig) if f.name != "extra"}
    return StackConfig(**base, extra=extra_sections(config.extra, config))


def load_stack_config(path: str | Path | None) -> StackConfig:
    """Load a launch config file and validate every section of it, once: the runtime's sections
    (`lotsen.runtime.config.load_config`, relative paths taken from the file's folder) and the
    `extra` sections. Every error names the file and the key path."""
    config = load_config(path)
    try:
        return stack_config(config)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}" if path is not None else str(exc)) from None


def config_files(config: LaunchConfig) -> tuple[str, ...]:
    """The files a config makes a command read (route, parameter and calibration files): no
    output of that command may overwrite one (lotsen.files.check_output)."""
    return tuple(p for p in (config.route, config.vessel.parameters_file, config.sim.boat.parameters_file,
                             config.nodes.mag_calibration_file) if p)
