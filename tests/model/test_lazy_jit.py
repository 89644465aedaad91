"""numba is imported only by a process that runs a compiled kernel."""

import subprocess
import sys


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_importing_the_model_planning_and_the_web_server_does_not_import_numba():
    out = _run("import sys, lotsen.model, lotsen.planning, lotsen.sim, lotsen.web.server\n"
               "print('numba' in sys.modules, 'scipy' in sys.modules)")
    assert out == "False False"


def test_the_first_kernel_call_compiles_every_kernel_and_rebinds_them():
    out = _run("import sys\n"
               "from lotsen.model import VesselModel, dynamics\n"
               "from lotsen.sim import plant\n"
               "from lotsen.model._jit import JIT_ENABLED, LazyKernel\n"
               "before = isinstance(dynamics.rk4_step, LazyKernel)\n"
               "x = VesselModel().step((0.1,) * 6, (0.1,) * 5, 0.1)\n"
               "print(JIT_ENABLED, before, type(dynamics.rk4_step).__name__, type(plant._plant_step).__name__,"
               " 'numba' in sys.modules)")
    jit, before, rk4, plant, loaded = out.split()
    if jit == "True":
        assert (before, rk4, plant, loaded) == ("True", "CPUDispatcher", "CPUDispatcher", "True")
    else:
        assert loaded == "False"


def test_lazy_and_compiled_kernels_give_the_same_step():
    out = _run("from lotsen.model import VesselModel\n"
               "from lotsen.model.dynamics import _rk4_py, _as_floats, NX, NU\n"
               "m = VesselModel()\n"
               "x, u = (0.3, -0.2, 0.1, 0.5, 0.05, 0.02), (0.1, -0.1, 20.0, 22.0, 3.0)\n"
               "a = m.step(x, u, 0.1)\n"
               "b, _ = _rk4_py(_as_floats(x, NX), _as_floats(u, NU), m.arrays.packed, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1)\n"
               "print(max(abs(p - q) for p, q in zip(a, b)))")
    assert float(out) < 1e-9
