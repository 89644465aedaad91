"""Launch configuration: a YAML file validated into frozen dataclasses.

Every error names the file, the key path and the bad value, e.g.
``config.yaml: sim.dt_s: expected a number, got 'fast'`` or
``config.yaml: nodes.controler: unknown key (did you mean 'controller'?)``.
The same strict loader (`from_mapping`) serves any dataclass tree in the project.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import sys
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, Mapping

from lotsen.errors import ConfigError
from lotsen.files import read_yaml
from lotsen.model.environment import Environment, Waves
from lotsen.settings import Number, number_of, with_unit
from lotsen.settings import value_range as _r


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", str(tp))


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, value, where)
            except ConfigError as e:
                errors.append(str(e))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where}: {value!r} matches none of the allowed types")
    if origin is Literal:
        if value not in args:
            raise ConfigError(f"{where}: {value!r} is not one of {', '.join(map(repr, args))}")
        return value
    if dataclasses.is_dataclass(tp):
        return from_mapping(tp, value, where)
    if origin in (list, tuple):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {value!r}")
        if origin is tuple and args and args[-1] is not Ellipsis:
            if len(value) != len(args):
                raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}")
            return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
        inner = args[0] if args else Any
        conv = [_convert(inner, v, f"{where}[{i}]") for i, v in enumerate(value)]
        return tuple(conv) if origin is tuple else conv
    if origin is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: expected a mapping, got {value!r}")
        kt, vt = args if len(args) == 2 else (Any, Any)
        return {_convert(kt, k, where): _convert(vt, v, f"{where}.{k}") for k, v in value.items()}
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        if isinstance(value, int) and abs(value) > sys.float_info.max:  # float() would overflow
            raise ConfigError(f"{where}: integer with {len(str(abs(value)))} digits is too large")
        if not math.isfinite(value):
            raise ConfigError(f"{where}: {value!r} is not finite")
        if value != 0 and abs(value) < sys.float_info.min:
            raise ConfigError(f"{where}: {value!r} is a denormal number, not a meaningful value")
        return float(value)
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected text, got {value!r}")
        return value
    raise ConfigError(f"{where}: unsupported type {_type_name(tp)}")


def from_mapping(cls: Any, data: Any, where: str = "") -> Any:
    """Build dataclass `cls` from a mapping; unknown keys, wrong types and out-of-range values
    (field metadata "range": (lo, hi)) are ConfigErrors naming the key path."""
    prefix = f"{where}." if where else ""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where or 'config'}: expected a mapping, got {data!r}")
    hints = typing.get_type_hints(cls)
    flds = {f.name: f for f in dataclasses.fields(cls) if f.init}
    kwargs = {}
    for key, value in data.items():
        if key not in flds:
            close = difflib.get_close_matches(str(key), flds, n=1, cutoff=0.5)
            hint = f" (did you mean {close[0]!r}?)" if close else f" (known: {', '.join(flds)})"
            raise ConfigError(f"{prefix}{key}: unknown key{hint}")
        f = flds[key]
        v = _convert(hints[key], value, f"{prefix}{key}")
        number = number_of(f.metadata, integer=isinstance(v, int) and not isinstance(v, bool))
        if number is not None and isinstance(v, (int, float)) and not isinstance(v, bool):
            v = with_unit(number, key).check(v, f"{prefix}{key}")  # finite, in range with its unit, no denormal
        kwargs[key] = v
    try:
        return cls(**kwargs)
    except ConfigError:
        raise
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{where or 'config'}: {exc}") from None


@dataclass(frozen=True)
class WavesConfig:
    """`sim.environment.waves`: a wind sea (lotsen.model.environment.Waves; docs/simulator.md)."""

    hs_m: float = field(default=0.0, metadata=_r(0.0, 0.5))
    tp_s: float = field(default=1.0, metadata=_r(0.3, 5.0))
    from_deg: float = field(default=0.0, metadata=_r(-360.0, 360.0))
    spreading: float = field(default=10.0, metadata=_r(0.0, 100.0))
    gamma: float = field(default=3.3, metadata=_r(1.0, 7.0))

    def waves(self) -> Waves | None:
        """The model's `Waves` (None for Hs 0: flat water)."""
        return Waves(self.hs_m, self.tp_s, self.from_deg, self.spreading, self.gamma) if self.hs_m > 0.0 else None

    @classmethod
    def parse(cls, text: str, where: str = "--waves") -> "WavesConfig":
        """'HS,TP,FROM_DEG[,SPREADING]' (metres, seconds, degrees the waves come from, the cos-2s
        exponent: 0 long-crested), each value checked against this section's ranges."""
        parts = text.split(",")
        if len(parts) not in (3, 4):
            raise ConfigError(f"{where} {text[:40]!r}: expected HS,TP,FROM_DEG[,SPREADING], e.g. 0.06,1.0,250")
        names = ("hs_m", "tp_s", "from_deg", "spreading")
        flds = {f.name: f for f in dataclasses.fields(cls)}
        values = {}
        for name, part in zip(names, parts):
            number = with_unit(number_of(flds[name].metadata), name)
            values[name] = number.parse(part, f"{where} {text[:40]!r}: {name}")
        return cls(**values)


