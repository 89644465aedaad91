"""Properties of hull B (tests/physics/hull_b.py, the catamaran; issue 47): physics that must hold,
its conventions (matched to hull6dof's), its environment, and the identification record it writes."""

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from hull_b import (  # noqa: E402
    CatamaranEnvironment, CatamaranHull, CatamaranParameters, bollard_pull, random_steps, record, reverse_thrust_ratio,
    steady_speed, turning_circle,
)

DEG = math.pi / 180


def test_kinetic_energy_decreases_with_thrusters_off():
    """Calm water, no current, no wind: moving, drifting and turning, the kinetic energy (rigid body
    plus added mass) falls in every 0.1 s; with heave, roll and pitch also excited, the total energy
    (plus the column hydrostatics' potential) falls in every 0.25 s."""
    h = CatamaranHull()
    h.set_velocity(1.2, 0.25, 0.6)
    ke = [h.kinetic_energy()]
    for _ in range(100):
        h.advance(0.1)
        ke.append(h.kinetic_energy())
    ke = np.array(ke)
    assert np.all(np.diff(ke) < 0.0), f"kinetic energy grew: max step {np.max(np.diff(ke)):.3g} J"
    assert ke[-1] < 0.05 * ke[0]

    h = CatamaranHull()
    h.set_velocity(1.0, 0.2, -0.5)
    h.x[8], h.x[9], h.x[10] = 0.05, 0.4, 0.1  # heave, roll and pitch rates
    h.x[2], h.x[3], h.x[4] = 0.01, 8 * DEG, -2 * DEG
    e = [h.kinetic_energy() + h.potential_energy()]
    for _ in range(60):
        h.advance(0.25)
        e.append(h.kinetic_energy() + h.potential_energy())
    e = np.array(e)
    assert np.all(np.diff(e) < 0.0), "total energy grew in some 0.25 s with the thrusters off"
    assert e[-1] < 0.05 * e[0]


def test_potential_energy_is_the_restoring_forces_potential():
    """The column hydrostatics are conservative: the work of the restoring roll moment over a small
    heel equals minus the potential's change (so the energy test above means what it says)."""
    h = CatamaranHull()
    phi = 5 * DEG
    h.x[3] = phi
    e1 = h.potential_energy()
    k = h.k_roll
    assert e1 == pytest.approx(0.5 * k * phi * phi, rel=0.05)  # rho g V GM_T phi^2 / 2
    assert 20.0 < k < 80.0  # N m/rad: a catamaran's roll stiffness (hull6dof's ~4.5)


def test_mass_matrix_and_the_figures_the_docstring_states():
    h = CatamaranHull()
    assert np.allclose(h.M, h.M.T) and np.allclose(h.M_A, h.M_A.T)
    assert np.linalg.eigvalsh(h.M_A).min() > 0.0 and np.linalg.eigvalsh(h.M).min() > 0.0
    np.testing.assert_allclose(np.diag(h.M)[[0, 1, 2, 5]], [14.33, 31.5, 23.4, 2.56], rtol=0.01)
    assert h.draft_m == pytest.approx(0.078, abs=0.001)
    assert h.gm_transverse_m == pytest.approx(0.37, abs=0.01)
    # the catamaran's roll: stiff, and large roll added mass from the demi-hulls' heave (a33 y^2)
    assert h.M_A[3, 3] > 0.3 * h.M_RB[3, 3]


def test_differential_thrust_yaws_away_from_the_faster_propeller():
    """Starboard propeller faster: the bow turns to port (r < 0); the demi-hulls' spacing gives the
    pods a 0.16 m arm (hull6dof's: 0.07 m)."""
    h = CatamaranHull()
    h.command(0.0, 0.0, 60.0, 30.0, 0.0)
    h.advance(8.0)
    assert h.nu[5] < -0.05


def test_symmetric_input_gives_no_yaw_or_sway():
    h = CatamaranHull()
    h.command(0.0, 0.0, 60.0, 60.0, 0.0)  # equal speeds, zero angles, no bow thrust
    h.advance(20.0)
    N, E, psi, u, v, r = h.x3
    assert u > 0.5
    assert max(abs(E), abs(psi), abs(v), abs(r), abs(h.eta[3]), abs(h.nu[3])) < 1e-9


