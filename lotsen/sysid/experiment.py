"""Identification experiments: input sequences from YAML, as pure input generators.

An `Experiment` is a list of pieces (constant, steps, ramp, zigzag, turning circle, PRBS,
multisine, piecewise-constant) run one after another. `InputGenerator(experiment).command(t,
measured_state)` returns the set-points u = [alpha1, alpha2, n1, n2, nt] (rad, rev/s) at time t
since the start; only the zigzag reads the measured heading. The same object drives the simulator
(`lotsen experiment run --sim`) and, later, the real boat through the runtime.

Before any run, `check_experiment` verifies actuator limits and predicts the trajectory with the
current model (`predict_trajectory`) to confirm it stays inside the experiment's area.
The YAML schema is documented in docs/sysid.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from lotsen.errors import ConfigError
from lotsen.files import read_yaml
from lotsen.model import DEFAULT_LIMITS, ActuatorLimits, VesselModel, rk4_step
from lotsen.model.angles import wrap_angle
from lotsen.settings import Number

CHANNELS = ("alpha1", "alpha2", "n1", "n2", "nt")
# YAML keys -> (channels, factor to SI): angles in degrees in files, radians inside
_KEYS = {
    "alpha_deg": ((0, 1), math.pi / 180), "alpha1_deg": ((0,), math.pi / 180),
    "alpha2_deg": ((1,), math.pi / 180), "n_rps": ((2, 3), 1.0), "n1_rps": ((2,), 1.0),
    "n2_rps": ((3,), 1.0), "nt_rps": ((4,), 1.0),
}
PIECE_TYPES = ("constant", "steps", "ramp", "zigzag", "turning_circle", "prbs", "multisine", "piecewise")

# What the numbers of an experiment file may be (lotsen.settings.Number: finite, in range with the
# unit, no denormals). Set-points are bounded loosely here and against the actuators' limits by
# `check_limits`; times so that no experiment runs (or is checked) for hours.
MAX_EXPERIMENT_S = 1800.0  # a whole experiment: a lake battery is 10 min
DURATION = Number(0.01, MAX_EXPERIMENT_S, "s")
ANGLE_DEG = Number(-90.0, 90.0, "deg")
SPEED_RPS = Number(-200.0, 200.0, "rev/s")
_LEVEL = {k: ANGLE_DEG if k.endswith("_deg") else SPEED_RPS for k in _KEYS}
ZIGZAG_ALPHA_DEG = Number(0.5, 90.0, "deg")
ZIGZAG_HEADING_DEG = Number(0.5, 180.0, "deg")
FREQUENCY_HZ = Number(0.001, 50.0, "Hz")
N_FREQ = Number(1, 100, integer=True)
SEED = Number(0, 2**32 - 1, integer=True)
AREA_M = Number(-2000.0, 2000.0, "m")
AREA_SIDE_M = Number(2.0, 4000.0, "m")
START_HEADING_DEG = Number(-360.0, 360.0, "deg")
START_SPEED_MPS = Number(0.0, 5.0, "m/s")
COMMAND_RATE_HZ = Number(1.0, 100.0, "Hz")


@dataclass(frozen=True)
class Area:
    """Allowed rectangle in the local NED frame (the run starts at the start position)."""

    north_m: tuple[float, float] = (-15.0, 15.0)
    east_m: tuple[float, float] = (-15.0, 15.0)

    def contains(self, north: float, east: float, margin_m: float = 0.0) -> bool:
        return (self.north_m[0] + margin_m <= north <= self.north_m[1] - margin_m
                and self.east_m[0] + margin_m <= east <= self.east_m[1] - margin_m)

    @classmethod
    def centred(cls, size_north_m: float, size_east_m: float) -> "Area":
        return cls((-size_north_m / 2, size_north_m / 2), (-size_east_m / 2, size_east_m / 2))


@dataclass(frozen=True)
class Piece:
    """One piece of an experiment. `params` holds the validated, SI-converted settings."""

    kind: str
    duration_s: float
    params: dict[str, Any] = field(default_factory=dict)
    label: str = ""


@dataclass(frozen=True)
class Experiment:
    name: str
    pieces: tuple[Piece, ...]
    area: Area = Area()
    start_heading_rad: float = 0.0
    start_speed_mps: float = 0.0
    command_rate_hz: float = 20.0
    description: str = ""

    @property
    def duration_s(self) -> float:
        return float(sum(p.duration_s for p in self.pieces))


# ----------------------------------------------------------------------------------------------
# parsing (pure: from a mapping; `load_experiment` reads the file)

def _num(d: Mapping[str, Any], key: str, where: str, number: Number, default: float | None = None) -> Any:
    """d[key] as `number` allows it (a refusal names the place, the value and the range)."""
    if key not in d:
        if default is None:
            raise ConfigError(f"{where}: missing '{key}'")
        return default
    return number.check(d[key], f"{where}: {key}")


def _levels(d: Mapping[str, Any], where: str, base: Sequence[float] | None = None) -> np.ndarray:
    """An input vector from keys alpha_deg / alpha1_deg / ... / nt_rps (missing: base or 0)."""
    u = np.array(base if base is not None else [0.0] * 5, dtype=float)
    if isinstance(d, _Seen):
        d.seen.update(k for k in d.keys() if k in _KEYS)
    for key, value in d.items():
        if key not in _KEYS:
            continue
        chans, k = _KEYS[key]
        v = _LEVEL[key].check(value, f"{where}: {key}")
        for c in chans:
            u[c] = v * k
    return u


def _channel(name: Any, where: str) -> tuple[tuple[int, ...], float]:
    key = str(name)
    if key not in _KEYS:
        raise ConfigError(f"{where}: unknown input channel {key!r} (one of {', '.join(_KEYS)})")
    return _KEYS[key]


class _Seen(dict):
    """A mapping that remembers which keys the parser looked at (the rest are unknown keys)."""

    def __init__(self, d: Mapping[str, Any]) -> None:
        super().__init__(d)
        self.seen: set[Any] = {"type", "label"}

    def __getitem__(self, k: Any) -> Any:
        self.seen.add(k)
        return super().__getitem__(k)

    def get(self, k: Any, default: Any = None) -> Any:
        self.seen.add(k)
        return super().get(k, default)

    def __contains__(self, k: object) -> bool:
        self.seen.add(k)
        return super().__contains__(k)


def parse_piece(d: Mapping[str, Any], where: str) -> Piece:
    if not isinstance(d, Mapping):
        raise ConfigError(f"{where}: expected a mapping with 'type' and 'duration_s'")
    d = _Seen(d)
    piece = _parse_piece(d, where)
    unknown = [str(k) for k in d if k not in d.seen]
    if unknown:
        raise ConfigError(f"{where} ({piece.kind}): unknown key(s) {', '.join(map(repr, unknown))}")
    return piece


def _parse_piece(d: Mapping[str, Any], where: str) -> Piece:
    kind = d.get("type")
    if kind not in PIECE_TYPES:
        raise ConfigError(f"{where}: unknown type {kind!r} (one of {', '.join(PIECE_TYPES)})")
    where = f"{where} ({kind})"
    label = str(d.get("label", kind))
    p: dict[str, Any] = {}
    if kind == "steps":
        levels = d.get("levels")
        if not isinstance(levels, list) or not levels:
            raise ConfigError(f"{where}: 'levels' must be a non-empty list of input settings")
        step_s = _num(d, "step_duration_s", where, DURATION)
        p["levels"] = [_levels(lv, f"{where} level {i + 1}") for i, lv in enumerate(levels)]
        p["step_s"] = step_s
        duration = step_s * len(levels)
    else:
        duration = _num(d, "duration_s", where, DURATION)
    if not 0 < duration <= MAX_EXPERIMENT_S:
        raise ConfigError(f"{where}: duration {duration:g} s outside the allowed range {DURATION.allowed()}")
    if kind == "constant":
        p["u"] = _levels(d, where)
    elif kind == "ramp":
        for k in ("from", "to"):
            if not isinstance(d.get(k), Mapping):
                raise ConfigError(f"{where}: '{k}' must be a mapping of input settings")
        p["u0"] = _levels(d["from"], f"{where} from")
        p["u1"] = _levels(d["to"], f"{where} to")
    elif kind == "zigzag":
        p["alpha"] = math.radians(_num(d, "alpha_deg", where, ZIGZAG_ALPHA_DEG))
        p["heading"] = math.radians(_num(d, "heading_deg", where, ZIGZAG_HEADING_DEG))
        p["n"] = _num(d, "n_rps", where, SPEED_RPS)
    elif kind == "turning_circle":
        direction = d.get("direction", "starboard")
        if direction not in ("starboard", "port"):
            raise ConfigError(f"{where}: direction must be 'starboard' or 'port'")
        a = math.radians(abs(_num(d, "alpha_deg", where, ANGLE_DEG)))
        # alpha > 0 yaws the bow to port (thrust at the stern to starboard): starboard turn = -alpha
        p["u"] = np.array([-a if direction == "starboard" else a] * 2 + [_num(d, "n_rps", where, SPEED_RPS)] * 2 + [0.0])
        p["u"][4] = _num(d, "nt_rps", where, SPEED_RPS, 0.0)
    elif kind in ("prbs", "multisine"):
        base = d.get("base", {})
        if not isinstance(base, Mapping):
            raise ConfigError(f"{where}: 'base' must be a mapping of input settings")
        p["base"] = _levels(base, f"{where} base")
        amps = d.get("amplitude")
        if not isinstance(amps, Mapping) or not amps:
            raise ConfigError(f"{where}: 'amplitude' must map channels (e.g. nt_rps) to amplitudes")
        p["amp"] = _levels(amps, f"{where} amplitude", [0.0] * 5)
        seed = _num(d, "seed", where, SEED, 0)
        rng = np.random.default_rng(seed)
        if kind == "prbs":
            bit = _num(d, "bit_s", where, DURATION)
            if bit > duration:
                raise ConfigError(f"{where}: bit_s {bit:g} s is longer than the piece ({duration:g} s): "
                                  "a PRBS needs several bits")
            nbits = int(math.ceil(duration / bit))
            p["bit_s"] = bit
            p["bits"] = rng.choice([-1.0, 1.0], size=(nbits, 5))
        else:
            f_lo, f_hi = _num(d, "f_min_hz", where, FREQUENCY_HZ), _num(d, "f_max_hz", where, FREQUENCY_HZ)
            nf = _num(d, "n_freq", where, N_FREQ, 6)
            if not f_lo <= f_hi:
                raise ConfigError(f"{where}: need f_min_hz <= f_max_hz (got {f_lo:g} and {f_hi:g} Hz)")
            freqs = np.linspace(f_lo, f_hi, nf)
            # Schroeder phases per channel (low crest factor), shifted per channel by the seed
            k = np.arange(1, nf + 1)
            ph = -np.pi * k * (k - 1) / nf
            p["freqs"] = freqs
            p["phases"] = ph[None, :] + rng.uniform(0, 2 * np.pi, size=(5, 1))
            p["norm"] = 1.0 / math.sqrt(nf / 2.0)  # unit RMS per channel, peaks ~1.4-1.7
    elif kind == "piecewise":
        seg = _num(d, "segment_s", where, DURATION)
        if seg > duration:
            raise ConfigError(f"{where}: segment_s {seg:g} s is longer than the piece ({duration:g} s)")
        values = d.get("values")
        if not isinstance(values, Mapping) or not values:
            raise ConfigError(f"{where}: 'values' must map channels to lists of levels")
        nseg = int(math.ceil(duration / seg - 1e-9))
        table = np.zeros((nseg, 5))
        for key, lst in values.items():
            chans, k = _channel(key, where)
            if not isinstance(lst, list) or len(lst) != nseg:
                raise ConfigError(f"{where}: '{key}' needs {nseg} levels (duration / segment_s), got "
                                  f"{len(lst) if isinstance(lst, list) else lst!r}")
            for c in chans:
                table[:, c] = [_LEVEL[str(key)].check(v, f"{where}: {key}[{i}]") * k for i, v in enumerate(lst)]
        p["segment_s"] = seg
        p["table"] = table
    return Piece(kind, duration, p, label)


EXPERIMENT_KEYS = ("name", "description", "area", "start", "pieces", "command_rate_hz")


def _unknown_keys(d: Mapping[str, Any], allowed: Sequence[str], where: str) -> None:
    unknown = [str(k) for k in d if k not in allowed]
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(map(repr, unknown))} (known: {', '.join(allowed)})")


def _pair(value: Any, where: str, number: Number) -> tuple[float, float]:
    if not (isinstance(value, (list, tuple)) and len(value) == 2):
        raise ConfigError(f"{where}: expected two numbers, got {str(value)[:60]}")
    return (number.check(value[0], f"{where}[0]"), number.check(value[1], f"{where}[1]"))


def parse_experiment(data: Mapping[str, Any], source: str = "experiment") -> Experiment:
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a mapping with 'name' and 'pieces'")
    _unknown_keys(data, EXPERIMENT_KEYS, source)
    pieces_raw = data.get("pieces")
    if not isinstance(pieces_raw, list) or not pieces_raw:
        raise ConfigError(f"{source}: 'pieces' must be a non-empty list")
    pieces = tuple(parse_piece(pd, f"{source}: piece {i + 1}") for i, pd in enumerate(pieces_raw))
    area = Area()
    if "area" in data:
        a = data["area"]
        if isinstance(a, Mapping) and set(a) == {"size_m"}:
            n, e = _pair(a["size_m"], f"{source}: area.size_m", AREA_SIDE_M)
            area = Area.centred(n, e)
        elif isinstance(a, Mapping) and set(a) == {"north_m", "east_m"}:
            area = Area(_pair(a["north_m"], f"{source}: area.north_m", AREA_M),
                        _pair(a["east_m"], f"{source}: area.east_m", AREA_M))
        else:
            raise ConfigError(f"{source}: area must have size_m: [n, e] or north_m: [lo, hi], east_m: [lo, hi]")
        if not (area.north_m[0] < 0 < area.north_m[1] and area.east_m[0] < 0 < area.east_m[1]):
            raise ConfigError(f"{source}: the start position (0, 0) must lie inside the area")
    start = data.get("start", {}) or {}
    if not isinstance(start, Mapping):
        raise ConfigError(f"{source}: start must be a mapping with heading_deg and speed_mps")
    _unknown_keys(start, ("heading_deg", "speed_mps"), f"{source}: start")
    rate = _num(data, "command_rate_hz", source, COMMAND_RATE_HZ, 20.0)
    total = sum(p.duration_s for p in pieces)
    if total > MAX_EXPERIMENT_S:
        raise ConfigError(f"{source}: the pieces last {total:g} s together, more than an experiment may "
                          f"({MAX_EXPERIMENT_S:g} s); split it into several experiments")
    for i, p in enumerate(pieces):
        if p.kind == "multisine" and p.params["freqs"].max() > rate / 2:
            raise ConfigError(f"{source}: piece {i + 1} (multisine): f_max_hz {p.params['freqs'].max():g} Hz is above "
                              f"half the command rate ({rate / 2:g} Hz): the commands cannot carry it")
    name = data.get("name", Path(source).stem)
    description = data.get("description", "")
    return Experiment(str(name)[:200], pieces, area,
                      math.radians(_num(start, "heading_deg", f"{source}: start", START_HEADING_DEG, 0.0)),
                      _num(start, "speed_mps", f"{source}: start", START_SPEED_MPS, 0.0), rate,
                      str(description)[:2000])


def load_experiment(path: str | Path) -> Experiment:
    """An experiment YAML file (lotsen.files: UTF-8, no duplicate keys, no hostile structures)."""
    return parse_experiment(read_yaml(path, ConfigError, "experiment file"), str(path))


# ----------------------------------------------------------------------------------------------
# the input generator

class InputGenerator:
    """u = command(t, measured_state): the experiment's set-points at time t (s since start).

    `measured_state` is anything with a heading: a sequence [N, E, psi, ...] or an object with
    `heading_rad`. Only zigzag pieces use it (heading trigger); the generator keeps that
    switching state, so calls must come in increasing t (as a control loop makes them).
    """

    def __init__(self, experiment: Experiment) -> None:
        self.experiment = experiment
        self._starts = np.cumsum([0.0] + [p.duration_s for p in experiment.pieces])
        self._zz_piece = -1
        self._zz_ref = 0.0
        self._zz_sign = -1.0

    def piece_at(self, t: float) -> int:
        i = int(np.searchsorted(self._starts, t, side="right") - 1)
        return min(max(i, 0), len(self.experiment.pieces) - 1)

    @property
    def duration_s(self) -> float:
        return self.experiment.duration_s

    def command(self, t: float, measured_state: Any = None) -> tuple[float, float, float, float, float]:
        if t >= self._starts[-1]:
            return (0.0, 0.0, 0.0, 0.0, 0.0)
        i = self.piece_at(t)
        piece = self.experiment.pieces[i]
        tau = t - self._starts[i]
        p = piece.params
        k = piece.kind
        if k in ("constant", "turning_circle"):
            u = p["u"]
        elif k == "steps":
            u = p["levels"][min(int(tau / p["step_s"]), len(p["levels"]) - 1)]
        elif k == "ramp":
            s = tau / piece.duration_s
            u = (1 - s) * p["u0"] + s * p["u1"]
        elif k == "piecewise":
            u = p["table"][min(int(tau / p["segment_s"]), len(p["table"]) - 1)]
        elif k == "prbs":
            u = p["base"] + p["amp"] * p["bits"][min(int(tau / p["bit_s"]), len(p["bits"]) - 1)]
        elif k == "multisine":
            s = np.sin(2 * np.pi * p["freqs"][None, :] * tau + p["phases"]).sum(axis=1) * p["norm"]
            u = p["base"] + p["amp"] * s
        elif k == "zigzag":
            psi = _heading(measured_state)
            if self._zz_piece != i:  # first call in this piece: start turning to starboard
                self._zz_piece, self._zz_ref, self._zz_sign = i, psi, -1.0
            dev = wrap_angle(psi - self._zz_ref)
            if self._zz_sign < 0 and dev >= p["heading"]:
                self._zz_sign = 1.0
            elif self._zz_sign > 0 and dev <= -p["heading"]:
                self._zz_sign = -1.0
            a = self._zz_sign * p["alpha"]
            u = np.array([a, a, p["n"], p["n"], 0.0])
        else:  # pragma: no cover - parse_piece rejects unknown kinds
            raise ConfigError(f"unknown piece type {k}")
        return tuple(float(v) for v in u)  # type: ignore[return-value]


def _heading(state: Any) -> float:
    if state is None:
        raise ConfigError("a zigzag piece needs the measured heading (measured_state)")
    if hasattr(state, "heading_rad"):
        return float(state.heading_rad)
    return float(state[2])


# ----------------------------------------------------------------------------------------------
# keeping the boat inside the area during a run

@dataclass(frozen=True)
class ReturnConfig:
    """When and how a running experiment brings its boat back into its area (`AreaKeeper`)."""

    # the position `lookahead_s` ahead at the present velocity within `guard_m` of the area's edge
    # starts a return: the designed track keeps its margin (2 m by default) inside, so a boat that
    # flies like its model does not return, and a straight run at the edge is caught ~3 s before it
    lookahead_s: float = 3.0
    guard_m: float = 0.5
    # the signal resumes once the boat is inside the central part of the area (this fraction of each
    # side) and heads within `resume_heading_rad` of the area's centre
    resume_fraction: float = 0.5
    resume_heading_rad: float = 0.5
    n_rps: float = 40.0  # both azimuths on the way back (the boat's cruise, ~0.6 m/s on the model)
    k_heading: float = 1.5  # azimuth angle per heading error (rad/rad), clipped to the limits
    nt_per_rad: float = 80.0  # bow thruster speed per heading error (rev/s per rad), clipped
    turn_speed_fraction: float = 0.2  # of n_rps while the bow points away from the centre
    max_return_s: float = 60.0  # a boat not back in the central part by then: the experiment ends

    def __post_init__(self) -> None:
        for name in ("lookahead_s", "guard_m", "n_rps", "k_heading", "nt_per_rad", "turn_speed_fraction"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(f"return: {name} must be >= 0, got {getattr(self, name)}")
        if not 0.0 < self.resume_fraction < 1.0:
            raise ConfigError(f"return: resume_fraction must be in (0, 1), got {self.resume_fraction}")
        if not 0.0 < self.resume_heading_rad <= math.pi or not self.max_return_s > 0.0:
            raise ConfigError("return: resume_heading_rad must be in (0, pi] and max_return_s > 0")

    def run_limit_s(self, duration_s: float) -> float:
        """The longest a run of a `duration_s` signal may take with its returns: three times the signal
        and one return's allowance; longer, the returns are eating the experiment and it ends."""
        return 3.0 * duration_s + self.max_return_s