@dataclass(frozen=True)
class EnvironmentConfig:
    """`sim.environment`: the simulated boat's water and air."""

    current_speed_mps: float = field(default=0.0, metadata=_r(0.0, 2.0))
    current_to_deg: float = field(default=0.0, metadata=_r(-360.0, 360.0))
    wind_speed_mps: float = field(default=0.0, metadata=_r(0.0, 20.0))
    wind_from_deg: float = field(default=0.0, metadata=_r(-360.0, 360.0))
    wind_gust_std_mps: float = field(default=0.0, metadata=_r(0.0, 10.0))
    wind_direction_std_deg: float = field(default=0.0, metadata=_r(0.0, 90.0))
    wave_force_std_N: float = field(default=0.0, metadata=_r(0.0, 10.0))
    waves: WavesConfig | None = None

    def environment(self) -> Environment:
        """The model's `Environment` of this section (the one conversion)."""
        w = self.waves
        return Environment(current_speed_mps=self.current_speed_mps, current_to_deg=self.current_to_deg,
                           wind_speed_mps=self.wind_speed_mps, wind_from_deg=self.wind_from_deg,
                           wind_gust_std_mps=self.wind_gust_std_mps, wind_direction_std_deg=self.wind_direction_std_deg,
                           wave_force_std_N=self.wave_force_std_N, waves=w.waves() if w is not None else None)


@dataclass(frozen=True)
class BoatSection:
    """`sim.boat`: the simulated hull, configured apart from the model in use (`vessel`).
    Keys left out keep the lake boat's values (docs/simulator.md); `ideal: true` makes the
    simulated boat exactly the model in use (figures from it are labelled "ideal model")."""

    name: str | None = None
    ideal: bool = False
    parameters_file: str | None = None  # a params JSON as `lotsen identify --out` writes it
    parameters: dict[str, float] | None = None  # coefficients over the file's (or the lake boat's)
    reverse_thrust_ratio: float | None = field(default=None, metadata=_r(0.1, 1.0))
    thrust_dead_band_rps: float | None = field(default=None, metadata=_r(0.0, 30.0))
    command_latency_s: float | None = field(default=None, metadata=_r(0.0, 0.5))
    motor_time_constant_s: float | None = field(default=None, metadata=_r(0.005, 2.0))
    alpha_rate_max_deg_s: float | None = field(default=None, metadata=_r(10.0, 2000.0))
    gnss_antenna_m: tuple[float, float] | None = None  # body x, y of the antenna
    gnss_antenna_height_m: float | None = field(default=None, metadata=_r(0.0, 3.0))  # above the roll/pitch centre

    def __post_init__(self) -> None:
        if self.parameters:  # each coefficient in its physical range now, not when a boat is built
            from lotsen.model.parameters import VesselParameters

            VesselParameters.from_dict(self.parameters, source="sim.boat.parameters")
        if self.gnss_antenna_m is not None and max(abs(v) for v in self.gnss_antenna_m) > 2.0:
            raise ConfigError(f"sim.boat.gnss_antenna_m: {list(self.gnss_antenna_m)} is more than 2 m "
                              "from the hull's origin")
        if self.ideal:
            given = [f.name for f in dataclasses.fields(self)
                     if f.name not in ("ideal", "name") and getattr(self, f.name) is not None]
            if given:
                raise ConfigError(f"sim.boat: 'ideal: true' makes the boat the model in use; remove {', '.join(given)}")


#: what a simulated start may be: within the 2 km of a route around the origin, a heading within one
#: turn either way, speeds a 1-m boat can have
INITIAL_STATE_RANGES: tuple[tuple[str, Number], ...] = (
    ("north", Number(-2000.0, 2000.0, "m")), ("east", Number(-2000.0, 2000.0, "m")),
    ("psi", Number(-2 * math.pi, 2 * math.pi, "rad")), ("u", Number(-5.0, 5.0, "m/s")),
    ("v", Number(-5.0, 5.0, "m/s")), ("r", Number(-10.0, 10.0, "rad/s")))