def test_mirrored_input_mirrors_the_motion():
    a, b = CatamaranHull(), CatamaranHull()
    a.command(0.3, 0.2, 60.0, 40.0, 30.0)
    b.command(-0.2, -0.3, 40.0, 60.0, -30.0)  # the port/starboard mirror image
    a.advance(6.0)
    b.advance(6.0)
    xa, xb = np.array(a.x3), np.array(b.x3)
    np.testing.assert_allclose(xa[[0, 3]], xb[[0, 3]], atol=1e-9)
    np.testing.assert_allclose(xa[[1, 2, 4, 5]], -xb[[1, 2, 4, 5]], atol=1e-9)
    assert abs(a.eta[3] + b.eta[3]) < 1e-9 and abs(a.eta[3]) > 1e-5


def test_steady_speed_at_fixed_propeller_speed():
    """Both propellers at 50 rev/s (half of 100): steady at ~1.0 m/s (0.3-1.5 m/s is plausible for a
    1 m boat); 25 rev/s ~0.5 m/s; steady means the speed changed by < 0.5 % over the last 10 s."""
    figures = {}
    for n in (25.0, 50.0):
        h = CatamaranHull()
        h.command(0.0, 0.0, n, n, 0.0)
        h.advance(30.0)
        u30 = h.nu[0]
        h.advance(10.0)
        figures[n] = h.nu[0]
        assert abs(h.nu[0] - u30) < 0.005 * h.nu[0]
    assert 0.3 < figures[50.0] < 1.5
    assert 0.85 < figures[50.0] < 1.15  # the figure the docstring states
    assert 0.35 < figures[25.0] < 0.65
    assert steady_speed(50.0, 40.0) == pytest.approx(figures[50.0], rel=1e-9)


def test_astern_is_weaker_and_runs_straight():
    ahead, astern = CatamaranHull(), CatamaranHull()
    ahead.command(0.0, 0.0, 50.0, 50.0, 0.0)
    astern.command(0.0, 0.0, -50.0, -50.0, 0.0)
    ahead.advance(20.0)
    astern.advance(20.0)
    assert astern.nu[0] < 0.0 and abs(astern.nu[0]) < 0.9 * ahead.nu[0]
    assert abs(astern.nu[5]) < 1e-9 and abs(astern.x3[1]) < 1e-9


def test_a_bollard_pull_reads_the_astern_factor():
    """At rest the propellers work at J = 0, where the astern curve is the ahead one times astern_factor:
    the lab's measurement (`--reverse-thrust-ratio` of the lab loop, bench hull_b) finds it, though the
    motors turn faster astern at the same command."""
    ahead, n_ahead = bollard_pull(50.0)
    astern, n_astern = bollard_pull(-50.0)
    assert ahead > 0 > astern and abs(n_astern) > n_ahead
    assert reverse_thrust_ratio() == pytest.approx(CatamaranParameters().astern_factor, rel=1e-6)

def test_positive_alpha_yaws_the_bow_to_port():
    """lotsen's convention (docs/model.md "Thruster forces"): alpha > 0 turns the azimuths' thrust to
    starboard; aft of the centre that pushes the stern to starboard, so the bow turns to PORT (r < 0)
    and the boat goes round to port, as hull6dof's test_turning_to_port_for_positive_alpha checks."""
    h = CatamaranHull()
    h.command(20 * DEG, 20 * DEG, 50.0, 50.0, 0.0)
    h.advance(10.0)
    assert h.nu[5] < -0.2 and h.x3[1] < 0.0
    m = CatamaranHull()
    m.command(-20 * DEG, -20 * DEG, 50.0, 50.0, 0.0)
    m.advance(10.0)
    assert m.nu[5] > 0.2


def test_turning_circle_is_wider_than_hull6dofs():
    """n = 50, alpha = 20 deg: a steady circle of ~4.5 m (hull6dof: 2.1 m, lotsen's defaults 2.2 m):
    the spaced demi-hulls damp yaw (each sees u -+ y_h r) and resist sway with two keels."""
    c = turning_circle(50.0, 20.0, 60.0)
    assert c["yaw_rate_radps"] < 0.0
    assert 3.5 < c["diameter_m"] < 6.0
    assert c["kinematic_diameter_m"] == pytest.approx(c["diameter_m"], rel=0.05)
    assert 0.6 < c["speed_mps"] < 1.0


