"""Vessel parameters, geometry and actuator limits, with units and physical ranges in one place.

The parameter vector theta follows the seed's eq. (26). Sign convention (Fossen): linear damping
coefficients are positive, quadratic ones negative, so that every damping term dissipates energy.
The metadata (unit, range, description) validates files and generates the docs' parameter table.
"""

from __future__ import annotations

import difflib
import json
import math
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Mapping

from lotsen.errors import ConfigError
from lotsen.files import read_json
from lotsen.settings import Number


#: coefficients that are optional model terms, beyond the seed's eq. (22): 0 switches a term off, and a
#: parameter file without one means it is off (identification turns one on where held-out prediction
#: shows the record needs it: lotsen.sysid.identify)
OPTIONAL_TERMS = {"X_uuu": "the surge resistance grows faster than speed squared (wave making)"}

#: identification's verdicts (lotsen.sysid.judge) a loader takes: "ok", "weak" (usable, some
#: coefficients weakly determined), "predictive" (effective values: they predict the boat's motion
#: though some are not its physical coefficients). "refused" and anything else is refused. The one
#: place the verdict of a parameter file is judged (`check_verdict`).
USABLE_VERDICTS = ("ok", "weak", "predictive")
#: the key of a parameter file that lists the coefficients it takes from the documented defaults
DEFAULTS_KEY = "defaults_for"


def _p(default: float, unit: str, lo: float, hi: float, doc: str) -> Any:
    return field(default=default, metadata={"unit": unit, "range": (lo, hi), "doc": doc,
                                            "number": Number(lo, hi, unit)})


@dataclass(frozen=True)
class VesselParameters:
    """The unknown parameters theta of the grey-box model (seed eq. 26); defaults: vessel-model.md's set."""

    m11: float = _p(14.0, "kg", 1.0, 200.0, "surge mass incl. added mass")
    m22: float = _p(24.0, "kg", 1.0, 400.0, "sway mass incl. added mass")
    m33: float = _p(1.8, "kg m^2", 0.01, 50.0, "yaw inertia incl. added inertia")
    X_u: float = _p(4.0, "kg/s", 0.0, 500.0, "linear surge damping (seed 16a: > 0)")
    X_uu: float = _p(-5.0, "kg/m", -500.0, 0.0, "quadratic surge damping X_|u|u")
    Y_v: float = _p(12.0, "kg/s", 0.0, 1000.0, "linear sway damping (seed 16b: > 0)")
    Y_r: float = _p(1.0, "kg m/s", -100.0, 100.0, "sway force from yaw rate")
    Y_uv: float = _p(-8.0, "kg/m", -1000.0, 0.0, "sway damping growing with speed Y_|u|v")
    Y_vv: float = _p(-40.0, "kg/m", -2000.0, 0.0, "quadratic sway damping Y_|v|v")
    Y_rv: float = _p(-2.0, "kg", -500.0, 0.0, "cross damping Y_|r|v")
    N_v: float = _p(0.5, "kg m/s", -100.0, 100.0, "yaw moment from sway velocity")
    N_r: float = _p(3.0, "kg m^2/s", 0.0, 200.0, "linear yaw damping (seed 16c: > 0)")
    N_vv: float = _p(-1.0, "kg m", -500.0, 0.0, "yaw moment N_|v|v")
    N_rr: float = _p(-1.5, "kg m^2", -500.0, 0.0, "quadratic yaw damping N_|r|r")
    kappa: float = _p(0.02, "m/rev", 0.0, 1.0, "propeller slipstream factor of the housing force")
    C_N: float = _p(1.0, "-", 0.0, 10.0, "normal-force coefficient of the thruster housing")
    mu_az: float = _p(0.0011, "N s^2", 1e-6, 0.1, "azimuth thrust per (rev/s)^2")
    mu_t: float = _p(0.0004, "N s^2", 0.0, 0.1, "bow-thruster thrust per (rev/s)^2")
    # optional model terms (0: off, the seed's equations exactly): OPTIONAL_TERMS
    X_uuu: float = _p(0.0, "kg s/m^2", -500.0, 0.0, "cubic surge damping X_uuu u^3 (optional term: resistance that "
                      "grows faster than speed squared, wave making near hull speed; 0 = off)")

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"parameter {f.name}: {value!r} is not a finite number")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    def to_vector(self) -> tuple[float, ...]:
        """theta in the order of seed eq. (26)."""
        return tuple(float(getattr(self, n)) for n in self.names())

    @classmethod
    def from_vector(cls, theta: Any) -> "VesselParameters":
        """From theta in `names()` order; the seed's 18 alone leave the optional terms off."""
        names = cls.names()
        if len(theta) not in (len(names), len(names) - len(OPTIONAL_TERMS)):
            raise ConfigError(f"parameter vector has {len(theta)} entries, expected {len(names)}")
        return cls(**{n: float(v) for n, v in zip(names, theta)})

    def to_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = "parameters") -> "VesselParameters":
        """Build from a mapping (a params.json, a config): the boundary where values are checked.
        Unknown keys, non-numbers and values outside the physical range of the field metadata
        are ConfigErrors naming parameter, value and range; missing keys take the defaults.
        The extra keys identification writes (`std`, `verdict`, `identification`, `environment`, ...:
        anything whose value is not a number) are ignored, but a file whose `verdict` is "refused"
        (the data could not support an answer) is refused here, with its reasons. (The constructor
        checks only finiteness, so identification may evaluate vectors outside the ranges.)
        """
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: expected a mapping of parameter names to numbers")
        check_verdict(data, source)
        known = set(cls.names())
        values: dict[str, float] = {}
        for key, value in data.items():
            if key not in known and (isinstance(value, (str, list, dict)) or value is None):
                continue  # identification's extra keys (std, verdict, reasons, ...)
            if key not in known:
                close = difflib.get_close_matches(str(key), cls.names(), n=1, cutoff=0.6)
                hint = f"did you mean {close[0]!r}?" if close else f"known: {', '.join(cls.names())}"
                raise ConfigError(f"{source}: unknown parameter {str(key)[:40]!r} ({hint})")
            f = cls.__dataclass_fields__[key]
            number = f.metadata["number"]
            try:
                values[key] = number.check(value, f"{source}: {key}")
            except ConfigError as exc:
                raise ConfigError(f"{exc} ({f.metadata['doc']})") from None
        return cls(**values)

    def with_updates(self, **changes: float) -> "VesselParameters":
        return replace(self, **changes)

    def physical_violations(self) -> list[str]:
        """Which parameters lie outside their physical range (seed 16a-c included)."""
        out = []
        for f in fields(self):
            lo, hi = f.metadata["range"]
            v = getattr(self, f.name)
            if not lo <= v <= hi:
                out.append(f"{f.name} = {v:g} outside [{lo:g}, {hi:g}] {f.metadata['unit']}")
        for name in ("X_u", "Y_v", "N_r"):
            if getattr(self, name) <= 0.0:
                out.append(f"{name} = {getattr(self, name):g} must be > 0 (seed eq. 16)")
        return out