@dataclass(frozen=True)
class LakeBedSection:
    """`sim.lakebed`: the simulated lake's bed (depths below the surface, m, on a grid: rows from
    south to north, columns from west to east, the first point at `origin_m` [north, east]) and the
    echosounder that pings it (lotsen.sim.lakebed). No depths: no bed, no sounder."""

    depths_m: tuple[tuple[float, ...], ...] = ()
    origin_m: tuple[float, float] = (0.0, 0.0)
    cell_m: float = field(default=5.0, metadata=_r(0.1, 500.0))
    sounder_rate_hz: float = field(default=5.0, metadata=_r(0.2, 50.0))
    sounder_noise_m: float = field(default=0.02, metadata=_r(0.0, 2.0))
    sounder_dropout: float = field(default=0.02, metadata=_r(0.0, 1.0))  # probability of a ping without a bottom
    sounder_max_range_m: float = field(default=50.0, metadata=_r(0.5, 1000.0))

    def __post_init__(self) -> None:
        if not self.depths_m:
            return
        if len(self.depths_m) < 2 or len({len(r) for r in self.depths_m}) != 1 or len(self.depths_m[0]) < 2:
            raise ConfigError("sim.lakebed.depths_m: rows of equal length, at least 2 x 2 points")
        if len(self.depths_m) * len(self.depths_m[0]) > 1_000_000:
            raise ConfigError("sim.lakebed.depths_m: more than a million points")
        for i, row in enumerate(self.depths_m):
            for j, d in enumerate(row):
                if not 0.0 <= d <= 1000.0:
                    raise ConfigError(f"sim.lakebed.depths_m[{i}][{j}]: {d:g} m is outside [0, 1000] m (depth below "
                                      "the surface)")
        for k, v in enumerate(self.origin_m):
            if not abs(v) <= 2000.0:
                raise ConfigError(f"sim.lakebed.origin_m[{k}]: {v:g} m is outside [-2000, 2000] m")


@dataclass(frozen=True)
class SimSection:
    dt_s: float = field(default=0.01, metadata=_r(0.001, 0.05))
    imu_rate_hz: float = field(default=100.0, metadata=_r(1.0, 100.0))
    gnss_rate_hz: float = field(default=8.0, metadata=_r(1.0, 20.0))
    # [north m, east m, psi rad, u m/s, v m/s, r rad/s] at the start (INITIAL_STATE_RANGES)
    initial_state: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    environment: EnvironmentConfig = field(default_factory=EnvironmentConfig)
    # the simulated ESCs arm after this long at neutral (the real ones after their arming beeps)
    esc_arm_time_s: float = field(default=1.0, metadata=_r(0.0, 30.0))
    boat: BoatSection = field(default_factory=BoatSection)
    lakebed: LakeBedSection = field(default_factory=LakeBedSection)

    def __post_init__(self) -> None:
        for (name, number), v in zip(INITIAL_STATE_RANGES, self.initial_state):
            number.check(v, f"sim.initial_state ({name})")


@dataclass(frozen=True)
class VesselSection:
    parameters_file: str | None = None  # params.json from `lotsen identify`; defaults if absent
    reverse_thrust_ratio: float = field(default=1.0, metadata=_r(0.1, 1.0))
    gnss_antenna_m: tuple[float, float] = (0.0, 0.0)  # measured on the hull: body x, y from the model's origin
    # measured on the hull: the antenna's height above the waterline (the roll and pitch centre); the
    # estimator takes the antenna's swing in roll and pitch out of the fixes (docs/fusion.md "Waves")
    gnss_antenna_height_m: float = field(default=0.0, metadata=_r(0.0, 3.0))
    # the hull's waterline length, beam and draft (m): how much of the waves its heave follows, for the
    # sea-state estimate (lotsen.fusion.seastate); the lake boat's by default
    hull_m: tuple[float, float, float] = (0.99, 0.30, 0.08)
    # the echosounder's transducer, measured on the hull: body x forward, y starboard from the GNSS
    # antenna, and its face's depth below the surface (soundings are depths below the surface)
    antenna_to_transducer_m: tuple[float, float] = (0.0, 0.0)
    transducer_draft_m: float = field(default=0.1, metadata=_r(0.0, 5.0))

    def __post_init__(self) -> None:
        if not all(0.01 <= v <= 20.0 for v in self.hull_m) or not self.hull_m[2] < self.hull_m[1] <= self.hull_m[0]:
            raise ConfigError(f"vessel.hull_m: {list(self.hull_m)} is not a hull's waterline length >= beam > draft "
                              "(each 0.01-20 m)")
        if max(abs(v) for v in self.gnss_antenna_m) > 2.0:
            raise ConfigError(f"vessel.gnss_antenna_m: {list(self.gnss_antenna_m)} is more than 2 m from the hull's origin")
        if max(abs(v) for v in self.antenna_to_transducer_m) > 3.0:
            raise ConfigError(f"vessel.antenna_to_transducer_m: {list(self.antenna_to_transducer_m)} is more than 3 m "
                              "from the antenna")

    @property
    def transducer_m(self) -> tuple[float, float]:
        """The transducer's body x, y from the hull's (the model's) origin."""
        return (self.gnss_antenna_m[0] + self.antenna_to_transducer_m[0],
                self.gnss_antenna_m[1] + self.antenna_to_transducer_m[1])


