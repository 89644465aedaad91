"""Optional just-in-time compilation of the float model with numba.

The equations exist once, as plain Python on floats. With numba installed (it is a pinned
dependency and has aarch64 wheels) they are compiled on first use, about 20x faster; without
it, or with LOTSEN_NO_JIT=1, exactly the same functions run as Python.

numba itself (with LLVM, ~65 MB per process and 0.2-0.5 s to import) is imported only when a
process first calls a compiled function: the web server, the recorder and the launcher import
the model for its parameters and angles but never run it. Until then `njit` hands out
`LazyKernel`s; the first call of any of them compiles them all (numba's dispatchers are cheap
until called) and puts each dispatcher in place of its `LazyKernel` in every lotsen module, so
compiled code that calls another compiled function finds a numba dispatcher there.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import sys
import threading
from typing import Any, Callable

JIT_ENABLED = not os.environ.get("LOTSEN_NO_JIT") and importlib.util.find_spec("numba") is not None

_kernels: list["LazyKernel"] = []
_activation = threading.Lock()
_active = False


def _numba_njit(fn: Callable[..., Any]) -> Callable[..., Any]:
    import numba  # only here: see the module's docstring

    return numba.njit(cache=True, fastmath=False)(fn)


class LazyKernel:
    """A function to be compiled with numba at the first call of any kernel of the process."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.py_func = fn
        self.dispatcher: Callable[..., Any] | None = None
        functools.update_wrapper(self, fn)

    def compiled(self) -> Callable[..., Any]:
        if self.dispatcher is None:
            activate()
        assert self.dispatcher is not None
        return self.dispatcher

    def __call__(self, *args: Any) -> Any:
        return self.compiled()(*args)

    def __getattr__(self, name: str) -> Any:  # signatures, inspect_types, ... of the dispatcher
        if name.startswith("__") or name in ("dispatcher", "py_func"):
            raise AttributeError(name)
        return getattr(self.compiled(), name)


def activate() -> None:
    """Import numba and make every kernel a numba dispatcher (idempotent; the first call of a
    kernel does it, `VesselModel.warm_up` and the other warm-ups therefore too)."""
    global _active
    with _activation:
        if _active:
            return
        try:
            for kernel in _kernels:
                kernel.dispatcher = _numba_njit(kernel.py_func)
        except ImportError:  # numba installed but unusable: the same functions as Python
            for kernel in _kernels:
                kernel.dispatcher = kernel.py_func
        for name, module in list(sys.modules.items()):
            if module is None or not (name == "lotsen" or name.startswith("lotsen.")):
                continue
            for attr, value in list(vars(module).items()):
                if isinstance(value, LazyKernel):
                    setattr(module, attr, value.dispatcher)
        _active = True


def njit(fn: Callable[..., Any]) -> Callable[..., Any]:
    if not JIT_ENABLED:
        return fn
    if _active:
        try:
            return _numba_njit(fn)
        except ImportError:
            return fn
    kernel = LazyKernel(fn)
    _kernels.append(kernel)
    return kernel


def py_func(fn: Any) -> Callable[..., Any]:
    """The plain Python function behind a (possibly) compiled one."""
    return getattr(fn, "py_func", fn)
