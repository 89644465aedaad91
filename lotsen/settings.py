"""Field metadata of settings dataclasses: the range a value must lie in.

    timeout_s: float = field(default=1.0, metadata=value_range(0.1, 60.0))

`lotsen.runtime.config.from_mapping` checks it when a config section is loaded, and the docs'
tables are generated from it; one definition for every package that declares settings.
"""

from __future__ import annotations


def value_range(lo: float, hi: float) -> dict:
    """Metadata for `dataclasses.field`: the value must lie in [lo, hi]."""
    return {"range": (lo, hi)}