@dataclass(frozen=True)
class NodesSection:
    fusion: Literal["ekf", "seed", "truth"] = "ekf"
    controller: Literal["mpc", "pursuit", "los", "lq"] = "mpc"
    control_rate_hz: float = field(default=10.0, metadata=_r(1.0, 50.0))
    command_deadline_s: float = field(default=0.5, metadata=_r(0.05, 5.0))
    mag_calibration_file: str | None = None


@dataclass(frozen=True)
class WebSection:
    enabled: bool = True
    host: str = "127.0.0.1"  # loopback by default; set 0.0.0.0 to serve the boat's Wi-Fi
    port: int = field(default=8080, metadata=_r(0, 65535))
    pilot_token: str | None = None  # printed at start when generated
    telemetry_rate_hz: float = field(default=20.0, metadata=_r(1.0, 50.0))


@dataclass(frozen=True)
class LoggingSection:
    enabled: bool = True
    directory: str = "logs"


@dataclass(frozen=True)
class OriginSection:
    """Geodetic origin of the local NED frame (WGS84). Without it: the simulated receiver's origin
    in simulation, the first usable GNSS fix on the boat."""

    lat_deg: float = field(metadata=_r(-90.0, 90.0))
    lon_deg: float = field(metadata=_r(-180.0, 180.0))
    height_m: float = field(default=0.0, metadata=_r(-500.0, 9000.0))


@dataclass(frozen=True)
class LaunchConfig:
    mode: Literal["sim", "hardware"] = "sim"
    seed: int = field(default=0, metadata=_r(0, 2**32 - 1))
    route: str | None = None  # route YAML loaded at start (relative to the config file's folder)
    origin: OriginSection | None = None
    sim: SimSection = field(default_factory=SimSection)
    vessel: VesselSection = field(default_factory=VesselSection)
    nodes: NodesSection = field(default_factory=NodesSection)
    web: WebSection = field(default_factory=WebSection)
    logging: LoggingSection = field(default_factory=LoggingSection)
    extra: dict[str, Any] = field(default_factory=dict)  # sections owned by optional parts (drivers, failsafes)


def load_yaml_file(path: str | Path) -> Any:
    return read_yaml(path, ConfigError)


def load_config(path: str | Path | None) -> LaunchConfig:
    """Load and validate a launch config; None gives the defaults. Relative file and folder
    names in it are taken from the config file's folder, so the command works from anywhere."""
    if path is None:
        return LaunchConfig()
    data = load_yaml_file(path)
    try:
        config = from_mapping(LaunchConfig, data)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    return resolve_paths(config, Path(path).resolve().parent)


def resolve_paths(config: LaunchConfig, base: Path) -> LaunchConfig:
    """`config` with every relative path made absolute against `base` (the config's folder)."""

    def absolute(p: str | None) -> str | None:
        if not p:
            return p
        q = Path(p).expanduser()
        return str(q if q.is_absolute() else (base / q).resolve())

    return dataclasses.replace(
        config, route=absolute(config.route),
        vessel=dataclasses.replace(config.vessel, parameters_file=absolute(config.vessel.parameters_file)),
        sim=dataclasses.replace(config.sim, boat=dataclasses.replace(
            config.sim.boat, parameters_file=absolute(config.sim.boat.parameters_file))),
        nodes=dataclasses.replace(config.nodes, mag_calibration_file=absolute(config.nodes.mag_calibration_file)),
        logging=dataclasses.replace(config.logging, directory=absolute(config.logging.directory) or "logs"))
