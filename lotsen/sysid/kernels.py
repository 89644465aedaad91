"""Compiled RK4 step kernels with forward sensitivities, run over chunks of integration steps.

The step is the one of lotsen.sysid.sensitivity (the model's own equations through
`lotsen.model.symbolic_rhs`, classical RK4 with the input held, a reset flag that loads a node
state and S = [I, 0]). Here CasADi's `mapaccum` over `CHUNK` steps (and over `TAIL_CHUNK` steps for
what is left at the end of a run) is generated as C code and compiled once into a shared library
(for this processor, NATIVE_FLAGS; cached by a hash of the generated code, the flags and the processor,
so a change of the model or geometry compiles anew), then
called through CasADi's buffer interface on numpy arrays: no conversion of matrices per call.
A call always computes its whole chunk, so the short one ends a run: with one chunk of 2048 a 60-s
design record (960 steps) computed twice its steps, and a block of shooting intervals a fraction
more. The steps are the same arithmetic whatever the chunks (the state is carried over exactly).
Measured on the 2-core development machine: 0.4 us per state step, 3-4 us per step with the
8 x 41 sensitivity of the lake model; compiling takes 5-10 s once per machine.

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
from typing import Any, Sequence

import numpy as np

from lotsen.model import DEFAULT_GEOMETRY, VesselGeometry, geometry_tuple
from lotsen.sysid.data import OUTPUT_STATE_INDEX, Segment
from lotsen.sysid.sensitivity import NS, NTHETA, NTHETA_LAKE, NU, NX_LAKE, _build_step_functions, make_grid

CHUNK = 512  # steps per call: memory per call ~ CHUNK * 2.6 kB whatever the record length
TAIL_CHUNK = 64  # the last steps of a run, in calls this long (fewer wasted steps)
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
    d = _cache_dir()
    for flags, machine in ((NATIVE_FLAGS, _this_cpu()), (PORTABLE_FLAGS, "")):
        digest = hashlib.sha1((src + " ".join(flags) + machine + ca.__version__).encode()).hexdigest()[:16]
        lib = d / f"{tag}_{digest}.so"
        failed = lib.with_suffix(".failed")  # the compiler refused the native flags once: not at every run again
        if lib.is_file() or (not failed.exists() and _build(cc, flags, src, d, lib)):
            return str(lib)
        if machine:
            failed.touch()
    return None


#: the kernels' compiler flags: this processor's instructions (the sensitivity step 15-20 % faster with
#: AVX here), but no fused multiply-add (-ffp-contract=off): every operation rounds as IEEE 754 says, so
#: the numbers are those of the portable build bit for bit (and the answer the same on any machine that
#: rounds so). A compiler without -march=native gets the portable flags.
NATIVE_FLAGS = ("-O3", "-march=native", "-ffp-contract=off", "-shared", "-fPIC")
PORTABLE_FLAGS = ("-O2", "-ffp-contract=off", "-shared", "-fPIC")


def _this_cpu() -> str:
    """The processor's identity and features (Linux; else the machine's type), part of a native build's
    cache key: a cache directory shared with another processor must not load code it cannot run."""
    import platform

    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as fh:
            lines = [ln for ln in fh.read(1 << 16).splitlines() if ln.split(":")[0].strip() in
                     ("model name", "flags", "Features", "CPU part")]
        return "\n".join(dict.fromkeys(lines)) or platform.machine()
    except OSError:
        return platform.machine() + platform.processor()


def _build(cc: str, flags: Sequence[str], src: str, d: Path, lib: Path) -> bool:
    fd, tmp_c = tempfile.mkstemp(suffix=".c", dir=d)
    with os.fdopen(fd, "w") as fh:
        fh.write(src)
    tmp_so = tmp_c[:-2] + ".so"
    try:
        subprocess.run([cc, *flags, "-o", tmp_so, tmp_c], check=True, capture_output=True, timeout=300)
        os.replace(tmp_so, lib)  # atomic: parallel processes may compile the same library
        return True
    except (OSError, subprocess.SubprocessError):
        return False
    finally:
        for p in (tmp_c, tmp_so):
            try:
                os.unlink(p)
            except OSError:
                pass


class StepKernels:
    """`sim` and `sens` over CHUNK steps, on persistent numpy buffers (see module docstring)."""

    def __init__(self, geom: tuple[float, ...], chunk: int = CHUNK, lake: bool = False) -> None:
        import casadi as ca

        self.chunk = chunk
        self.nx, nth = (NX_LAKE, NTHETA_LAKE) if lake else (6, NTHETA)
        self.ns = self.nx + nth
        self.nth = nth
        step, step_sens = _build_step_functions(geom, False, lake)
        tag = "lotsen_lake" if lake else "lotsen_ms"
        lengths = (chunk, TAIL_CHUNK) if chunk > TAIL_CHUNK else (chunk,)
        functions = [(step.mapaccum(f"{tag}_sim{L}", L, [0], [0]),
                      step_sens.mapaccum(f"{tag}_sens{L}", L, [0, 1], [0, 1])) for L in lengths]
        lib = _compile([f for pair in functions for f in pair], tag)
        self.compiled = lib is not None
        if lib is not None:
            functions = [(ca.external(f"{tag}_sim{L}", lib), ca.external(f"{tag}_sens{L}", lib)) for L in lengths]
        self._calls = [_ChunkCall(sim, sens, L, self.nx, self.ns, nth) for L, (sim, sens) in zip(lengths, functions)]

    def run_record(self, theta: Sequence[float], h: np.ndarray, U: np.ndarray, reset: np.ndarray,
                   reset_step: np.ndarray, reset_states: np.ndarray, need: np.ndarray,
                   sens: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """A whole grid of steps (h, U: n_steps x 10 input lines, reset) chunk by chunk: the state starts from
        `reset_states[i]` at step `reset_step[i]` (sorted), and the states (and with `sens` the
        sensitivities, len(need) x nx x ns) after the steps `need` (sorted) are returned."""
        n_steps = len(h)
        X = np.empty((len(need), self.nx))
        S = np.empty((len(need), self.nx, self.ns)) if sens else None
        x0, S0 = np.zeros(self.nx), np.zeros((self.ns, self.nx))
        theta = np.asarray(theta, float)
        long, short = self._calls[0], self._calls[-1]
        a = 0
        while a < n_steps:
            call = long if n_steps - a > long.chunk - short.chunk or long is short else short
            b = min(a + call.chunk, n_steps)
            lo, hi = np.searchsorted(reset_step, [a, b])
            call.load(theta, h[a:b], U[a:b], reset[a:b], x0, S0 if sens else None)
            call.set_resets(reset_step[lo:hi] - a, reset_states[lo:hi])
            i0, i1 = np.searchsorted(need, [a, b])
            cols = need[i0:i1] - a
            n = b - a
            if sens:
                call.run_sens()
                S[i0:i1] = call.S[cols].transpose(0, 2, 1)
                S0 = call.S[n - 1]
            else:
                call.run_sim()
            X[i0:i1] = call.X[cols]
            x0 = call.X[n - 1]
            a = b
        return X, S


class _ChunkCall:
    """One compiled chunk length: its functions and the numpy buffers they read and write."""

    def __init__(self, acc_sim: Any, acc_sens: Any, L: int, nx: int, ns: int, nth: int) -> None:
        self.chunk = L
        # inputs (column-major CasADi matrices = C-ordered numpy arrays with the dimensions reversed)
        self.x0 = np.zeros(nx)
        self.S0 = np.zeros((ns, nx))
        self.U = np.zeros((L, 2 * NU))  # the input's line over each step (u0, du)
        self.TH = np.zeros((L, nth))
        self.H = np.zeros(L)
        self.RS = np.zeros(L)
        self.XR = np.zeros((L, nx))
        self.X = np.zeros((L, nx))
        self.S = np.zeros((L, ns, nx))  # S[k, j, i] = d x_i / d p_j after step k
        self._theta: np.ndarray | None = None  # what TH holds (the same for a whole run)
        self._reset_rows = np.zeros(0, int)  # the rows of XR the last chunk set
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

    def load(self, theta: np.ndarray, h: np.ndarray, U: np.ndarray, reset: np.ndarray, x0: np.ndarray,
             S0: np.ndarray | None) -> None:
        """One chunk's inputs (the steps beyond len(h) do nothing: zero length, no reset); what stays the
        same from chunk to chunk (the parameters) is not copied again."""
        n = len(h)
        self.x0[:] = x0
        if S0 is not None:
            self.S0[:] = S0
        if self._theta is None or not np.array_equal(theta, self._theta):
            self.TH[:] = theta[None, :]
            self._theta = theta.copy()
        self.H[:n] = h
        self.U[:n] = U
        self.RS[:n] = reset
        if n < self.chunk:
            self.H[n:] = 0.0
            self.RS[n:] = 0.0

    def set_resets(self, rows: np.ndarray, states: np.ndarray) -> None:
        """The node states loaded at `rows` of this chunk (the other rows' reset flags are 0)."""
        self.XR[self._reset_rows] = 0.0
        self.XR[rows] = states
        self._reset_rows = rows

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


class WindowSimulator:
    """Simulate windows for a theta and initial states; optionally with sensitivities.

    Runs the compiled chunk kernels of lotsen.sysid.kernels (CHUNK steps per call), so the memory
    is bounded whatever the record length; only the states at the samples are kept."""

    def __init__(self, windows: Sequence[Segment], geometry: VesselGeometry = DEFAULT_GEOMETRY,
                 h_max: float = 0.0625, jit: bool | None = None) -> None:
        self.windows = list(windows)
        self.geom = geometry_tuple(geometry)
        self.grid = make_grid(self.windows, h_max)
        self.k = step_kernels(self.geom)

    def _run(self, theta: Sequence[float], x0s: np.ndarray, sens: bool) -> tuple[np.ndarray, np.ndarray | None]:
        g = self.grid
        return self.k.run_record(theta, g.h, g.U.T, g.reset, g.window_start_step,  # U: 10 x n -> n x 10 view
                                 np.asarray(x0s, dtype=float).reshape(-1, 6), g.sample_step, sens)

    def simulate(self, theta: Sequence[float], x0s: np.ndarray) -> np.ndarray:
        """States at every sample (n_samples x 6), windows concatenated."""
        return self._run(theta, x0s, False)[0]

    def simulate_sens(self, theta: Sequence[float], x0s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """States (n_samples x 6) and sensitivities (n_samples x 6 x 24: d x / d[x0_window, theta])."""
        X, S = self._run(theta, x0s, True)
        return X, S  # type: ignore[return-value]

    def output_index(self) -> list[int]:
        names = self.windows[0].output_names
        return [OUTPUT_STATE_INDEX[n] for n in names]
