"""The EKF's model input (issue 14, item 2): achieved actuator values, not the set-points."""

from __future__ import annotations

import numpy as np

from lotsen.fusion import ModelAidedEKF
from lotsen.fusion.inputs import ActuatorInputFilter, InputConfig
from lotsen.messages import ActuatorState, ThrustCommand, VesselState

DT = 0.05


def _run(f: ActuatorInputFilter, seconds: float, t0: float, cmd: tuple, measured=None) -> tuple[float, list]:
    """Set-point every 50 ms, a measurement (if given: t -> speeds) every 50 ms; returns (t, values)."""
    t, out = t0, []
    for _ in range(int(round(seconds / DT))):
        f.set_command(t, cmd)
        if measured is not None:
            f.measure_speeds(t, measured(t))
        t += DT
        f.advance(t, DT)
        out.append(f.value())
    return t, out


def test_escs_not_armed_give_no_thrust() -> None:
    f = ActuatorInputFilter()
    f.set_armed(False)
    _, vals = _run(f, 3.0, 0.0, (0.0, 0.0, 60.0, 60.0, 0.0))
    assert all(v[2] == 0.0 and v[3] == 0.0 for v in vals)
    f.set_armed(True)
    _, vals = _run(f, 2.0, 3.0, (0.0, 0.0, 60.0, 60.0, 0.0))
    assert vals[-1][2] > 50.0  # the motor model spins up once armed


def test_quantised_tachometer_does_not_step_the_input() -> None:
    """A 3.3 rev/s quantised tachometer around the modelled speed: the input stays within a
    fraction of a step of the model (the offset filter averages), no 3.3 rev/s jumps."""
    rng = np.random.default_rng(3)
    f = ActuatorInputFilter()
    q = 20.0 / 6.0
    _, vals = _run(f, 4.0, 0.0, (0.0, 0.0, 50.0, 50.0, 0.0))  # spun up on the model alone
    ref = vals[-1][2]
    _, vals = _run(f, 5.0, 4.0, (0.0, 0.0, 50.0, 50.0, 0.0),
                   measured=lambda t: tuple(q * round((ref + rng.normal(0, 0.2)) / q) for _ in range(3)))
    n1 = np.array([v[2] for v in vals])
    assert np.max(np.abs(np.diff(n1))) < 0.5  # no quantisation steps in the prediction's input
    assert abs(n1[-1] - ref) < 1.0


def test_esc_that_does_not_follow_is_followed_from_the_first_measurement() -> None:
    """Armed by the report, but the ESC holds neutral (a failed or still-arming ESC): the
    measured zero replaces the modelled 60 rev/s at once, and the model returns when they agree."""
    f = ActuatorInputFilter(InputConfig())
    _, vals = _run(f, 3.0, 0.0, (0.0, 0.0, 60.0, 60.0, 0.0), measured=lambda t: (0.0, 0.0, 0.0) if t < 1.0
                   else (55.0, 55.0, 0.0))
    n1 = [v[2] for v in vals]
    assert max(n1[2:20]) < 1.0  # follows the measured 0, not the model's spin-up
    assert abs(n1[-1] - 55.0) < 6.0  # the motor runs later: measured and modelled agree again


def test_ekf_predicts_with_achieved_values() -> None:
    """Commands say 60 rev/s for 3 s, the ESCs report not armed (neutral): the prediction must
    not accelerate the boat (the issue measured 84 deg heading error on the emulated hardware)."""
    init = VesselState(stamp_s=0.0, north_m=0, east_m=0, heading_rad=0, u_mps=0, v_mps=0, r_radps=0)
    ekf = ModelAidedEKF(initial=init)
    t = 0.0
    while t < 3.0:
        ekf.on_command(ThrustCommand(stamp_s=t, alpha1_rad=0.3, alpha2_rad=0.3, n1_rps=60.0, n2_rps=60.0))
        ekf.on_command(ActuatorState(stamp_s=t, alpha1_rad=0.3, alpha2_rad=0.3, n1_rps=0.0, n2_rps=0.0,
                                     nt_rps=0.0, escs_armed=False))
        t += DT
    e = ekf.estimate(3.0)
    assert abs(e.u_mps) < 0.01 and abs(e.r_radps) < 0.01
    ref = ModelAidedEKF(initial=init)  # the same set-points without achieved values
    for k in range(60):
        ref.on_command(ThrustCommand(stamp_s=k * DT, alpha1_rad=0.3, alpha2_rad=0.3, n1_rps=60.0, n2_rps=60.0))
    assert ref.estimate(3.0).u_mps > 0.3  # what the commands alone would have predicted