class AreaKeeper:
    """Pauses an experiment's signal and steers its boat back when it is about to leave the area.

    A design keeps its predicted track inside the area, but the boat is not its model: a hull that
    turns wider than predicted (before any identification, or not built like the model) would leave
    it, and the run had to be aborted, the record lost. Fed the boat's position (relative to the
    experiment's start) and velocity each command tick, `update` returns None while the signal may
    run, or the return's set-points: both azimuths at `n_rps`, angled (and the bow thruster) to turn
    the bow to the area's centre. The signal resumes where it paused once the boat is inside the
    area's central part and heads for the centre. Pure: no clock, no I/O; the record keeps every row
    (the return's inputs are logged like the signal's, so the identification uses them too)."""

    def __init__(self, area: Area, config: ReturnConfig = ReturnConfig(),
                 limits: ActuatorLimits = DEFAULT_LIMITS) -> None:
        self.area, self.config, self.limits = area, config, limits
        self.centre = (0.5 * (area.north_m[0] + area.north_m[1]), 0.5 * (area.east_m[0] + area.east_m[1]))
        side = min(area.north_m[1] - area.north_m[0], area.east_m[1] - area.east_m[0])
        self._resume_margin_m = 0.5 * (1.0 - config.resume_fraction) * side
        self.returning = False
        self.returns = 0  # how many returns so far
        self.paused_s = 0.0  # signal time not run: the returns' total duration
        self._since: float | None = None  # when the present return began
        self._last_t: float | None = None

    def update(self, t: float, north_m: float, east_m: float, heading_rad: float, u_mps: float,
               v_mps: float) -> tuple[float, float, float, float, float] | None:
        """None: run the signal; else the return's set-points (alpha1, alpha2, n1, n2, nt)."""
        c, a = self.config, self.area
        dt = 0.0 if self._last_t is None else max(t - self._last_t, 0.0)
        self._last_t = t
        if self.returning:
            self.paused_s += dt
        cos_h, sin_h = math.cos(heading_rad), math.sin(heading_rad)
        vn, ve = u_mps * cos_h - v_mps * sin_h, u_mps * sin_h + v_mps * cos_h
        err = wrap_angle(math.atan2(self.centre[1] - east_m, self.centre[0] - north_m) - heading_rad)
        if not self.returning:
            if a.contains(north_m + vn * c.lookahead_s, east_m + ve * c.lookahead_s, c.guard_m):
                return None
            self.returning, self._since = True, t
            self.returns += 1
        elif a.contains(north_m, east_m, self._resume_margin_m) and abs(err) <= c.resume_heading_rad:
            self.returning, self._since = False, None
            return None
        # alpha > 0 yaws the bow to port, nt > 0 to starboard (docs/model.md): err > 0 asks starboard
        alpha = -min(max(c.k_heading * err, -self.limits.alpha_max_rad), self.limits.alpha_max_rad)
        nt = min(max(c.nt_per_rad * err, -self.limits.n_bow_max_rps), self.limits.n_bow_max_rps)
        # slow while the bow is far off the centre: the turn is tight where the boat is (the bow
        # thruster's authority does not fade with it), and the run towards the edge ends
        n = min(c.n_rps, self.limits.n_az_max_rps) * min(max(math.cos(err), c.turn_speed_fraction), 1.0)
        return (alpha, alpha, n, n, nt)

    def overdue(self, t: float) -> bool:
        """A return that has taken longer than `max_return_s`."""
        return self._since is not None and t - self._since > self.config.max_return_s

    def failure(self, t: float, duration_s: float) -> str:
        """Why the run must end at `t` (s since its start) for its returns, or "": a return overdue, or
        the run past `ReturnConfig.run_limit_s` of its `duration_s` signal."""
        if self.overdue(t):
            return f"the boat did not get back into the area's central part within {self.config.max_return_s:g} s"
        if t > self.config.run_limit_s(duration_s):
            return f"the returns to the area took {self.paused_s:.0f} s of the run"
        return ""