def test_bow_thruster_yaws_as_hull6dofs_does():
    from hull6dof import Hull6DOF

    rates = []
    for hull in (CatamaranHull(), Hull6DOF()):
        hull.command(0.0, 0.0, 0.0, 0.0, 60.0)
        hull.advance(3.0)
        rates.append(hull.nu[5])
    assert rates[0] > 0.05 and rates[1] > 0.05  # nt > 0 pushes the bow to starboard in both


def test_bow_thruster_fades_then_recovers_with_speed():
    """The tunnel thruster's yaw moment ahead at speed: weaker at ~0.5 m/s than at rest (the dip of
    the jet-speed ratio law), and the law recovers towards 1 beyond it."""
    p = CatamaranParameters()
    rest = CatamaranHull()
    rest.x[16] = 2 * math.pi * 60.0
    s_rest = rest._loads(rest.x, (0, 0, 0, 0, 60.0))[0]
    moving = CatamaranHull()
    moving.x[16] = 2 * math.pi * 60.0
    moving.set_velocity(0.5, 0.0, 0.0)
    s_mov = moving._loads(moving.x, (0, 0, 0, 0, 60.0))[0]
    assert 0.3 < s_mov[5] / s_rest[5] < 0.8
    d, s0 = p.bow_fade_depth, p.bow_fade_ratio
    f = [1 - 2 * d * x * x / (1 + x ** 4) for x in np.array([0.0, 1.0, 4.0])]
    assert f[1] == pytest.approx(1 - d) and f[2] > 0.9 and f[0] == 1.0
    assert s0 > 0


def test_a_bow_thruster_just_spinning_up_at_speed_stays_finite():
    """The fade law at a jet speed near zero (the motor's first steps while the boat is moving):
    the jet-speed ratio is huge, the law must give ~1 and no overflow (found by a 600-s record)."""
    h = CatamaranHull()
    h.set_velocity(1.0, 0.0, 0.0)
    h.x[16] = 1e-150
    tau = h._loads(h.x, (0, 0, 0, 0, 0.0))[0]
    assert np.all(np.isfinite(tau))
    h.command(0.0, 0.0, 40.0, 40.0, 0.0)
    for nt in (1e-3, -20.0, 0.0, 30.0):
        h.command(0.0, 0.0, 40.0, 40.0, nt)
        h.advance(0.5)
    assert np.all(np.isfinite(h.x))


def test_dc_motor_droops_under_load_and_spins_up_at_a_current_limited_rate():
    h = CatamaranHull()
    h.command(0.0, 0.0, 90.0, 90.0, 0.0)
    h.advance(0.1)
    n01 = h.actuators[2]
    h.advance(10.0)
    n_ss = h.actuators[2]
    assert 80.0 < n_ss < 90.0  # the governor's droop under the propeller's torque
    # current-limited: no faster than the no-load ramp, after the latency
    assert n01 <= h.motor_ramp_rps2 * (0.1 - h.p.latency_s) + 1e-6
    assert n01 > 0.5 * h.motor_ramp_rps2 * (0.1 - h.p.latency_s)


def test_roll_returns_to_upright():
    for heel in (10 * DEG, -20 * DEG):
        h = CatamaranHull()
        h.x[3] = heel
        h.advance(0.3)
        assert abs(h.eta[3]) < abs(heel)
        h.advance(6.0)
        assert abs(h.eta[3]) < 0.02 * abs(heel)
        assert abs(h.nu[3]) < 0.01
        assert abs(h.eta[2]) < 1e-3  # back at its waterline too


def test_current_drifts_the_hull_with_it():
    env = CatamaranEnvironment(current_mps=0.1, current_to_deg=60.0)
    h = CatamaranHull(environment=env)
    h.advance(20.0)
    (vn, ve, _), _ = h.measure()
    slip20 = math.hypot(vn - 0.05, ve - 0.1 * math.sin(60 * DEG))
    h.advance(40.0)
    (vn, ve, _), _ = h.measure()
    slip60 = math.hypot(vn - 0.05, ve - 0.1 * math.sin(60 * DEG))
    assert slip60 < 0.6 * slip20  # the water's drag takes it up to the current's velocity
    assert math.hypot(vn, ve) == pytest.approx(0.1, rel=0.1)
    assert math.degrees(math.atan2(ve, vn)) == pytest.approx(60.0, abs=3.0)
    N, E = h.x3[:2]
    assert math.degrees(math.atan2(E, N)) == pytest.approx(60.0, abs=5.0)
    assert 4.0 < math.hypot(N, E) < 6.0