# The documented default set of vessel-model.md (sized for a 0.99 m, 13 kg hull).
DEFAULT_PARAMETERS = VesselParameters()


def check_verdict(data: Mapping[str, Any], source: str) -> str:
    """The identification verdict of a parameter file ("" when it has none); ConfigError with the
    recorded reasons when it is not one of USABLE_VERDICTS."""
    verdict = data.get("verdict")
    if verdict is None:
        return ""
    if verdict not in USABLE_VERDICTS:
        details = data.get("identification")
        reasons = details.get("reasons") if isinstance(details, Mapping) else None
        why = "; ".join(str(r) for r in reasons)[:600] if isinstance(reasons, list) else ""
        if verdict == "refused":
            raise ConfigError(f"{source}: identification refused these coefficients ({why or 'no reason recorded'}); "
                              "record a better experiment and identify again, or use another file")
        raise ConfigError(f"{source}: verdict {str(verdict)[:40]!r} is not one of {', '.join(USABLE_VERDICTS)} "
                          "(a file identification refused is refused by every loader)")
    return str(verdict)


@dataclass(frozen=True)
class ParameterFile:
    """A parameter file as loaded: its coefficients, those it takes from the documented defaults
    (it must say so: `"defaults_for": [...]`), its verdict and where it came from."""

    parameters: VesselParameters
    source: str
    defaults_for: tuple[str, ...] = ()
    verdict: str = ""

    def describe(self) -> str:
        """What every report names: 'params.json' or 'params.json (defaults for Y_rv, N_vv)'."""
        return self.source + (f" (defaults for {', '.join(self.defaults_for)})" if self.defaults_for else "")