# ----------------------------------------------------------------------------------------------
# checks before a run

def check_limits(experiment: Experiment, limits: ActuatorLimits = DEFAULT_LIMITS, dt_s: float = 0.05) -> list[str]:
    """Set-points outside the actuator limits, as messages naming piece, channel and time."""
    gen = InputGenerator(experiment)
    lim = np.array([limits.alpha_max_rad] * 2 + [limits.n_az_max_rps] * 2 + [limits.n_bow_max_rps])
    problems: list[str] = []
    seen: set[tuple[int, int]] = set()
    for t in np.arange(0.0, experiment.duration_s, dt_s):
        i = gen.piece_at(t)
        u = np.array(gen.command(t, (0.0, 0.0, experiment.start_heading_rad)))
        for c in np.where(np.abs(u) > lim * (1 + 1e-9))[0]:
            if (i, c) in seen:
                continue
            seen.add((i, c))
            shown = math.degrees(u[c]) if c < 2 else u[c]
            shown_lim = math.degrees(lim[c]) if c < 2 else lim[c]
            unit = "deg" if c < 2 else "rev/s"
            problems.append(f"piece {i + 1} ({experiment.pieces[i].label}): {CHANNELS[c]} = {shown:.1f} {unit} "
                            f"at t = {t:.2f} s exceeds the limit {shown_lim:.0f} {unit}")
    return problems


