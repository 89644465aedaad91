"""The MPC's QP data on a fixed case, against a recording (data/mpc_qp_reference.npz, written by
the assembly as it was before its arguments were grouped into PathTable, QpWeights, QpPattern and
QpData): any change to what the compiled assembly writes shows here. Compared to 1e-9 relative, not
bit for bit: another CPU or numba version may fuse or reorder floating-point operations."""

from pathlib import Path

import numpy as np
import pytest

from lotsen.control import MPCConfig, MPCController
from lotsen.messages import VesselState

from .conftest import circle_path
from .helpers import WEIGHTS_BEFORE_RETUNING

REFERENCE = Path(__file__).parent / "data" / "mpc_qp_reference.npz"
ARRAYS = ("_Px", "_Ax", "_q", "_l", "_u", "_ref", "_Ad", "_Bd", "_c")
STATES = [(0.0, 0.3, 0.05, 0.4, 0.02, 0.01), (0.05, 0.28, 0.07, 0.45, 0.01, 0.02)]
# the weights the recording was made with (the defaults then): the test checks the assembly, not the tuning
RECORDED = dict(time_limit_s=0.0, **WEIGHTS_BEFORE_RETUNING)


@pytest.mark.parametrize("name,config", [
    ("predicted", MPCConfig(**RECORDED)),
    ("time", MPCConfig(**RECORDED, progress_reference="time", qp_iterations=2)),
])
def test_assembled_qp_matches_the_recording(name, config):
    reference = np.load(REFERENCE)
    c = MPCController(config=config)
    c.reset(circle_path())
    for k, (n, e, psi, u, v, r) in enumerate(STATES):
        c.update(0.1 * k, VesselState(stamp_s=0.1 * k, north_m=n, east_m=e, heading_rad=psi, u_mps=u, v_mps=v,
                                      r_radps=r, current_ne_mps=(0.05, 0.1)))
        for a in ARRAYS:
            want = reference[f"{name}{k}{a}"]
            got = getattr(c, a)
            assert got.shape == want.shape, (name, k, a)
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12, err_msg=f"{name} update {k} {a}")
