"""Compiled RK4 step kernels with forward sensitivities, run over chunks of integration steps.

The step is the one of lotsen.sysid.sensitivity (the model's own equations through
`lotsen.model.symbolic_rhs`, classical RK4 with the input held, a reset flag that loads a node
state and S = [I, 0]). Here CasADi's `mapaccum` over `CHUNK` steps is generated as C code and
compiled once into a shared library (cached by a hash of the generated code, so a change of the
model or geometry compiles anew), then called through CasADi's buffer interface on numpy arrays:
no conversion of matrices per call. Measured on the 2-core development machine: 0.4 us per state
step, 4 us per step with the 6 x 24 sensitivity; compiling takes 2-3 s once per machine.

Without a C compiler the same functions run in CasADi's virtual machine (about 10x slower).
The cache directory is $LOTSEN_CACHE_DIR, else ~/.cache/lotsen, else the temp directory.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from lotsen.sysid.sensitivity import NS, NTHETA, NTHETA_LAKE, NX_LAKE, _build_step_functions

CHUNK = 2048  # steps per call: memory per call ~ CHUNK * 1.3 kB whatever the record length
_KERNELS: dict[tuple, "StepKernels"] = {}


def _cache_dir() -> Path:
    for cand in (os.environ.get("LOTSEN_CACHE_DIR"), os.path.join(os.path.expanduser("~"), ".cache", "lotsen"),
                 os.path.join(tempfile.gettempdir(), "lotsen-cache")):
        if not cand:
            continue
        try:
            p = Path(cand) / "sysid"
            p.mkdir(parents=True, exist_ok=True)
            if os.access(p, os.W_OK):
                return p
        except OSError:
            continue
    return Path(tempfile.mkdtemp(prefix="lotsen-sysid-"))


def _compile(functions: list[Any], tag: str) -> str | None:
    """Generate C for `functions`, compile (cached) and return the library path, or None."""
    import casadi as ca

    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        return None
    cg = ca.CodeGenerator(f"{tag}.c", {"with_header": False})
    for f in functions:
        cg.add(f)
    src = cg.dump()
    flags = ["-O2", "-shared", "-fPIC"]
    digest = hashlib.sha1((src + " ".join(flags) + ca.__version__).encode()).hexdigest()[:16]
    d = _cache_dir()
    lib = d / f"{tag}_{digest}.so"
    if lib.is_file():
        return str(lib)
    fd, tmp_c = tempfile.mkstemp(suffix=".c", dir=d)
    with os.fdopen(fd, "w") as fh:
        fh.write(src)
    tmp_so = tmp_c[:-2] + ".so"
    try:
        subprocess.run([cc, *flags, "-o", tmp_so, tmp_c], check=True, capture_output=True, timeout=300)
        os.replace(tmp_so, lib)  # atomic: parallel processes may compile the same library
    except (OSError, subprocess.SubprocessError):
        return None
    finally:
        for p in (tmp_c, tmp_so):
            try:
                os.unlink(p)
            except OSError:
                pass
    return str(lib)


class StepKernels:
    """`sim` and `sens` over CHUNK steps, on persistent numpy buffers (see module docstring)."""

    def __init__(self, geom: tuple[float, ...], chunk: int = CHUNK, lake: bool = False) -> None:
        import casadi as ca

        self.chunk = L = chunk
        self.nx, nth = (NX_LAKE, NTHETA_LAKE) if lake else (6, NTHETA)
        self.ns = ns = self.nx + nth
        nx = self.nx
        step, step_sens = _build_step_functions(geom, False, lake)
        tag = "lotsen_lake" if lake else "lotsen_ms"
        acc_sim = step.mapaccum(f"{tag}_sim", L, [0], [0])
        acc_sens = step_sens.mapaccum(f"{tag}_sens", L, [0, 1], [0, 1])
        lib = _compile([acc_sim, acc_sens], tag)
        self.compiled = lib is not None
        if lib is not None:
            acc_sim, acc_sens = ca.external(f"{tag}_sim", lib), ca.external(f"{tag}_sens", lib)
        # inputs (column-major CasADi matrices = C-ordered numpy arrays with the dimensions reversed)
        self.x0 = np.zeros(nx)
        self.S0 = np.zeros((ns, nx))
        self.U = np.zeros((L, 5))
        self.TH = np.zeros((L, nth))
        self.H = np.zeros(L)
        self.RS = np.zeros(L)
        self.XR = np.zeros((L, nx))
        self.X = np.zeros((L, nx))
        self.S = np.zeros((L, ns, nx))  # S[k, j, i] = d x_i / d p_j after step k
        self._fs = acc_sim  # keep the functions alive with their buffers
        self._fss = acc_sens
        self.buf_sim, self._ev_sim = acc_sim.buffer()
        for i, a in enumerate((self.x0, self.U, self.TH, self.H, self.RS, self.XR)):
            self.buf_sim.set_arg(i, memoryview(a))
        self.buf_sim.set_res(0, memoryview(self.X))
        self.buf_sens, self._ev_sens = acc_sens.buffer()
        for i, a in enumerate((self.x0, self.S0, self.U, self.TH, self.H, self.RS, self.XR)):
            self.buf_sens.set_arg(i, memoryview(a))
        self.buf_sens.set_res(0, memoryview(self.X))
        self.buf_sens.set_res(1, memoryview(self.S))

    def run_sim(self) -> None:
        self._ev_sim()

    def run_sens(self) -> None:
        self._ev_sens()


def step_kernels(geom: tuple[float, ...], chunk: int = CHUNK, lake: bool = False) -> StepKernels:
    """The kernels of a geometry (one set per process, geometry and model; not thread-safe);
    `lake`: with current, wind and the interval's gust factor (lotsen.sysid.sensitivity.ENV_NAMES)."""
    key = (geom, chunk, lake)
    if key not in _KERNELS:
        _KERNELS[key] = StepKernels(geom, chunk, lake)
    return _KERNELS[key]