@dataclass
class Prediction:
    t: np.ndarray
    x: np.ndarray  # K x 6
    u: np.ndarray  # K x 5 set-points


def predict_trajectory(experiment: Experiment, model: VesselModel | None = None, dt_s: float = 0.05) -> Prediction:
    """The model's prediction of the run (set-points applied directly; no noise, calm water)."""
    model = model or VesselModel()
    gen = InputGenerator(experiment)
    n = int(math.ceil(experiment.duration_s / dt_s))
    x = (0.0, 0.0, experiment.start_heading_rad, experiment.start_speed_mps, 0.0, 0.0)
    ts = np.arange(n + 1) * dt_s
    X = np.empty((n + 1, 6))
    U = np.empty((n + 1, 5))
    X[0] = x
    for k in range(n):
        u = gen.command(ts[k], x)
        U[k] = u
        x, _ = rk4_step(x, u, model.arrays.packed, 0.0, 0.0, 0.0, 0.0, 0.0, dt_s)
        X[k + 1] = x
        if not math.isfinite(sum(x)):
            break
    U[n] = U[n - 1] if n else 0.0
    return Prediction(ts, X, U)


#: how a design for a model other than the defaults ends its description (`experiment design --params P`)
DESIGNED_FOR = "; designed for the model in "


def designed_for(experiment: Experiment) -> str | None:
    """The parameter file an experiment was designed for (its description's DESIGNED_FOR), if any."""
    _, marker, tail = experiment.description.rpartition(DESIGNED_FOR)
    return tail if marker else None