def test_wind_pushes_the_hull_downwind():
    h = CatamaranHull(environment=CatamaranEnvironment(wind_mps=6.0, wind_from_deg=270.0))
    h.advance(30.0)
    assert h.x3[1] > 0.5  # from the west: drifts east
    assert h.wind_now == pytest.approx((6.0, 270.0))


def test_deterministic_with_a_seed():
    def run(seed):
        env = CatamaranEnvironment(current_mps=0.08, current_to_deg=30.0, wind_mps=4.0, wind_from_deg=250.0,
                                   gust_fraction=0.2, wind_wander_deg=15.0, seed=seed)
        h = CatamaranHull(environment=env)
        h.command(0.1, 0.1, 40.0, 40.0, 10.0)
        h.advance(15.0)
        return np.array(h.x)

    a, b, c = run(3), run(3), run(4)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_gusts_have_the_asked_strength():
    env = CatamaranEnvironment(wind_mps=4.0, gust_fraction=0.2, wind_wander_deg=15.0, seed=1)
    h = CatamaranHull(environment=env)
    ts = np.arange(0.0, 1800.0, 0.5)
    speeds = np.array([h._gust(t) for t in ts])
    assert np.std(speeds) == pytest.approx(0.8, rel=0.35)


def test_waves_are_refused():
    with pytest.raises(ValueError, match="no waves"):
        CatamaranHull(environment=CatamaranEnvironment(wave_hs_m=0.03))


def test_step_with_input_and_whole_steps_only():
    a, b = CatamaranHull(), CatamaranHull()
    a.step((0.1, 0.1, 30.0, 30.0, 0.0), 0.5)
    b.command(0.1, 0.1, 30.0, 30.0, 0.0)
    b.advance(0.5)
    assert np.array_equal(a.x, b.x)
    with pytest.raises(ValueError):
        a.advance(0.0123)


def test_independent_of_lotsens_model_and_of_hull6dof():
    """hull_b.py imports numpy and the standard library only at module level (lotsen's record format
    inside record(), as hull6dof does), and nothing of hull6dof."""
    tree = ast.parse((HERE / "hull_b.py").read_text())
    top = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            top.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            top.add((node.module or "").split(".")[0])
    assert top <= {"__future__", "math", "dataclasses", "typing", "numpy"}, top
    every = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    every |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert every <= {"__future__", "math", "dataclasses", "typing", "numpy", "lotsen.sysid.data", "argparse"}, every
    code = ("import sys; sys.path.insert(0, %r); import hull_b; h = hull_b.CatamaranHull(); h.advance(0.1); "
            "print(sorted(m for m in sys.modules if m.startswith('lotsen') or m.startswith('hull6dof')))" % str(HERE))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_record_is_a_lake_record():
    rec = record(duration_s=20.0, seed=2)
    r = rec.record
    assert r.input_kind == "mean"
    has_u = np.isfinite(r.inputs[:, 0])
    has_y = np.isfinite(r.outputs[:, 0])
    np.testing.assert_allclose(np.diff(r.t[has_u]), 0.02, atol=1e-9)  # 50 Hz inputs
    np.testing.assert_allclose(np.diff(r.t[has_y]), 0.125, atol=1e-9)  # 8 Hz fixes
    err = r.outputs[has_y, 0] - rec.truth_x[:, 0]
    assert 0.005 < np.std(err) < 0.02
    assert np.nanmax(np.abs(r.inputs[:, 2])) > 20.0  # achieved propeller speeds, rev/s
    assert random_steps(2, 20.0)(5.0) == random_steps(2, 20.0)(5.0)


# The long checks (lotsen identify on a 300-s record, the figure eight flown by lotsen's stack) are
# bench/bench_hull_b.py's rows, out of make test.