def parameters_from_file(data: Any, source: str) -> ParameterFile:
    """The boundary of every parameter file (a params JSON from `lotsen identify --out`, a boat's
    coefficients): all 18 of the seed's coefficients present, each a finite number in its physical range (no
    denormals), the verdict one of USABLE_VERDICTS. A coefficient left out is refused, naming every
    missing one, unless the file lists it in "defaults_for" (then the documented default is used
    and `ParameterFile.describe` says so in every report). Numbers only for coefficients; other
    keys (std, verdict, identification, ...) are identification's and skipped. The optional model
    terms (OPTIONAL_TERMS) may be left out: off."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{source}: expected a JSON object of parameter names to numbers")
    verdict = check_verdict(data, source)
    names = VesselParameters.names()
    raw_defaults = data.get(DEFAULTS_KEY, [])
    if not isinstance(raw_defaults, list) or not all(isinstance(n, str) for n in raw_defaults):
        raise ConfigError(f"{source}: {DEFAULTS_KEY}: expected a list of coefficient names, e.g. "
                          f'"{DEFAULTS_KEY}": ["Y_rv", "N_vv"]')
    unknown = [n for n in raw_defaults if n not in names]
    if unknown:
        raise ConfigError(f"{source}: {DEFAULTS_KEY}: unknown coefficient(s) {', '.join(repr(n[:20]) for n in unknown[:5])} "
                          f"(known: {', '.join(names)})")
    defaults = tuple(n for n in names if n in raw_defaults)
    both = [n for n in defaults if n in data]
    if both:
        raise ConfigError(f"{source}: {', '.join(both)} both given and listed in {DEFAULTS_KEY}; keep one")
    values = {k: v for k, v in data.items() if k != DEFAULTS_KEY}
    parameters = VesselParameters.from_dict(values, source=source)  # what is there is physical
    # an optional model term left out is off (0), as in every file written before it existed
    missing = [n for n in names if n not in data and n not in defaults and n not in OPTIONAL_TERMS]
    if missing:
        example = ", ".join(json.dumps(n) for n in missing[:3])
        raise ConfigError(f"{source}: missing coefficient(s) {', '.join(missing)}: a parameter file gives all "
                          f"{len(names) - len(OPTIONAL_TERMS)} (a model half of defaults is a wrong model on the "
                          f"boat; optional terms such as {', '.join(OPTIONAL_TERMS)} may be left out: off); to take the "
                          f'documented defaults for some, list them: "{DEFAULTS_KEY}": [{example}]')
    return ParameterFile(parameters, source, defaults, verdict)


@dataclass(frozen=True)
class VesselGeometry:
    """Fixed geometry (seed Table 1). Body frame: x forward, y starboard, origin amidships."""

    length_m: float = 0.99
    beam_m: float = 0.30
    mass_kg: float = 13.0
    l_x1: float = -0.39  # starboard azimuth thruster
    l_y1: float = 0.07
    l_x2: float = -0.39  # port azimuth thruster
    l_y2: float = -0.07
    l_xt: float = 0.37  # bow tunnel thruster
    rudder_area_m2: float = 0.001  # A_r, effective housing area
    rho_water: float = 1000.0
    # Field notes: reverse thrust is weaker than forward on most propellers. 1.0 is the seed's
    # symmetric n|n| model; a value < 1 scales thrust for negative propeller speed.
    reverse_thrust_ratio: float = 1.0


@dataclass(frozen=True)
class ActuatorLimits:
    """Limits of servos and motors (vessel-model.md 'Actuators'); also the MPC's input bounds (seed 44)."""

    alpha_max_rad: float = math.radians(45.0)
    alpha_rate_max_radps: float = math.radians(180.0)  # hobby servo, about 0.33 s per 60 deg
    n_az_max_rps: float = 100.0
    n_bow_max_rps: float = 80.0
    n_rate_max_rps2: float = 400.0  # ESC ramp limit
    motor_time_constant_s: float = 0.08  # first-order ESC + motor speed response

    def clip(self, alpha1: float, alpha2: float, n1: float, n2: float, nt: float) -> tuple[float, ...]:
        a, na, nb = self.alpha_max_rad, self.n_az_max_rps, self.n_bow_max_rps
        return (min(max(alpha1, -a), a), min(max(alpha2, -a), a),
                min(max(n1, -na), na), min(max(n2, -na), na), min(max(nt, -nb), nb))


DEFAULT_GEOMETRY = VesselGeometry()
DEFAULT_LIMITS = ActuatorLimits()


def parameter_table_markdown() -> str:
    """The parameter table of the docs, generated from the metadata above."""
    rows = ["| parameter | default | unit | range | meaning |", "|---|---|---|---|---|"]
    for f in fields(VesselParameters):
        lo, hi = f.metadata["range"]
        rows.append(f"| {f.name} | {getattr(DEFAULT_PARAMETERS, f.name):g} | {f.metadata['unit']} "
                    f"| [{lo:g}, {hi:g}] | {f.metadata['doc']} |")
    return "\n".join(rows)


def load_parameter_file(path: str) -> ParameterFile:
    """The one loader of parameter files (as `lotsen identify --out` writes them): every coefficient
    present and physical, or listed in "defaults_for"; a file identification refused is refused
    here too, with its reasons (`parameters_from_file`). Below the commands and the stack, so that
    both read a file the same way."""
    return parameters_from_file(read_json(path, ConfigError), str(path))
