import dataclasses
import math

import pytest


def _same(a, b) -> bool:
    if dataclasses.is_dataclass(a):
        if type(a) is not type(b):
            return False
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, float) or isinstance(b, float):  # (the simulator publishes numpy floats)
        return (math.isnan(a) and math.isnan(b)) or a == b
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


@pytest.fixture
def same():
    """Message equality where NaN equals NaN (messages carry NaN for 'not available')."""
    return _same
