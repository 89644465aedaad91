"""Optional just-in-time compilation of the float model with numba.

The equations exist once, as plain Python on floats. With numba installed (it is a pinned
dependency and has aarch64 wheels) they are compiled on first use, about 20x faster; without
it, or with LOTSEN_NO_JIT=1, exactly the same functions run as Python.
"""

from __future__ import annotations

import os
from typing import Any, Callable

try:  # pragma: no cover - depends on the environment
    if os.environ.get("LOTSEN_NO_JIT"):
        raise ImportError("disabled by LOTSEN_NO_JIT")
    import numba

    def njit(fn: Callable[..., Any]) -> Callable[..., Any]:
        return numba.njit(cache=True, fastmath=False)(fn)

    JIT_ENABLED = True
except ImportError:  # pragma: no cover
    def njit(fn: Callable[..., Any]) -> Callable[..., Any]:
        return fn

    JIT_ENABLED = False


def py_func(fn: Any) -> Callable[..., Any]:
    """The plain Python function behind a (possibly) compiled one."""
    return getattr(fn, "py_func", fn)
