"""The compiled step kernels (lotsen.sysid.kernels)."""

import numpy as np
import pytest

from lotsen.model import DEFAULT_GEOMETRY, DEFAULT_PARAMETERS, geometry_tuple
from lotsen.sysid import kernels


@pytest.mark.parametrize("lake", [False, True])
def test_states_are_the_same_with_and_without_sensitivities(lake):
    """The Gauss-Newton search takes a trial's states (no sensitivities) for the point it ends at
    (lotsen.sysid.multiple._gauss_newton): the two kernels must agree to the last bit."""
    k = kernels.step_kernels(geometry_tuple(DEFAULT_GEOMETRY), lake=lake)
    rng = np.random.default_rng(1)
    n = 3000
    h = np.full(n, 0.0625)
    U = rng.uniform(-1, 1, (n, 10)) * [0.5, 0.5, 25, 25, 20, 0.1, 0.1, 3, 3, 3]
    reset = np.zeros(n)
    reset[::32] = 1.0
    starts = np.flatnonzero(reset)
    x0 = rng.normal(0.0, 0.3, (len(starts), k.nx))
    theta = np.array(DEFAULT_PARAMETERS.to_vector(), float)
    if lake:
        x0[:, 6] += 1.0
        theta = np.concatenate([theta, [0.05, -0.03, 2.0, -3.0, 0.02, 0.05, 0.01, 0.003]])
    need = np.arange(0, n, 3)
    X, _ = k.run_record(theta, h, U, reset, starts, x0, need, False)
    Xs, S = k.run_record(theta, h, U, reset, starts, x0, need, True)
    assert np.all(np.isfinite(X)) and np.array_equal(X, Xs)


def test_a_compiler_that_refuses_the_native_flags_gets_the_portable_ones(tmp_path, monkeypatch):
    """-march=native is not every compiler's: the portable build then, and the refusal remembered."""
    import casadi as ca

    monkeypatch.setenv("LOTSEN_CACHE_DIR", str(tmp_path))
    calls: list[tuple[str, ...]] = []

    def build(cc, flags, src, d, lib):  # type: ignore[no-untyped-def]
        calls.append(tuple(flags))
        if "-march=native" in flags:
            return False
        lib.write_bytes(b"")
        return True

    monkeypatch.setattr(kernels, "_build", build)
    x = ca.SX.sym("x")
    f = ca.Function("lotsen_test_f", [x], [2 * x])
    first = kernels._compile([f], "lotsen_test")
    assert first is not None and calls == [kernels.NATIVE_FLAGS, kernels.PORTABLE_FLAGS]
    calls.clear()
    assert kernels._compile([f], "lotsen_test") == first and calls == []  # both remembered: nothing built again