def check_experiment(experiment: Experiment, model: VesselModel | None = None,
                     limits: ActuatorLimits = DEFAULT_LIMITS, margin_m: float = 1.0,
                     area_advice: str = "") -> Prediction:
    """Refuse (ConfigError) an experiment that exceeds actuator limits or is predicted to leave its area
    (`area_advice` appended to the latter's message)."""
    problems = check_limits(experiment, limits)
    if problems:
        raise ConfigError(f"experiment '{experiment.name}' exceeds actuator limits:\n  " + "\n  ".join(problems))
    pred = predict_trajectory(experiment, model)
    a = experiment.area
    inside = ((pred.x[:, 0] >= a.north_m[0] + margin_m) & (pred.x[:, 0] <= a.north_m[1] - margin_m)
              & (pred.x[:, 1] >= a.east_m[0] + margin_m) & (pred.x[:, 1] <= a.east_m[1] - margin_m)
              & np.isfinite(pred.x).all(axis=1))
    if not inside.all():
        k = int(np.argmin(inside))
        i = InputGenerator(experiment).piece_at(pred.t[k])
        raise ConfigError(
            f"experiment '{experiment.name}' is predicted to leave its area (north {a.north_m[0]:g}..{a.north_m[1]:g} m, "
            f"east {a.east_m[0]:g}..{a.east_m[1]:g} m, {margin_m:g} m margin): at t = {pred.t[k]:.1f} s in piece "
            f"{i + 1} ({experiment.pieces[i].label}) the predicted position is north {pred.x[k, 0]:.1f} m, "
            f"east {pred.x[k, 1]:.1f} m. Shorten the pieces, lower the speed or enlarge the area.{area_advice}")
    return pred


