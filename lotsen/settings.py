"""The one number type of every setting, command-line flag and file field that carries a number.

A `Number` says what a value must be: finite, within [lo, hi] in its unit, a whole number where it
must be one, never a denormal (a magnitude below 2.2e-308 is an artefact, not a measurement), and
optionally 0 besides the range (a node speed of 0 means "at rest here"; 1e-9 m/s means nothing).
The same rules hold for a value from a flag, a YAML file or a JSON file, and every refusal names
the place, the value and the allowed range with its unit:

    nodes[2].speed_mps: 1e-09 outside the allowed range 0 or 0.05 to 5 m/s
    argument --node: nan is not a finite number (allowed: 0.2 to 60 s)

Settings dataclasses declare it as field metadata,

    timeout_s: float = field(default=1.0, metadata=value_range(0.1, 60.0, "s"))

which `lotsen.runtime.config.from_mapping` checks when a config section is loaded; a command-line
flag takes the same object as its argparse `type` (`type=Number(0.1, 60.0, "s")`).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from typing import Any

from lotsen.errors import ConfigError, LotsenError

#: the smallest normal double: anything nonzero below it is a denormal
_TINY = sys.float_info.min
#: a seed or other integer is at most this many digits when written (int() of a 5000-digit
#: string is itself slow, and Python refuses beyond 4300)
_MAX_INT_DIGITS = 40


def _fmt(v: float) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


@dataclass(frozen=True)
class Number:
    """A physical number: finite, in [lo, hi] `unit`, an integer if `integer`, 0 also allowed if
    `zero_ok` (for quantities where 0 means "none" and tiny values mean nothing)."""

    lo: float
    hi: float
    unit: str = ""
    integer: bool = False
    zero_ok: bool = False

    def __post_init__(self) -> None:
        if not self.lo <= self.hi:
            raise ValueError(f"Number: lo {self.lo} above hi {self.hi}")

    def allowed(self) -> str:
        """'0.1 to 60 s', '0 or 0.05 to 5 m/s', '0 to 4294967295 (whole numbers)'."""
        unit = f" {self.unit}" if self.unit else ""
        if self.lo <= -sys.float_info.max and self.hi >= sys.float_info.max:
            return f"a finite number{' in ' + self.unit if self.unit else ''}"
        span = f"{_fmt(self.lo)} to {_fmt(self.hi)}{unit}"
        if self.zero_ok and not self.lo <= 0 <= self.hi:
            span = f"0 or {span}"
        return f"{span} (whole numbers)" if self.integer else span

    def check(self, value: Any, where: str, error: type[LotsenError] = ConfigError) -> Any:
        """`value` (a parsed number) as float (int if `integer`), or `error` naming `where`."""
        if not isinstance(value, (bool, int, float)) and hasattr(value, "item") and hasattr(value, "__float__"):
            value = value.item()  # a numpy scalar: its Python number
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            shown = repr(value)
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            raise error(f"{where}: expected a number, got {shown} (allowed: {self.allowed()})")
        if isinstance(value, int):
            if abs(value) > sys.float_info.max:
                raise error(f"{where}: integer with {len(str(abs(value)))} digits is outside the allowed "
                            f"range {self.allowed()}")
            v: float = value
        else:
            v = value
            if not math.isfinite(v):
                raise error(f"{where}: {v} is not a finite number (allowed: {self.allowed()})")
            if v != 0.0 and abs(v) < _TINY:
                raise error(f"{where}: {v!r} is a denormal number (magnitude below {_TINY:.3g}), not a "
                            f"meaningful value (allowed: {self.allowed()})")
        if self.integer and v != math.floor(v):
            raise error(f"{where}: {_fmt(v)} is not a whole number (allowed: {self.allowed()})")
        if not (self.lo <= v <= self.hi or (self.zero_ok and v == 0)):
            shown = repr(v) if len(repr(v)) <= 40 else f"{float(v):g}"
            raise error(f"{where}: {shown} outside the allowed range {self.allowed()}")
        return int(v) if self.integer else float(v)

    def parse(self, text: str, where: str, error: type[LotsenError] = ConfigError) -> Any:
        """A number written as text (a flag, a CSV cell), checked as `check` does."""
        s = str(text).strip()
        if not s:
            raise error(f"{where}: empty (expected a number, allowed: {self.allowed()})")
        if len(s) > 400:
            raise error(f"{where}: {len(s)} characters is not a number (allowed: {self.allowed()})")
        value: Any
        try:
            if self.integer and s.lstrip("+-").isdigit():
                if len(s.lstrip("+-")) > _MAX_INT_DIGITS:
                    raise error(f"{where}: an integer of {len(s.lstrip('+-'))} digits is outside the allowed "
                                f"range {self.allowed()}")
                value = int(s)
            else:
                value = float(s)
        except ValueError:
            shown = s if len(s) <= 40 else s[:37] + "..."
            raise error(f"{where}: {shown!r} is not a number (allowed: {self.allowed()})") from None
        return self.check(value, where, error)

    def __call__(self, text: str) -> Any:
        """argparse `type=`: argparse prefixes the flag ("argument --node: ...")."""
        try:
            return self.parse(text, "value")
        except LotsenError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("value: ")) from None


def value_range(lo: float, hi: float, unit: str = "", integer: bool = False, zero_ok: bool = False) -> dict:
    """Metadata for `dataclasses.field`: the value is a `Number` (`"number"`); `"range"` keeps
    (lo, hi) for the code that reads only the bounds (docs tables, estimator bounds)."""
    return {"range": (lo, hi), "number": Number(lo, hi, unit, integer, zero_ok)}


def number_of(metadata: Any, integer: bool = False) -> Number | None:
    """The `Number` of a field's metadata (a bare "range" becomes one without a unit)."""
    n = metadata.get("number")
    if n is None and metadata.get("range") is not None:
        lo, hi = metadata["range"]
        n = Number(lo, hi)
    if n is not None and integer and not n.integer:
        n = Number(n.lo, n.hi, n.unit, True, n.zero_ok)
    return n


#: unit of a setting named by the project's convention (`timeout_s`, `speed_mps`, `rate_hz`, ...)
_SUFFIX_UNITS = (("_deg_s", "deg/s"), ("_mps2", "m/s^2"), ("_mps", "m/s"), ("_rps", "rev/s"), ("_radps", "rad/s"),
                 ("_rad", "rad"), ("_deg", "deg"), ("_hz", "Hz"), ("_ms", "ms"), ("_s", "s"), ("_m", "m"),
                 ("_N", "N"), ("_v", "V"), ("_a", "A"), ("_bytes", "bytes"), ("_mb", "MB"), ("_pct", "%"))


def unit_from_name(name: str) -> str:
    """The unit a setting's name carries by the naming convention ('' when it carries none)."""
    return next((unit for suffix, unit in _SUFFIX_UNITS if name.endswith(suffix)), "")


def with_unit(number: Number, name: str) -> Number:
    """`number`, with the unit of `name` when it has none of its own."""
    if number.unit:
        return number
    unit = unit_from_name(name)
    return Number(number.lo, number.hi, unit, number.integer, number.zero_ok) if unit else number


# Common quantities (one definition each; flags and files share them)
SEED = Number(0, 2**32 - 1, integer=True)  # numpy's seeds
PORT = Number(0, 65535, integer=True)  # 0: the system picks one
RUN_DURATION = Number(0.1, 7 * 86400.0, "s")  # a command that runs until stopped, stopped after this: a week at most