def experiment_to_dict(experiment: Experiment) -> dict[str, Any]:
    """YAML-ready mapping of an experiment made of constant/piecewise/steps pieces (design output)."""
    pieces = []
    for p in experiment.pieces:
        if p.kind == "piecewise":
            tab = p.params["table"]
            vals = {"alpha1_deg": [round(math.degrees(v), 2) for v in tab[:, 0]],
                    "alpha2_deg": [round(math.degrees(v), 2) for v in tab[:, 1]],
                    "n1_rps": [round(float(v), 2) for v in tab[:, 2]],
                    "n2_rps": [round(float(v), 2) for v in tab[:, 3]],
                    "nt_rps": [round(float(v), 2) for v in tab[:, 4]]}
            pieces.append({"type": "piecewise", "label": p.label, "duration_s": round(p.duration_s, 3),
                           "segment_s": p.params["segment_s"], "values": vals})
        elif p.kind == "constant":
            u = p.params["u"]
            pieces.append({"type": "constant", "label": p.label, "duration_s": round(p.duration_s, 3),
                           "alpha1_deg": round(math.degrees(u[0]), 2), "alpha2_deg": round(math.degrees(u[1]), 2),
                           "n1_rps": round(float(u[2]), 2), "n2_rps": round(float(u[3]), 2),
                           "nt_rps": round(float(u[4]), 2)})
        else:
            raise ConfigError(f"cannot write piece type {p.kind} back to YAML")
    a = experiment.area
    return {"name": experiment.name, "description": experiment.description,
            "area": {"north_m": list(a.north_m), "east_m": list(a.east_m)},
            "start": {"heading_deg": round(math.degrees(experiment.start_heading_rad), 3),
                      "speed_mps": experiment.start_speed_mps},
            "command_rate_hz": experiment.command_rate_hz, "pieces": pieces}
