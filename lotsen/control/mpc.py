"""Path-following MPC on the actuators (seed section 3.5, eq. 43-44), LTV / real-time iteration, OSQP.

Model and linearisation
-----------------------
The prediction model is the full 6-state vessel model x = [N, E, psi, u, v, r] of `lotsen.model`,
including the thruster housing force, linearised at every step along the *nominal* trajectory
(the previous solution shifted by one step, its first state replaced by the measured state):

    x_{k+1} = f_d(xb_k, wb_k) + Ad_k (x_k - xb_k) + Bd_k (w_k - wb_k)
    Ad_k = I + dt A_k + dt^2/2 A_k^2,   Bd_k = dt B_k + dt^2/2 A_k B_k,   (A_k, B_k) = jacobians(xb_k, ub_k)

f_d is one RK4 step of the nonlinear model (with the estimated disturbance force, below). One QP
per step (real-time iteration): the nominal of the next step is this step's solution. With
`qp_iterations = 2` a second QP, re-linearised along the first one's solution, runs while the first
moved an input by more than `reiterate_dw` from its nominal (a transient; in steady tracking on ~1 %
of the steps). The cold-start nominal runs the azimuths at the trim thrust of the reference speed:
at q = 0 the angles would have no authority in the linearisation (the side force T sin(alpha) is
bilinear).

Inputs (decision variables, scaled): w = [alpha_1, alpha_2, q_1, q_2, q_t], q = n|n| / n_max^2.
The thrust is linear in q (T = mu n_max^2 q), so the bow thruster keeps its authority at n = 0
where d(n|n|)/dn = 0 would hide it from a linearisation in n; the housing force's kappa*n term is
the only remaining nonlinearity in q (its derivative uses |n| >= n_floor). Angles are the servo
set-points themselves, so the angle limit and the servo slew rate are exact constraints.
Commands: n = sign(q) n_max sqrt|q|, then clipped to the ESC ramp (`allocation.rate_limit`).

Decision vector (OSQP variable z), horizon N, n_x = 6, n_w = 5:

    z = [x_0, x_1, ..., x_N, w_0, ..., w_{N-1}, t_0, ..., t_{N-1}]        length 6 (N + 1) + 5 N + 3 N
    positions are relative to the measured position (N0, E0) of the current step; t_k = the
    reversal slacks of the three propellers (below).

QP (seed eq. 43-44):

    min  sum_{k=1..N} rho_k ||C_k x_k + d_k||^2_Q  +  sum_k ||w_k - w_ref,k||^2_R  +  sum_k ||w_k - w_{k-1}||^2_S
         + sum_k lambda' t_k + mu ||t_k||^2                                (reversal guard)
    s.t. x_0 = x_measured
         x_{k+1} - Ad_k x_k - Bd_k u_k = c_k                               (linearised dynamics)
         u_k = beta_k w_k + (1 - beta_k) w_{k-1} per input                 (servo and ESC lags; w_{-1} =
                                                                             servo angles, achieved thrust)
         t_k >= 0, t_k + sigma q_k >= -q_band                              (per propeller)
         w_min <= w_k <= w_max                                             (44: input bounds)
         -dw_max <= w_k - w_{k-1} <= dw_max,  w_{-1} = previous command    (44: rate bounds)

    rows of C_k x_k + d_k (reference point P_k = path at the predicted progress s_k, heading psi_k):
      cross-track error   -sin(psi_k)(N - P_N) + cos(psi_k)(E - P_E)
      course error        psi + v / U_k - psi_k        (heading plus drift angle: crabbing in a current
                                                         is not penalised, only where the vessel goes)
      heading error       psi - psi_k - crab_k         (small weight; crab_k = 0 except in the crab
                                                         alignment, `MPCConfig.align_min_crab_deg`)
      speed error         u - v_ref,k
      yaw-rate error      r - v_ref,k kappa_k          (curvature feedforward)
    rho_N = terminal_factor, else 1. w_ref = [0, 0, q_trim(v_ref), q_trim(v_ref), 0].

The predicted progress s_k is the projection of the nominal positions onto the path (two
vectorised Newton steps from the previous prediction), so the reference moves with the boat.

Sparse matrices are set up once. P (upper triangle) and A have a fixed sparsity pattern: the
structural non-zeros of C^T Q C per stage, and of Ad (23 of 36 entries: the kinematics leave
Ad[3:6, 0:3] zero) and Bd (dense 6x5) per stage, found once from random operating points. At every
step one numba-compiled function (`_assemble`) overwrites their data arrays and q, l, u in place
through precomputed index maps, followed by one `update(Px=, Ax=, q=, l=, u=)`. OSQP is
warm-started from its previous primal-dual solution (measured: fewer iterations than a primal-only
warm start with the shifted plan, `MPCConfig.warm_start_shifted`); Ruiz scaling is off
(`scaling=0`) because re-scaling on every matrix update cost more than it saved here.

Propeller reversals: a reversal is a sign change of a propeller's speed. Each propeller has a
direction state sigma (+-1, 0 = none yet) that follows its modelled achieved speed with a
hysteresis (+-reversal_hysteresis_rps). In every stage the soft sign constraint
sigma q_k >= -q_band (speeds within +-reversal_band_rps are free either way) has the slack t_k,
priced per newton of thrust against the present direction (reversal_cost_*_per_N, converted with
the model's thrust per unit q); thrust in the present direction carries no price. For
reversal_dwell_s after a change of direction the price is reversal_dwell_factor times higher, so a
propeller does not chatter back. sigma lives in fixed entries of A, rewritten when it changes.
ESC lag: the thrust over a step is the
average of a first-order response (motor time constant T_m) from the previous set-point to the new
one, beta = 1 - T_m/dt (1 - exp(-dt/T_m)); stage 0 starts from the modelled achieved speed (the
simulator's actuator model run on the commands sent). The previous set-point stands for the
achieved speed at the start of later stages (an approximation: 71 % reached after one step).
Servo slew: the angle over a step is the average of a ramp at the rate limit from the
previous set-point, beta_k = 1 - |dalpha_k| / (2 rate dt) with dalpha_k from the nominal plan (exact
for the simulator's servo at the nominal; the rate bound makes every set-point reachable in a step).

The estimator's water current (`VesselState.current_ne_mps`) enters the RK4 term, the Jacobians
and the observer's prediction.

Offset-free action: a disturbance observer estimates a constant body-frame force (current, wind)
from the one-step prediction error of the model (with the ESC lag's effective thrust) and adds it to f_d.

Safety: a solver status other than solved, a time-limit hit (OSQP `time_limit`, set on the real-time stack)
or a non-finite solution never reaches the actuators. The controller then plays the previous
feasible plan, shifted, for at most `max_fallback_steps`, then commands neutral (safe stop);
`ControllerStatus.failures` counts the failures and `status` says which mode is active.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, NamedTuple

import numpy as np
import osqp
import scipy.sparse as sp

from lotsen.control.allocation import rate_limit
from lotsen.control.base import PathReference, SeaLevel, SeaLevelConfig, make_status, state_is_finite, wrap_angle
from lotsen.messages import ControllerStatus, ThrustCommand, VesselState
from lotsen.model._jit import njit
from lotsen.model.dynamics import VesselModel, _jacobians_current, rk4_step, surge_drag
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.model.actuators import advance_motors

NX, NW, NY = 6, 5, 5
NREV = 3  # propellers with a direction: azimuth 1, azimuth 2, bow
#: the solve's wall-clock budget on the real-time stack: a fifth of the 10 Hz period (a solve takes
#: ~1 ms here, ~4 ms on a Pi 4); a late solve falls back like a failed one
REALTIME_SOLVE_LIMIT_S = 0.02
_SOLVED = (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)


@dataclass(frozen=True)
class MPCConfig:
    """Horizon, weights and solver settings of the path-following MPC."""

    horizon: int = 20  # N steps
    dt_s: float = 0.1  # prediction step = control period
    # per m^2. 120 (was 60): on the lake boat in current and wind on the EKF the exact model tracks
    # 0.68 cm instead of 0.72 and a model 25 % off 1.45x that instead of 1.61x (seeds 0-2; 1.60x
    # instead of 1.70x over seeds 0-8); it comes with the dearer azimuth crossing below, without
    # which a wrong model reverses the propellers 0.13-0.19 times per second
    q_cross_track: float = 120.0
    # Far from the path the cross-track weight falls to q_cross_track_far: q = far + (near - far) /
    # (1 + (e / cross_track_far_m)^2) with e the measured cross-track error, set each step. A stiff
    # weight 1 m off the path drives a boat starting from rest straight at the path faster than a
    # 2-s horizon can see it stop: from 1 m off it overshot by 0.8 m at 120 (none at 60).
    q_cross_track_far: float = 60.0
    cross_track_far_m: float = 0.1  # 0: no schedule (q_cross_track everywhere)
    q_course: float = 6.0  # per rad^2
    q_heading: float = 0.3  # per rad^2
    # per (m/s)^2. 1 cm of cross-track weighs as much as 5 cm/s of speed error: in a turn at the
    # limit of the yaw authority the boat gives up a little speed rather than the path (at 20 a
    # model with its masses 25 % off lost the turn of the figure eight by 10-20 cm)
    q_speed: float = 5.0
    # per (rad/s)^2. 4 (was 1): the yaw rate follows the path's curvature (r_ref = v_ref kappa) more
    # firmly, so a model that misjudges the yaw inertia or authority does not swing the heading. On
    # the lake boat in current and wind on the EKF (seeds 0-8): a model 25 % off 0.86 cm instead of
    # 1.04 (1.28x the exact model instead of 1.52x; worst seed 1.66x instead of 2.67x), the exact
    # model 0.67 instead of 0.69; 2.5 and 8 both did worse at 25 % (1.39x / 1.29x)
    q_yaw_rate: float = 4.0
    terminal_factor: float = 3.0
    r_alpha: float = 0.05  # per rad^2
    # Input costs in newtons (converted with the model's thrust per unit q, mu n_max^2): the same
    # physical price whatever the model says a unit of q makes. Small, so that the deviations from
    # path, heading and speed dominate (seed eq. 43) and the inputs are used within their limits.
    r_thrust_azimuth_per_N2: float = 4e-4  # per N^2 of azimuth thrust away from the trim thrust
    r_thrust_bow_per_N2: float = 0.01  # per N^2 of bow thrust
    # Rate penalties. On the EKF estimate 0.3 / 0.5 let the noise through to the servos (rms step
    # change 5 deg per 0.1 s on the figure eight); s_alpha = 10 cuts that to 1.2 deg at no cost in
    # tracking. A thrust rate penalty above ~1 makes the MPC too slow against current and wind
    # (harbour approach, 0.1 m/s + 3 m/s on the EKF: cross-track RMS 2.6 cm at 1, 6.6 cm at 5,
    # 8.7 cm at 20), so s_thrust stays small and the ESC's own time constant filters the rest.
    s_alpha: float = 10.0  # rate penalty per rad^2 (per step)
    s_thrust: float = 1.0  # rate penalty per q^2 (per step)
    # In a sea the rate penalties grow as the wave-frequency motion the estimator separates out
    # (`VesselState.wave_motion`) grows beyond its dead band (the sea level f, 0..1: `SeaLevel`): the
    # angles' up to `wave_rate_scale` times, the propellers' up to `wave_thrust_rate_scale`, the
    # reversal guard's crossing price up to `wave_reversal_scale`. What the
    # wave filter leaves of the waves in the estimate (at 1 m/s in quartering and following seas the
    # encounter frequency falls to 0.3-0.5 Hz, where it passes 80 % of the wave yaw rate) is then not
    # chased (issue 46; docs/control.md "Waves"). Flat water: unchanged. The three are apart because
    # they act apart: the angles' alone dear, the MPC steers by reversing the propellers instead.
    wave_rate_scale: float = 3.0
    wave_thrust_rate_scale: float = 3.0
    wave_reversal_scale: float = 3.0
    sea: SeaLevelConfig = field(default_factory=SeaLevelConfig)  # what the sea level is read from
    # Above `wave_speed_ref_mps` the angles' sea scale grows with the square of the azimuths' trim thrust
    # and the crossing price with the thrust, k = q_trim(u) / q_trim(wave_speed_ref_mps) >= 1 (2.8 at
    # 1 m/s): what the hull feels of an angle change is the side force T d(alpha), so a penalty per
    # rad^2 is k^2 cheaper per newton at speed. Without it the azimuths chased the waves at 1 m/s (3.1-4.2
    # x calm travel, 2.5-5.1 x reversals) and a scale high enough there (30 / 10) cost 0.5 m/s its
    # tracking and two missions (docs/control.md "Waves at 1 m/s"). inf: off.
    wave_speed_ref_mps: float = 0.5
    wave_speed_angle_exponent: float = 2.0
    wave_speed_reversal_exponent: float = 1.0
    # In a sea, uneven azimuth thrust and the bow thruster get dearer (issue 46, docs/control.md
    # "Waves"). The quadratic input cost is no power model (P ~ |n|^3 ~ |T|^1.5): at the calm weights
    # the MPC bought millimetres of tracking in a sea with yaw couples (one azimuth astern against the
    # other) and the bow thruster near its limit, 1.5-5.8x calm energy where the sea's mean drift alone
    # asks 1.04-1.26x. With the sea level f (`sea`): the azimuths' thrust cost is
    # r_thrust_azimuth_per_N2 (1 + (wave_azimuth_split_scale - 1) f) about a reference that moves by f
    # from the trim thrust to the nominal plan's mean of the two azimuths, so it prices their
    # difference (the couple, an uneven split) and not the thrust the sea's added resistance needs
    # (about the trim, a dear thrust cost slowed the boat down, in Hs 10 cm to a time-out); the bow
    # thruster's cost grows alike to wave_bow_cost_scale. 1: off.
    wave_azimuth_split_scale: float = 10.0
    wave_bow_cost_scale: float = 10.0
    # In a sea (sea level > 0) an azimuth astern longer than this gets ahead as its direction again,
    # as `azimuth_astern_hold_s` does (which stays off in calm water): the crossing price scaled with
    # the sea made an azimuth sent astern at the start stay astern for 40-60 % of a mission while the
    # other carried the thrust (issue 46). 60 -> 30 s (2026-11-30, bench waves' 1.0 m/s figure eight in
    # Hs 3 cm, seeds 0-2): 6-DOF hull energy 7971 -> 7855 J (1.31 -> 1.29 x calm), tracking 6.14 -> 6.12 cm,
    # reversals 0.147 -> 0.161 per s; lake boat 11191 -> 10813 J, tracking unchanged. 10 s made 2-3 x calm
    # reversals on the 6-DOF hull (docs/control.md "Waves"). inf: off.
    wave_azimuth_astern_hold_s: float = 30.0
    min_speed_ref_mps: float = 0.15  # leave a node whose planned speed is 0
    min_speed_course_mps: float = 0.3  # U_k floor in the drift-angle term v / U_k
    # Crab alignment, the start procedure in a cross current: a boat that has made less than
    # `align_stall_fraction` of the reference speed along the path for `align_stall_s`, where the
    # estimated current asks for a crab angle (`crab_angle`: the heading of the water-relative velocity
    # that makes the reference speed along the path) above `align_min_crab_deg`, first turns to it:
    # until its heading is within `align_done_deg` of the path heading plus the crab angle, for at most
    # `align_max_s`, the heading row's reference carries the crab angle (up to `max_crab_deg`) and its
    # weight is `align_q_heading` (the course row's). ControllerStatus.status reads "aligning".
    # The trap it breaks (issue 46, bench failsafes' current_toward_geofence in Hs 6 cm, seed 1): started
    # at rest in a 0.2-0.28 m/s beam current with 0.17 m/s planned, the boat backed onto the path and
    # held it for ~100 s, heading 5-20 deg downstream, the bow thruster saturated and the azimuths as a
    # couple making a pure side force; the turn into the current that would free it costs cross-track
    # for longer than the 2-s horizon sees the gain. With the alignment it is under way (8 m north) after
    # 18 s, not 105 (seeds 0-6: 10-23 s, every breach caught); the crab reference in every step, or the
    # course row faded below min_speed_course_mps, also freed it but change every mission in a current.
    # The same trap mid-route: the harbour approach in a 0.3 m/s current (EKF, seeds 0-2) was swept 5 m
    # off its southbound leg at 82-106 s, and completes with it; a fraction of 0.5 (0.3 tried first) caught
    # that stall 40 s sooner (no `no_progress`). Calm starts and a boat under way never meet the
    # condition (docs/control.md "Crab alignment"). inf: off.
    align_min_crab_deg: float = 20.0
    align_stall_s: float = 3.0
    align_stall_fraction: float = 0.5
    align_done_deg: float = 10.0
    align_q_heading: float = 6.0
    align_max_s: float = 20.0
    max_crab_deg: float = 60.0
    # only on the path: a boat farther off is joining it, and its speed along the path says nothing (lotsen
    # run, the harbour approach in 0.3 m/s current from 17 m off: it aligned while heading for the path)
    align_max_cross_track_m: float = 1.0
    # where stage k's reference lies on the path: "predicted" = the projection of the nominal (shifted
    # previous) prediction's position k (path following: the reference waits for a slow boat);
    # "time" = s0 + k U dt from the measured progress (trajectory tracking along the path; the OCP
    # the do-mpc peer in bench_control solves, so its cost gap measures the one QP per step only)
    progress_reference: str = "predicted"
    # QPs per step at most, each re-linearised along the previous one's solution (RTI: 1). A further
    # QP runs only while the last one moved an input by more than `reiterate_dw` (scaled units: rad,
    # q) from the nominal it was linearised on: in a transient, not in steady tracking, where one QP
    # per step has converged along the trajectory (the median step stays that of one QP). 2 halves
    # the do-mpc tracking gap of a start 30 cm off the path (docs/control.md), but in the fault suite's
    # 0.3 m/s beam current it settled bow-downstream at 0.1 m/s where one QP turns into the current
    # and follows, so the default stays one (not measured again with the crab alignment, align_*).
    qp_iterations: int = 1
    reiterate_dw: float = 0.2
    n_floor_rps: float = 5.0  # |n| floor in d(kappa n)/dq
    disturbance_gain: float = 0.15  # observer gain per step (0 switches it off)
    disturbance_max_N: float = 5.0
    max_fallback_steps: int = 5  # play the previous plan this many steps, then neutral
    max_iter: int = 400  # 200 ran out on the first steps after a cold start with the reversal slacks
    # OSQP's wall-clock time limit; 0: none, the solve bounded by max_iter alone, so a run on
    # simulated time gives the same answer on any machine. The real-time stack sets
    # REALTIME_SOLVE_LIMIT_S (lotsen.stack.parts.add_supervisor).
    time_limit_s: float = 0.0
    eps: float = 1e-4
    check_termination: int = 5
    scaling: int = 0  # OSQP Ruiz equilibration iterations
    rho: float = 0.1  # OSQP's initial ADMM step (its default)
    adaptive_rho: bool = True
    adaptive_rho_interval: int = 0  # 0: OSQP's own choice
    warm_start_shifted: bool = False  # warm-start with the shifted plan (else OSQP's last solution)
    # Propeller reversals: a reversal is a sign change of a propeller's speed, guarded by a direction
    # state per propeller (sigma = +-1, set by the modelled achieved speed leaving +-reversal_hysteresis_rps;
    # 0 = no direction yet) and, in every stage of the horizon, the soft sign constraint
    # sigma q >= -q_band (commands within +-reversal_band_rps are free either way) whose slack costs
    # reversal_cost_*_per_N per newton of thrust against the present direction per stage. Thrust in
    # the present direction carries no such price. For reversal_dwell_s after a propeller changed
    # direction the crossing cost is reversal_dwell_factor times higher (no chattering back).
    # per N of astern (against sigma) thrust per stage (0 = off). 0.05 with q_cross_track 120: a 25 %
    # wrong model at <= 0.11 reversals/s (0.01: 0.14-0.19); 0.08 tracked as well, but in the fault
    # suite's sudden 0.2 m/s beam current (seed 0) the EKF then refused the GNSS 4 s after the
    # current set in (an estimator failsafe, not the geofence the case expects); 0.15 lost a turn
    # with a 10 % wrong model (1.5 cm). docs/control.md has the sweep.
    reversal_cost_azimuth_per_N: float = 0.05
    reversal_cost_bow_per_N: float = 0.2  # per N of bow thrust against its direction per stage (0 = off)
    reversal_band_rps: float = 3.0  # |n| below this is free in either direction
    # 4 s (was 2): with the stiffer path weight a default model on the lake boat sent azimuth 1
    # astern, ahead and astern again 3 s apart in one turn of the figure eight (7 reversals in 60 s)
    reversal_dwell_s: float = 4.0
    reversal_dwell_factor: float = 5.0
    # True: the azimuths' direction is fixed ahead (sigma = +1) instead of following the achieved
    # speed. False (default): in a turn at the limit of the yaw authority (bow thruster saturated)
    # one azimuth astern is the yaw couple that keeps the boat on the path.
    azimuth_ahead_only: bool = False
    # An azimuth's home is ahead: astern is for a manoeuvre. After this long astern its direction in
    # the sign constraint is ahead again (astern thrust priced, ahead free), so a propeller sent astern
    # in a start or a turn comes back. Without it the price of crossing back (0.05 N^-1 a stage against
    # a quadratic of 4e-4 N^-2) can keep an azimuth astern or idle for a whole mission while the other
    # does the work: the same thrust from one propeller draws ~40 % more power (P ~ n^3 ~ T^1.5). Found
    # on the survey (issue 48, 16 x 12 m, lake boat, EKF, 0.1 m/s + 3 m/s): azimuth 2 sent astern in the
    # first 5 s stayed there for all 240 s; with 10 s here both azimuths share and the motors draw
    # 14.1 kJ instead of 17.0 (-17 %), tracking unchanged (0.91 vs 0.94 cm). Off (inf) by default: the
    # return is a reversal, and on the figure eight (test_no_propeller_reversals_in_steady_tracking_on_the_ekf,
    # seed 0) it makes 6 in 60 s against the bar of 0.1/s (5 without); the control owner decides.
    azimuth_astern_hold_s: float = math.inf
    # An azimuth whose direction is astern but whose modelled achieved speed has stayed inside the
    # hysteresis (|n| < reversal_hysteresis_rps: idle, not pushing astern) for longer than this gets
    # ahead as its direction again (its direction state drops to none, sigma ahead), so ahead thrust is
    # free and astern priced. The astern trap it breaks: an azimuth sent astern once (in the first 2 s
    # of a start on the EKF, or in a turn) keeps sigma = astern while it idles at the band's edge
    # (+3 rev/s), ahead thrust then costs the crossing price at every stage, so the other azimuth
    # carries the thrust and the idle one is used astern as a free yaw couple, on straights as much as in
    # turns (lake boat, figure eight 0.5 m/s calm, seed 0: azimuth 2 astern-directed from t = 1.6 s
    # for 99 % of the mission, astern 63 % of the straights, 45 % of the turns, 66 rev/s against it).
    # Unlike `azimuth_astern_hold_s` it never flips a propeller that is pushing astern, only one idle.
    # Measured 2026-11-29 (bench_waves' cases: 0.08 m/s current, 4 m/s gusty wind, EKF, default model,
    # seeds 0-2; inf -> 2 s): figure eight 0.5 m/s lake boat 8001 -> 6685 J, 0.90 -> 0.93 cm; 6-DOF hull
    # 5769 -> 5097 J, 1.39 -> 1.38 cm; 1.0 m/s lake 9745 -> 8685 J, 1.18 -> 1.13 cm; 6-DOF 6945 -> 6094 J,
    # 3.31 -> 3.36 cm; Hs 6 cm 0.5 m/s lake 8856 -> 8990 J, 2.02 -> 1.93 cm; 6-DOF 10186 -> 9107 J,
    # 4.43 -> 4.37 cm. The cost: reversals 0.025 -> 0.065/s (lake, 0.5 m/s), 0.024 -> 0.064 (6-DOF),
    # 0.098 -> 0.148 (6-DOF 1.0 m/s); test_no_propeller_reversals_in_steady_tracking_on_the_ekf unchanged
    # (5 in 60 s, seeds 0-2 as before). A partial fix: an azimuth that keeps pushing astern is not idle
    # and stays astern-directed (lake 0.5 m/s seed 1: 33 % astern, 7754 J; 6-DOF hull 0.5 m/s: azimuth 1
    # astern 38-54 % on every seed); calm-water split pricing (tried, docs/control.md) or a hold
    # catches that, at a price. In flat water only (sea level 0): in a sea `wave_azimuth_astern_hold_s`
    # acts, and the idle release there cost the 6-DOF hull tracking in Hs 10 cm (figure eight, seeds
    # 0-2: 0.5 m/s 6.20 -> 7.33 cm, 1.0 m/s 13.78 -> 15.32 cm, every seed worse at 1.0 m/s) for -5 / +2 %
    # energy, and the lake boat +1.5-3.7 % energy in Hs 6-10 cm. inf: off.
    azimuth_idle_release_s: float = 2.0
    # The bow thruster idle (inside the hysteresis) this long with a direction has none again: free both
    # ways, as at the start. The trap it breaks is the azimuths' one above, in a sea: a start sent the bow
    # thruster one way, the leg needed the other, the crossing price (scaled with the sea) kept it idle,
    # and the azimuths made the yaw moment as a couple, one near full speed ahead, the other astern, for
    # 37-53 s of the 6-DOF hull's figure eight at 0.5 m/s in Hs 3 cm (seeds 0-2; 2 x calm water's energy;
    # the wave hold at 60 s ended it). Measured 2026-11-30 (bench waves, 3 seeds, x calm, inf -> 10 s):
    # 6-DOF 0.5 m/s Hs 3 cm energy 1.66 -> 1.22, tracking 1.41 -> 1.23, reversals 0.78 -> 0.88 (every
    # bar met); lake boat 0.5 m/s energy 0.92 / 1.15 / 1.77 -> 0.88 / 1.12 / 1.71 in Hs 3 / 6 / 10 cm;
    # the cost: lake 0.5 m/s Hs 6 / 10 cm tracking 2.26 / 3.69 -> 2.42 / 4.20 and reversals 0.78 / 0.91 ->
    # 0.89 / 1.26, 6-DOF 0.5 m/s Hs 6 cm tracking 2.71 -> 2.87, energy 1.74 -> 1.85; calm water and
    # 1.0 m/s unchanged. At 2 s the bow thruster turned over so often that the 6-DOF hull's reversals
    # went to 2.3 x calm (seed 0). inf: off.
    bow_idle_release_s: float = 10.0
    reversal_quadratic: float = 1e-3  # small quadratic on the slacks (strict convexity)
    reversal_hysteresis_rps: float = 5.0  # direction changes on achieved speeds beyond +-this (also the count)
    # ESC + motor lag in the prediction (first order, motor_time_constant_s of the limits): each
    # step's thrust is the step average of a first-order response from the previous set-point
    # (for stage 0: the modelled achieved speed) to the new one. False: set-points act at once.
    esc_in_prediction: bool = True
    # servo slew in the prediction: each step's angle is the step average of a ramp at the
    # servo's rate limit from the previous set-point (`_lag_weights`). False: set-points act at once.
    servo_in_prediction: bool = True
    # the prediction uses the estimator's water current (VesselState.current_ne_mps, earth
    # frame) in the RK4 affine term and the Jacobians (kinetics on the relative velocity); the
    # disturbance observer then learns only the remainder (wind). An estimate above max_current_mps
    # or not finite is ignored (zero current).
    current_in_prediction: bool = True
    max_current_mps: float = 1.0

    def __post_init__(self) -> None:
        if self.horizon < 2:
            raise ValueError(f"MPCConfig.horizon: {self.horizon} must be >= 2")
        if not 1 <= self.qp_iterations <= 5:
            raise ValueError(f"MPCConfig.qp_iterations: {self.qp_iterations} must be in 1..5")
        if not (math.isfinite(self.reiterate_dw) and self.reiterate_dw >= 0.0):
            raise ValueError(f"MPCConfig.reiterate_dw: {self.reiterate_dw} must be a finite number >= 0")
        if not self.align_min_crab_deg > 0.0:
            raise ValueError(f"MPCConfig.align_min_crab_deg: {self.align_min_crab_deg} must be > 0 (inf: off)")
        if not 0.0 < self.max_crab_deg < 90.0:
            raise ValueError(f"MPCConfig.max_crab_deg: {self.max_crab_deg} must be in (0, 90)")
        if not (self.align_stall_s > 0.0 and self.align_max_s > 0.0 and self.align_done_deg > 0.0
                and self.align_max_cross_track_m > 0.0):
            raise ValueError(f"MPCConfig.align_stall_s ({self.align_stall_s}), align_max_s ({self.align_max_s}), "
                             f"align_done_deg ({self.align_done_deg}) and align_max_cross_track_m "
                             f"({self.align_max_cross_track_m}) must be > 0")
        if not (0.0 <= self.align_stall_fraction < 1.0 and self.align_q_heading >= 0.0):
            raise ValueError(f"MPCConfig.align_stall_fraction: {self.align_stall_fraction} must be in [0, 1) and "
                             f"align_q_heading: {self.align_q_heading} >= 0")
        if not self.azimuth_idle_release_s > 0.0:
            raise ValueError(f"MPCConfig.azimuth_idle_release_s: {self.azimuth_idle_release_s} must be > 0 (inf: off)")
        if not self.bow_idle_release_s > 0.0:
            raise ValueError(f"MPCConfig.bow_idle_release_s: {self.bow_idle_release_s} must be > 0 (inf: off)")
        if not self.reversal_band_rps < self.reversal_hysteresis_rps:
            raise ValueError(f"MPCConfig.reversal_band_rps: {self.reversal_band_rps} must be below "
                             f"reversal_hysteresis_rps ({self.reversal_hysteresis_rps})")
        if self.progress_reference not in ("predicted", "time"):
            raise ValueError(f"MPCConfig.progress_reference: {self.progress_reference!r} is not predicted or time")
        if not self.dt_s > 0:
            raise ValueError(f"MPCConfig.dt_s: {self.dt_s} must be positive")
        for name in ("r_thrust_azimuth_per_N2", "r_thrust_bow_per_N2", "reversal_cost_azimuth_per_N",
                     "reversal_cost_bow_per_N", "reversal_band_rps", "reversal_dwell_s", "reversal_dwell_factor",
                     "reversal_quadratic", "reversal_hysteresis_rps", "q_cross_track", "q_cross_track_far",
                     "cross_track_far_m", "wave_azimuth_split_scale", "wave_bow_cost_scale"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"MPCConfig.{name}: {v} must be a finite number >= 0")


def _linearise_horizon_py(xb, wb, scale, mq, dt, dfx, dfy, dfn, n_floor, cn, ce, Ad, Bd, c):  # type: ignore[no-untyped-def]
    """Discrete LTV matrices along the nominal trajectory (numba-compiled; see module docstring).
    `mq`: the model's `ModelArrays.packed` (M, D_L, D_NL, thrust coefficients, thruster positions)."""
    N = wb.shape[0]
    M, _, _, thrust, arms = mq
    m11, m22, m33 = M[0, 0], M[1, 1], M[2, 2]
    _, _, mu_az, mu_t, rev = thrust
    for k in range(N):
        x = (xb[k, 0], xb[k, 1], xb[k, 2], xb[k, 3], xb[k, 4], xb[k, 5])
        q1 = wb[k, 2] * scale[2]
        q2 = wb[k, 3] * scale[3]
        qt = wb[k, 4] * scale[4]
        n1 = math.copysign(math.sqrt(abs(q1)), q1)
        n2 = math.copysign(math.sqrt(abs(q2)), q2)
        nt = math.copysign(math.sqrt(abs(qt)), qt)
        u = (wb[k, 0], wb[k, 1], n1, n2, nt)
        A, B = _jacobians_current(x, u, mq, cn, ce)
        # d/dq: the thrust is exactly linear in q (dT/dq = mu n_max^2, also at n = 0, where the
        # chain rule d/dn * dn/dq = 2 mu |n| / (2 |n|) is 0/0); only the housing force's kappa n
        # term goes through dn/dq = 1 / (2|n|), with |n| >= n_floor. (Through the floor, the whole
        # column would give a propeller at n = 0 no thrust authority in the prediction: the bow
        # thruster would never be used and an azimuth at zero would stay there.)
        for j in range(2):
            n = u[2 + j]
            a = u[j]
            fac = 1.0 if (n >= 0.0 or rev == 1.0) else rev
            lx = arms[j, 0]
            ly = arms[j, 1]
            ex = math.cos(a)
            ey = math.sin(a)
            en = lx * ey - ly * ex
            dT_dn = 2.0 * mu_az * abs(n) * fac
            dT_dq = mu_az * fac * scale[2 + j]
            g = scale[2 + j] / (2.0 * max(abs(n), n_floor))
            B[3, 2 + j] = (B[3, 2 + j] - dT_dn * ex / m11) * g + dT_dq * ex / m11
            B[4, 2 + j] = (B[4, 2 + j] - dT_dn * ey / m22) * g + dT_dq * ey / m22
            B[5, 2 + j] = (B[5, 2 + j] - dT_dn * en / m33) * g + dT_dq * en / m33
        B[4, 4] = mu_t * scale[4] / m22  # bow tunnel thruster: F_t = mu_t n|n| = mu_t n_max^2 q
        B[5, 4] = arms[2, 0] * mu_t * scale[4] / m33
        x1, _k1 = rk4_step(x, u, mq, cn, ce, dfx, dfy, dfn, dt)
        AA = A @ A
        AB = A @ B
        for i in range(6):
            for j in range(6):
                Ad[k, i, j] = dt * A[i, j] + 0.5 * dt * dt * AA[i, j]
            Ad[k, i, i] += 1.0
            for j in range(5):
                Bd[k, i, j] = dt * B[i, j] + 0.5 * dt * dt * AB[i, j]
        for i in range(6):
            acc = x1[i]
            for j in range(6):
                acc -= Ad[k, i, j] * xb[k, j]
            for j in range(5):
                acc -= Bd[k, i, j] * wb[k, j]
            c[k, i] = acc


_linearise_horizon = njit(_linearise_horizon_py)


def _path_at_py(s, S, table, dtable, ds, length, cos_end, sin_end, out):  # type: ignore[no-untyped-def]
    """Path (north, east, heading, curvature, speed) at arc length s, straight beyond the end."""
    sc = min(max(s, S[0]), length)
    i = np.searchsorted(S, sc, side="right") - 1
    i = min(max(i, 0), S.shape[0] - 2)
    f = (sc - S[i]) / ds[i]
    for j in range(5):
        out[j] = table[i, j] + f * dtable[i, j]
    b = s - sc
    if b > 0.0:
        out[0] += b * cos_end
        out[1] += b * sin_end
        out[3] = 0.0


_path_at = njit(_path_at_py)


def _crab_angle_py(path_heading, speed, current_n, current_e, limit):  # type: ignore[no-untyped-def]
    """The heading offset from the path (rad, + to starboard) of the water-relative velocity that makes
    `speed` along the path in the current (current_n, current_e): into the current's cross component,
    within +-limit; the along component is floored at 0.05 m/s (a following current as fast as the boat)."""
    ch = np.cos(path_heading)
    sh = np.sin(path_heading)
    along = speed - (ch * current_n + sh * current_e)
    across = sh * current_n - ch * current_e
    return min(max(np.arctan2(across, max(along, 0.05)), -limit), limit)


_crab_angle = njit(_crab_angle_py)


def crab_angle(path_heading_rad: float, speed_mps: float, current_ne_mps: tuple[float, float],
               limit_rad: float = math.pi / 2) -> float:
    """The crab angle (rad, + to starboard of the path) that makes `speed_mps` along a path of
    heading `path_heading_rad` in the earth-frame current `current_ne_mps`."""
    return float(_crab_angle(float(path_heading_rad), float(speed_mps), float(current_ne_mps[0]),
                             float(current_ne_mps[1]), float(limit_rad)))


class PathTable(NamedTuple):
    """The reference path as the compiled kernels read it (PathReference's interpolation tables)."""

    s_m: np.ndarray  # arc length of the table's rows
    table: np.ndarray  # (rows, 5): north, east, heading, curvature, speed
    dtable: np.ndarray  # row-to-row differences of `table`
    ds_m: np.ndarray  # row-to-row arc length
    end: np.ndarray  # (length_m, cos, sin of the heading at the end): straight beyond the end


def path_table(ref: PathReference) -> PathTable:
    return PathTable(ref.s, ref._table, ref._dtable, ref._ds, np.array([ref.length, ref._cos_end, ref._sin_end]))


class QpPattern(NamedTuple):
    """Where the kernel writes: the structural non-zeros of Ad and Bd, the upper triangle of
    C^T Q C, and their positions in the data arrays of A and P (set up once)."""

    ad_i: np.ndarray  # Ad[k] entries (row, column) in A, per stage at a_dyn_pos[k, :len(ad_i)]
    ad_j: np.ndarray
    bd_i: np.ndarray  # Bd[k] entries, at a_dyn_pos[k, len(ad_i):]
    bd_j: np.ndarray
    a_dyn_pos: np.ndarray  # (N, entries of Ad and Bd): positions in A's data
    p_state_pos: np.ndarray  # (N, entries of C^T Q C): positions in P's data
    p_i: np.ndarray  # the (row, column) of those entries
    p_j: np.ndarray


def cross_track_weight(cfg: MPCConfig, cross_track_m: float) -> float:
    """The cross-track weight at a measured cross-track error: q_cross_track on the path, falling
    towards q_cross_track_far beyond cross_track_far_m (a gentle approach from far, stiff tracking near)."""
    if cfg.cross_track_far_m <= 0.0 or not math.isfinite(cross_track_m):
        return cfg.q_cross_track
    return cfg.q_cross_track_far + (cfg.q_cross_track - cfg.q_cross_track_far) / (
        1.0 + (cross_track_m / cfg.cross_track_far_m) ** 2)


class QpWeights(NamedTuple):
    """The cost and the rate bound of the first input (scaled units, set up once; q_y[0], the
    cross-track weight, is set each step by `cross_track_weight`)."""

    q_y: np.ndarray  # outputs: cross-track, course, heading, speed, yaw rate
    stage: np.ndarray  # per stage (the terminal factor on the last)
    r_input: np.ndarray  # input weights R
    s_rate: np.ndarray  # input-rate weights S
    q_trim_gain: np.ndarray  # trim thrust of each azimuth at speed v: [0] v + [1] |v| v + [2] v^3
    dw_max: np.ndarray  # largest input change in one step
    min_speed_course_mps: float
    crab_max_rad: np.ndarray  # [limit] of the heading row's crab angle, set each step (0: none)
    row_rate: int  # first row of the rate bounds in A
    # the azimuths' thrust reference per stage: trim + split[0] (q_common[k] - trim), q_common the
    # nominal plan's mean of the two azimuths (split[0] = 0 in flat water: the trim alone)
    q_common: np.ndarray
    split: np.ndarray


class QpData(NamedTuple):
    """What the kernel writes, in place: the LTV model of the horizon, the data arrays of P and A,
    q, l, u, and the reference (north, east, heading, curvature, speed) of stages 1..N."""

    Ad: np.ndarray
    Bd: np.ndarray
    c: np.ndarray
    Px: np.ndarray
    Ax: np.ndarray
    q: np.ndarray
    l: np.ndarray
    u: np.ndarray
    ref: np.ndarray


def _assemble_py(x, xb, wb, s_pred, path, scale, mq, dt, dist, cur, n_floor, w_prev,  # type: ignore[no-untyped-def]
                 weights, pattern, qp, newton_iters):
    """One step of QP data: predicted progress, reference, LTV model, cost; written in place into
    `qp` (QpData) at the positions of `pattern` (QpPattern), with `weights` (QpWeights).

    xb: nominal states (absolute), wb: the inputs of the linearisation, s_pred: progress guess per
    stage (refined here by `newton_iters` foot-point steps, 0 keeps it: the time-parameterised
    reference; s_pred[0] fixed), path: PathTable, mq: the model's ModelArrays.packed, w_prev: the
    last applied input (scaled).
    """
    S, table, dtable, ds = path.s_m, path.table, path.dtable, path.ds_m
    length, cos_end, sin_end = path.end[0], path.end[1], path.end[2]
    Qy, stage_w, R, S_rate = weights.q_y, weights.stage, weights.r_input, weights.s_rate
    q_trim_gain, dw_max = weights.q_trim_gain, weights.dw_max
    q_common, split = weights.q_common, weights.split[0]
    min_speed_course, row_rate = weights.min_speed_course_mps, weights.row_rate
    crab_max = weights.crab_max_rad[0]
    ad_i, ad_j, bd_i, bd_j = pattern.ad_i, pattern.ad_j, pattern.bd_i, pattern.bd_j
    a_dyn_pos, p_state_pos, iu_i, iu_j = pattern.a_dyn_pos, pattern.p_state_pos, pattern.p_i, pattern.p_j
    Ad, Bd, c, Px, Ax, q, l, u, ref = qp.Ad, qp.Bd, qp.c, qp.Px, qp.Ax, qp.q, qp.l, qp.u, qp.ref
    N = wb.shape[0]
    nx = 6
    nw = 5
    buf = np.zeros(5)
    # --- progress of the nominal positions: Newton steps of the foot-point equation
    for it in range(newton_iters):
        for k in range(1, N + 1):
            _path_at(s_pred[k], S, table, dtable, ds, length, cos_end, sin_end, buf)
            dn = xb[k, 0] - buf[0]
            de = xb[k, 1] - buf[1]
            ch = np.cos(buf[2])
            sh = np.sin(buf[2])
            along = ch * dn + sh * de
            cross = -sh * dn + ch * de
            s_pred[k] += along / max(1.0 - buf[3] * cross, 0.3)
        for k in range(1, N + 1):  # monotone progress
            if s_pred[k] < s_pred[k - 1]:
                s_pred[k] = s_pred[k - 1]
    # --- reference; heading on the branch of the measured heading
    for k in range(N):
        _path_at(s_pred[k + 1], S, table, dtable, ds, length, cos_end, sin_end, buf)
        for j in range(5):
            ref[k, j] = buf[j]
    two_pi = 2.0 * np.pi
    ref[0, 2] += two_pi * np.round((x[2] - ref[0, 2]) / two_pi)
    for k in range(1, N):
        ref[k, 2] = ref[k - 1, 2] + ((ref[k, 2] - ref[k - 1, 2] + np.pi) % two_pi - np.pi)
    # --- linearisation, positions relative to the measured one
    xr = xb.copy()
    for k in range(N + 1):
        xr[k, 0] -= x[0]
        xr[k, 1] -= x[1]
    _linearise_horizon(xr, wb, scale, mq, dt, dist[0], dist[1], dist[2], n_floor, cur[0], cur[1], Ad, Bd, c)
    na = ad_i.shape[0]
    nb = bd_i.shape[0]
    for k in range(N):
        for m in range(na):
            Ax[a_dyn_pos[k, m]] = -Ad[k, ad_i[m], ad_j[m]]
        for m in range(nb):
            Ax[a_dyn_pos[k, na + m]] = -Bd[k, bd_i[m], bd_j[m]]
    # --- bounds: x0 = measured (relative), dynamics offsets, rate bound of the first input
    for i in range(nx):
        l[i] = xr[0, i]
        u[i] = xr[0, i]
    for k in range(N):
        for i in range(nx):
            l[nx + nx * k + i] = c[k, i]
            u[nx + nx * k + i] = c[k, i]
    for j in range(nw):
        l[row_rate + j] = w_prev[j] - dw_max[j]
        u[row_rate + j] = w_prev[j] + dw_max[j]
    # --- cost: y = C x + d (cross-track, course, heading, speed, yaw rate), P = C'QC, q = C'Qd
    Cm = np.zeros((5, nx))
    dv = np.zeros(5)
    H = np.zeros((nx, nx))
    nP = iu_i.shape[0]
    for k in range(N):
        pn = ref[k, 0] - x[0]
        pe = ref[k, 1] - x[1]
        ph = ref[k, 2]
        sh = np.sin(ph)
        ch = np.cos(ph)
        U = max(ref[k, 4], min_speed_course)
        Cm[0, 0] = -sh
        Cm[0, 1] = ch
        dv[0] = sh * pn - ch * pe
        Cm[1, 2] = 1.0
        Cm[1, 4] = 1.0 / U
        dv[1] = -ph
        Cm[2, 2] = 1.0
        dv[2] = -ph
        if crab_max > 0.0:
            dv[2] -= _crab_angle(ph, ref[k, 4], cur[0], cur[1], crab_max)
        Cm[3, 3] = 1.0
        dv[3] = -ref[k, 4]
        Cm[4, 5] = 1.0
        dv[4] = -ref[k, 4] * ref[k, 3]
        w = stage_w[k]
        for i in range(nx):
            for j in range(nx):
                acc = 0.0
                for y in range(5):
                    acc += Cm[y, i] * Qy[y] * Cm[y, j]
                H[i, j] = w * acc
            acc = 0.0
            for y in range(5):
                acc += Cm[y, i] * Qy[y] * dv[y]
            q[nx * (k + 1) + i] = w * acc
        for m in range(nP):
            Px[p_state_pos[k, m]] = H[iu_i[m], iu_j[m]]
    for i in range(nx):
        q[i] = 0.0
    base = nx * (N + 1)
    for k in range(N):
        v = ref[k, 4]
        qt = q_trim_gain[0] * v + q_trim_gain[1] * abs(v) * v + q_trim_gain[2] * v * v * v  # trim thrust (scaled)
        qt = qt + split * (q_common[k] - qt)  # in a sea: about the plan's common mode (MPCConfig.wave_*)
        q[base + nw * k + 0] = 0.0
        q[base + nw * k + 1] = 0.0
        q[base + nw * k + 2] = -R[2] * qt
        q[base + nw * k + 3] = -R[3] * qt
        q[base + nw * k + 4] = 0.0
    for j in range(nw):
        q[base + j] -= S_rate[j] * w_prev[j]


_assemble = njit(_assemble_py)


def _input_lag_block_py(Bd, bi, bj, beta, w_before, Ax, a_b_pos, a_lag_pos, l, u):  # type: ignore[no-untyped-def]
    """The actuator lags' entries (module docstring): input column j of stage k's dynamics row scaled
    by beta[k, j], the previous stage's set-point by (1 - beta[k, j]), and for stage 0 the actuator
    state before the step (`w_before`: the servo angles, the achieved ESC thrust) moved into the row's
    bounds. Written in place (numba-compiled: per step, no allocation)."""
    N = Bd.shape[0]
    m = bi.shape[0]
    for k in range(N):
        for j in range(m):
            b = Bd[k, bi[j], bj[j]]
            g = beta[k, bj[j]]
            Ax[a_b_pos[k, j]] = -g * b
            if k >= 1:
                Ax[a_lag_pos[k - 1, j]] = -(1.0 - g) * b
    for i in range(Bd.shape[1]):
        off = 0.0
        for j in range(w_before.shape[0]):
            off += Bd[0, i, j] * (1.0 - beta[0, j]) * w_before[j]
        l[Bd.shape[1] + i] += off
        u[Bd.shape[1] + i] += off


_input_lag_block = njit(_input_lag_block_py)


def _csc_template(n_rows: int, n_cols: int, entries: list[tuple[int, int]]) -> tuple[sp.csc_matrix, np.ndarray]:
    """CSC matrix with a fixed pattern; returns it and `pos` with data[pos[i]] = value of entry i."""
    rows = np.array([e[0] for e in entries])
    cols = np.array([e[1] for e in entries])
    ids = np.arange(1, len(entries) + 1, dtype=float)
    M = sp.csc_matrix((ids, (rows, cols)), shape=(n_rows, n_cols))
    M.sort_indices()
    if M.nnz != len(entries):
        raise RuntimeError("duplicate entries in a sparse template")
    pos = np.empty(len(entries), dtype=np.int64)
    pos[M.data.astype(np.int64) - 1] = np.arange(M.nnz)
    return M, pos


class MPCController:
    """Path-following MPC (see module docstring). Implements the `PathFollower` protocol."""

    name = "mpc"

    def __init__(self, model: VesselModel | None = None, limits: ActuatorLimits = DEFAULT_LIMITS,
                 config: MPCConfig = MPCConfig()) -> None:
        self.model = model or VesselModel()
        self.limits = limits
        self.config = config
        self.N = config.horizon
        N = self.N
        self.scale = np.array([1.0, 1.0, limits.n_az_max_rps ** 2, limits.n_az_max_rps ** 2,
                               limits.n_bow_max_rps ** 2])
        self.nz = NX * (N + 1) + NW * N + NREV * N
        self._build_qp()
        self.path: PathReference | None = None
        self.failures = 0
        self.solve_times_ms: list[float] = []
        self._reset_state()

    # ------------------------------------------------------------------ set-up (once)
    def _xi(self, k: int) -> int:
        return NX * k

    def _wi(self, k: int) -> int:
        return NX * (self.N + 1) + NW * k

    def _ti(self, k: int) -> int:
        """Reversal slacks t_k (one per propeller) of stage k."""
        return NX * (self.N + 1) + NW * self.N + NREV * k

    def _build_qp(self) -> None:
        N, cfg, lim = self.N, self.config, self.limits
        # --- P (upper triangle): dense 6x6 state blocks for k = 1..N, input blocks (R + rate S)
        p_entries: list[tuple[int, int]] = []
        # structural pattern of C^T Q C (see the output rows in the module docstring)
        C_struct = np.zeros((NY, NX))
        for i, j in ((0, 0), (0, 1), (1, 2), (1, 4), (2, 2), (3, 3), (4, 5)):
            C_struct[i, j] = 1.0
        iu = np.nonzero(np.triu(C_struct.T @ C_struct) > 0)
        self._iu = iu
        for k in range(1, N + 1):
            b = self._xi(k)
            p_entries += [(b + i, b + j) for i, j in zip(iu[0], iu[1])]
        n_state_p = len(p_entries)
        # thrust of one unit of q in newtons (the model's), to price thrust in physical terms
        p = self.model.params
        self.thrust_per_q = np.array([p.mu_az * self.scale[2], p.mu_az * self.scale[3], p.mu_t * self.scale[4]])
        tq = self.thrust_per_q
        R = np.array([cfg.r_alpha, cfg.r_alpha, cfg.r_thrust_azimuth_per_N2 * tq[0] ** 2,
                      cfg.r_thrust_azimuth_per_N2 * tq[1] ** 2, cfg.r_thrust_bow_per_N2 * tq[2] ** 2])
        S = np.array([cfg.s_alpha, cfg.s_alpha, cfg.s_thrust, cfg.s_thrust, cfg.s_thrust])
        self._R, self._S, self._S_calm, self._R_calm = R, S, S.copy(), R.copy()
        p_in_vals: list[float] = []
        rate_j: list[int] = []  # per input entry of P: its input, and how many S it holds (`_set_sea_weights`)
        rate_count: list[float] = []
        for k in range(N):
            b = self._wi(k)
            for j in range(NW):
                diag = R[j] + S[j] + (S[j] if k < N - 1 else 0.0)
                p_entries.append((b + j, b + j))
                p_in_vals.append(diag)
                rate_j.append(j)
                rate_count.append(2.0 if k < N - 1 else 1.0)
            if k >= 1:
                for j in range(NW):
                    p_entries.append((self._wi(k - 1) + j, b + j))
                    p_in_vals.append(-S[j])
                    rate_j.append(j)
                    rate_count.append(-1.0)
        for k in range(N):
            for j in range(NREV):
                p_entries.append((self._ti(k) + j, self._ti(k) + j))
                p_in_vals.append(cfg.reversal_quadratic)
        P, self._p_pos = _csc_template(self.nz, self.nz, p_entries)
        self._p_state_pos = self._p_pos[:n_state_p].reshape(N, len(iu[0]))
        self._Px = np.zeros(P.nnz)
        self._Px[self._p_pos[n_state_p:]] = p_in_vals
        self._p_in_pos = self._p_pos[n_state_p:n_state_p + len(rate_j)]
        self._p_in_j = np.array(rate_j)
        self._p_in_count = np.array(rate_count)
        self._Px[self._p_state_pos] = 1e-6  # replaced before the first solve
        # --- A: x0 = x_meas; dynamics; input bounds; rate bounds
        a_entries: list[tuple[int, int]] = []
        a_vals: list[float] = []
        row = 0
        for i in range(NX):
            a_entries.append((row + i, i))
            a_vals.append(1.0)
        row += NX
        dyn_entries_start = len(a_entries)
        ai, aj, bi, bj = self._dynamics_pattern()
        self._ad_idx, self._bd_idx = (ai, aj), (bi, bj)
        for k in range(N):
            r = row + NX * k
            a_entries += [(r + i, self._xi(k) + j) for i, j in zip(ai, aj)]
            a_entries += [(r + i, self._wi(k) + j) for i, j in zip(bi, bj)]
            a_vals += [0.0] * (len(ai) + len(bi))
        dyn_count = len(a_entries) - dyn_entries_start
        # actuator lags (ESC, servo): stage k's dynamics also depend on the previous set-point (k >= 1)
        lag_start = len(a_entries)
        for k in range(1, N):
            r = row + NX * k
            a_entries += [(r + i, self._wi(k - 1) + j) for i, j in zip(bi, bj)]
            a_vals += [0.0] * len(bi)
        lag_count = len(a_entries) - lag_start
        for k in range(N):
            for i in range(NX):
                a_entries.append((row + NX * k + i, self._xi(k + 1) + i))
                a_vals.append(1.0)
        row += NX * N
        self._row_bounds = row
        for k in range(N):
            for j in range(NW):
                a_entries.append((row + NW * k + j, self._wi(k) + j))
                a_vals.append(1.0)
        row += NW * N
        self._row_rate = row
        for k in range(N):
            for j in range(NW):
                a_entries.append((row + NW * k + j, self._wi(k) + j))
                a_vals.append(1.0)
                if k >= 1:
                    a_entries.append((row + NW * k + j, self._wi(k - 1) + j))
                    a_vals.append(-1.0)
        row += NW * N
        # reversal slacks per propeller: t >= 0, t + sigma q >= -q_band (t >= the thrust against the
        # present direction sigma beyond the free band; sigma written at run time, 0 = no constraint)
        self._row_rev = row
        sigma_start = len(a_entries)
        for k in range(N):
            for j in range(NREV):
                a_entries.append((row + 2 * NREV * k + NREV + j, self._wi(k) + 2 + j))
                a_vals.append(1.0)
        for k in range(N):
            for j in range(NREV):
                r1, r2, tj = row + 2 * NREV * k + j, row + 2 * NREV * k + NREV + j, self._ti(k) + j
                a_entries += [(r1, tj), (r2, tj)]
                a_vals += [1.0, 1.0]
        row += 2 * NREV * N
        self.m = row
        A, a_pos = _csc_template(self.m, self.nz, a_entries)
        self._a_sigma_pos = a_pos[sigma_start:sigma_start + NREV * N]  # per stage: azimuth 1, 2, bow
        self._Ax = np.zeros(A.nnz)
        self._Ax[a_pos] = a_vals
        # per stage k: the Ad entries of the pattern, then the Bd entries
        self._a_dyn_pos = a_pos[dyn_entries_start:dyn_entries_start + dyn_count].reshape(N, len(ai) + len(bi))
        self._a_lag_pos = a_pos[lag_start:lag_start + lag_count].reshape(N - 1, len(bi))
        self._a_b_pos = self._a_dyn_pos[:, len(ai):].copy()  # per stage: the Bd entries of the pattern
        T_m = lim.motor_time_constant_s
        # weight of the new set-point in the step-average thrust of a first-order response
        self._esc_beta = 1.0 - T_m / cfg.dt_s * (1.0 - math.exp(-cfg.dt_s / T_m)) if cfg.esc_in_prediction else 1.0
        self._beta = np.ones((N, NW))  # per stage and input: weight of the new set-point (`_lag_weights`)
        # bounds
        self._l = np.zeros(self.m)
        self._u = np.zeros(self.m)
        w_max = np.array([lim.alpha_max_rad, lim.alpha_max_rad, 1.0, 1.0, 1.0])
        self._w_max = w_max
        self._l[self._row_bounds:self._row_rate] = np.tile(-w_max, N)
        self._u[self._row_bounds:self._row_rate] = np.tile(w_max, N)
        dn = lim.n_rate_max_rps2 * cfg.dt_s
        dq_az = min(1.0, 2.0 * dn / lim.n_az_max_rps)
        dq_bow = min(1.0, 2.0 * dn / lim.n_bow_max_rps)
        da = lim.alpha_rate_max_radps * cfg.dt_s
        self._dw_max = np.array([da, da, dq_az, dq_az, dq_bow])
        self._l[self._row_rate:self._row_rev] = np.tile(-self._dw_max, N)
        self._u[self._row_rate:self._row_rev] = np.tile(self._dw_max, N)
        self._l[self._row_rev:] = 0.0
        self._u[self._row_rev:] = np.inf
        band = cfg.reversal_band_rps ** 2 / self.scale[2:]
        for k in range(N):
            r2 = self._row_rev + 2 * NREV * k + NREV
            self._l[r2:r2 + NREV] = -band
        self._q = np.zeros(self.nz)
        # crossing cost per unit of q: newtons against the direction (astern thrust is weaker by the
        # model's reverse ratio, so an azimuth's astern q makes fewer newtons)
        rev = float(self.model.geometry.reverse_thrust_ratio)
        self._crossing_cost_q = np.array([cfg.reversal_cost_azimuth_per_N * tq[0] * rev,
                                          cfg.reversal_cost_azimuth_per_N * tq[1] * rev,
                                          cfg.reversal_cost_bow_per_N * tq[2]])
        self._q[self._ti(0):] = np.tile(self._crossing_cost_q, N)
        P.data[:] = self._Px
        A.data[:] = self._Ax
        self.solver = osqp.OSQP()
        settings: dict[str, Any] = dict(verbose=False, warm_starting=True, polishing=False,
                                        eps_abs=cfg.eps, eps_rel=cfg.eps, max_iter=cfg.max_iter,
                                        check_termination=cfg.check_termination, adaptive_rho=cfg.adaptive_rho,
                                        scaling=cfg.scaling, rho=cfg.rho)
        if cfg.adaptive_rho_interval > 0:
            settings["adaptive_rho_interval"] = cfg.adaptive_rho_interval
        if cfg.time_limit_s > 0:
            settings["time_limit"] = cfg.time_limit_s
        self.solver.setup(P, self._q, A, self._l, self._u, **settings)
        # scratch arrays for the linearisation
        self._Ad = np.zeros((N, NX, NX))
        self._Bd = np.zeros((N, NX, NW))
        self._c = np.zeros((N, NX))
        self._ones_stage = np.ones(N)
        self._ones_stage[-1] = cfg.terminal_factor
        self._ref = np.zeros((N, 5))
        p = self.model.params
        self._q_trim_gain = np.array([p.X_u, -p.X_uu, -p.X_uuu]) / (2.0 * p.mu_az * self.scale[2])
        self._q_trim_sea_ref = float(self.q_trim(np.array(cfg.wave_speed_ref_mps)))  # k's denominator in a sea
        self._Qy = np.array([cfg.q_cross_track, cfg.q_course, cfg.q_heading, cfg.q_speed, cfg.q_yaw_rate])
        # the compiled assembly's view of the above (the same arrays, grouped)
        self._pattern = QpPattern(self._ad_idx[0], self._ad_idx[1], self._bd_idx[0], self._bd_idx[1],
                                  self._a_dyn_pos, self._p_state_pos, self._iu[0], self._iu[1])
        self._q_common = np.zeros(N)
        self._split = np.zeros(1)
        self._crab_max = np.zeros(1)
        self._align_point = np.zeros(5)  # the path (north, east, heading, curvature, speed) at the progress
        self._weights = QpWeights(self._Qy, self._ones_stage, self._R, self._S, self._q_trim_gain, self._dw_max,
                                  float(cfg.min_speed_course_mps), self._crab_max, int(self._row_rate),
                                  self._q_common, self._split)
        self._qp = QpData(self._Ad, self._Bd, self._c, self._Px, self._Ax, self._q, self._l, self._u, self._ref)

    def _dynamics_pattern(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Structural non-zeros of Ad and Bd: the union over random operating points (the
        kinematics make e.g. Ad[3:6, 0:3] structurally zero); the diagonal of Ad always."""
        rng = np.random.default_rng(1)
        N = 8
        xb = np.zeros((N + 1, NX))
        xb[:, :2] = rng.uniform(-5, 5, (N + 1, 2))
        xb[:, 2] = rng.uniform(-np.pi, np.pi, N + 1)
        xb[:, 3] = rng.uniform(-0.5, 1.5, N + 1)
        xb[:, 4:] = rng.uniform(-0.3, 0.3, (N + 1, 2))
        wb = rng.uniform(-1, 1, (N, NW)) * np.array([0.7, 0.7, 1, 1, 1])
        Ad, Bd, c = np.zeros((N, NX, NX)), np.zeros((N, NX, NW)), np.zeros((N, NX))
        _linearise_horizon(xb, wb, self.scale, self.model.arrays.packed, self.config.dt_s,
                           0.1, 0.1, 0.1, self.config.n_floor_rps, 0.1, -0.1, Ad, Bd, c)
        a_mask = np.any(np.abs(Ad) > 0, axis=0) | np.eye(NX, dtype=bool)
        b_mask = np.any(np.abs(Bd) > 0, axis=0)
        ai, aj = np.nonzero(a_mask)
        bi, bj = np.nonzero(b_mask)
        return ai, aj, bi, bj

    # ------------------------------------------------------------------ run time
    def _reset_state(self) -> None:
        self._xb: np.ndarray | None = None  # nominal states (N+1, 6), absolute positions
        self._wb = np.zeros((self.N, NW))  # nominal inputs (scaled)
        self._s_pred: np.ndarray | None = None
        self._s = 0.0
        self._w_prev = np.zeros(NW)  # last applied (scaled) input
        self._cmd_prev: tuple[float, ...] | None = None
        self._plan: np.ndarray | None = None  # last feasible input sequence (scaled)
        self._plan_age = 0
        self._dist = np.zeros(3)  # estimated disturbance force (N, N, N m) in the body frame
        self._current = np.zeros(2)  # water current in the prediction (VesselState.current_ne_mps)
        self._obs: tuple[np.ndarray, tuple[float, ...]] | None = None
        self._done = False
        self._direction = np.zeros(NREV)  # achieved direction beyond the hysteresis (0: none yet)
        self.reversals = 0  # reversals of the modelled achieved speeds since reset (all three propellers)
        # present direction of each propeller in the sign constraint: the azimuths start ahead (a
        # route starts ahead: free astern thrust at the start backed the boat away from its path in
        # a beam current), the bow thruster with none (0: no constraint)
        self._sigma = np.array([1.0, 1.0, 0.0])
        self._since_flip_s = np.full(NREV, np.inf)  # time since each propeller changed direction
        self._astern_s = np.zeros(NREV)  # how long each propeller's direction has been astern
        self._idle_s = np.zeros(NREV)  # how long each has idled with its direction astern (the bow: either)
        self._n_achieved = np.zeros(NREV)  # modelled ESC speeds (rev/s) at the present time
        self._cmd_effective: tuple[float, ...] = (0.0,) * NW
        self._Ax[self._a_sigma_pos] = np.tile(self._sigma, self.N)
        self._sea = SeaLevel(self.config.sea, self.config.dt_s)
        self._set_sea_weights(1.0, 1.0, 1.0, 0.0)
        self._stalled_s = 0.0  # how long the boat has been slow along the path where the current asks a crab
        self._aligning_s = math.nan  # time in the crab alignment (nan: not aligning)

    @property
    def sea_level(self) -> float:
        """0 (flat water) .. 1 (MPCConfig.sea), from the wave motion the estimate carries."""
        return self._sea.level

    def _set_sea_weights(self, scale: float, thrust_scale: float, reversal_scale: float, sea_level: float) -> None:
        """The input-rate penalties times `scale` and the thrust costs at `sea_level`
        (MPCConfig.wave_azimuth_split_scale, wave_bow_cost_scale): S in the first stage's linear term
        (the kernel's s_rate), R in the trim term (the kernel's r_input) and both in P's input entries
        (R + count S on the diagonal, -S off it)."""
        cfg = self.config
        self.rate_scale = scale
        self.thrust_rate_scale = thrust_scale
        self.reversal_scale = reversal_scale
        self._split[0] = sea_level
        self._R[2:4] = self._R_calm[2:4] * (1.0 + (max(cfg.wave_azimuth_split_scale, 1.0) - 1.0) * sea_level)
        self._R[4] = self._R_calm[4] * (1.0 + (max(cfg.wave_bow_cost_scale, 1.0) - 1.0) * sea_level)
        p_in_R = np.where(self._p_in_count > 0, self._R[self._p_in_j], 0.0)  # R on the diagonal only
        self._S[:] = self._S_calm * np.array([scale, scale, thrust_scale, thrust_scale, thrust_scale])
        self._Px[self._p_in_pos] = p_in_R + self._p_in_count * self._S[self._p_in_j]

    def _schedule_rate(self, state: VesselState) -> None:
        """In a sea, dearer input changes, reversals, uneven azimuth thrust and bow thrust
        (MPCConfig.wave_*): the RMS of the wave displacement or heading the estimator separated out,
        beyond its dead band, is the sea level f (0..1) that scales the angles' rate penalty up to
        wave_rate_scale (times k^2 above wave_speed_ref_mps), the propellers' up to
        wave_thrust_rate_scale, the crossing price up to wave_reversal_scale (times k) and the thrust
        costs up to wave_azimuth_split_scale and wave_bow_cost_scale."""
        cfg = self.config
        w = getattr(state, "wave_motion", (0.0, 0.0, 0.0))
        scales = (cfg.wave_rate_scale, cfg.wave_thrust_rate_scale, cfg.wave_reversal_scale, cfg.wave_azimuth_split_scale,
                  cfg.wave_bow_cost_scale)
        if not ((max(scales) > 1.0 or math.isfinite(cfg.wave_azimuth_astern_hold_s))
                and all(math.isfinite(a) for a in w)):
            return
        f = self._sea.update(w)
        k = 1.0
        if f > 0.0 and state.u_mps > cfg.wave_speed_ref_mps:
            k = float(self.q_trim(np.array(state.u_mps))) / self._q_trim_sea_ref
        scale = 1.0 + (max(cfg.wave_rate_scale, 1.0) * k ** cfg.wave_speed_angle_exponent - 1.0) * f
        thrust_scale = 1.0 + (max(cfg.wave_thrust_rate_scale, 1.0) - 1.0) * f
        reversal_scale = 1.0 + (max(cfg.wave_reversal_scale, 1.0) * k ** cfg.wave_speed_reversal_exponent - 1.0) * f
        if abs(scale - self.rate_scale) > 0.01 * self.rate_scale or abs(f - self._split[0]) > 0.01 \
                or abs(reversal_scale - self.reversal_scale) > 0.01 * self.reversal_scale:
            self._set_sea_weights(scale, thrust_scale, reversal_scale, f)

    def _q_achieved(self) -> np.ndarray:
        n = self._n_achieved
        return n * np.abs(n) / self.scale[2:]

    def _lag_weights(self, w: np.ndarray, before: np.ndarray, beta: np.ndarray) -> np.ndarray:
        """Weight of the new set-point w in each input's step average after `before` (rows: stages),
        written into beta: the ESC's first-order response (`_esc_beta`) and the servo slewing at its
        rate limit, whose ramp takes |delta| / rate of the step, so that the average lags the new
        angle by delta |delta| / (2 rate dt) (exact for the simulator's servo; the rate bound keeps
        every set-point reachable within a step). The step average is beta w + (1 - beta) before."""
        beta[..., 2:] = self._esc_beta
        if self.config.servo_in_prediction:
            da = self.limits.alpha_rate_max_radps * self.config.dt_s
            beta[..., :2] = 1.0 - np.minimum(np.abs(w[..., :2] - before[..., :2]) / (2.0 * da), 0.5)
        else:
            beta[..., :2] = 1.0
        return beta

    def _effective_command(self, cmd: tuple[float, ...], previous: tuple[float, ...]) -> tuple[float, ...]:
        """The step-average input of the servo and ESC responses to cmd after `previous` (the
        prediction's input), as angles and propeller speeds."""
        w = self.command_to_w(cmd)
        before = np.concatenate([previous[:2], self._q_achieved()])
        b = self._lag_weights(w, before, np.empty(NW))
        return self.w_to_command(b * w + (1.0 - b) * before)

    def _advance_esc(self, cmd: tuple[float, ...]) -> None:
        """The modelled ESC speeds one control period on under cmd (the simulator's motor model, 10 ms steps)."""
        lim = self.limits
        steps = max(1, int(round(self.config.dt_s / 0.01)))
        self._n_achieved = np.array(advance_motors(self._n_achieved, lim.clip(*cmd)[2:], self.config.dt_s, lim, steps))

    def _update_direction(self) -> None:
        """Direction state per propeller from the modelled achieved speed (|n| within the hysteresis
        keeps the direction): count reversals, set sigma for the sign constraint, time the dwell."""
        cfg = self.config
        h = cfg.reversal_hysteresis_rps
        self._since_flip_s += cfg.dt_s
        for j in range(NREV):
            n = self._n_achieved[j]
            d = 1.0 if n > h else (-1.0 if n < -h else 0.0)
            if d != 0.0:
                if self._direction[j] == -d:
                    self.reversals += 1
                    self._since_flip_s[j] = 0.0
                self._direction[j] = d
        self._astern_s = np.where(self._direction < 0.0, self._astern_s + cfg.dt_s, 0.0)
        idle = (self._direction < 0.0) & (np.abs(self._n_achieved) < h)
        idle[2] = self._direction[2] != 0.0 and abs(self._n_achieved[2]) < h  # the bow: idle either way
        self._idle_s = np.where(idle, self._idle_s + cfg.dt_s, 0.0)
        sigma_prev = self._sigma.copy()
        if self._idle_s[2] > cfg.bow_idle_release_s:
            self._direction[2] = 0.0
            self._idle_s[2] = 0.0
            sigma_prev[2] = 0.0
        # an azimuth idle astern-directed: ahead again; in flat water only (in a sea the wave hold acts)
        if math.isfinite(cfg.azimuth_idle_release_s) and self.sea_level == 0.0:
            for j in range(2):
                if self._idle_s[j] > cfg.azimuth_idle_release_s:
                    self._direction[j] = 0.0
                    self._astern_s[j] = 0.0
                    self._idle_s[j] = 0.0
                    sigma_prev[j] = 1.0
        sigma = np.where(self._direction != 0.0, self._direction, sigma_prev)
        if cfg.azimuth_ahead_only:
            sigma[:2] = 1.0
        hold = min(cfg.azimuth_astern_hold_s, cfg.wave_azimuth_astern_hold_s) if self.sea_level > 0.0 \
            else cfg.azimuth_astern_hold_s
        sigma[:2] = np.where(self._astern_s[:2] > hold, 1.0, sigma[:2])
        if np.any(sigma != self._sigma):
            self._sigma = sigma
            self._Ax[self._a_sigma_pos] = np.tile(sigma, self.N)

    def _crossing_costs(self) -> None:
        """The slacks' cost per stage: the crossing cost, times the dwell factor for a propeller that
        changed direction less than reversal_dwell_s ago."""
        cfg = self.config
        lam = self._crossing_cost_q * np.where(self._since_flip_s < cfg.reversal_dwell_s, cfg.reversal_dwell_factor, 1.0)
        lam = lam * self.reversal_scale
        self._q[self._ti(0):] = np.tile(lam, self.N)

    def reset(self, path: Any, progress_m: float = 0.0) -> None:
        self.path = PathReference(path, self.config.min_speed_ref_mps)
        self._path_table = path_table(self.path)
        self.failures = 0
        self.solve_times_ms = []
        self.qp_solves = 0  # QPs solved since reset (more than the steps only in transients: reiterate_dw)
        self._reset_state()
        self._s = float(progress_m)

    @property
    def done(self) -> bool:
        return self._done

    @property
    def progress_m(self) -> float:
        return self._s

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) everything a step runs, with a few steps on a short
        straight path in a light current; then back to the state before `reset`. The live stack
        calls it at start: a first compile takes ~0.3 s, which the control loop must not pay at AUTO."""
        s = np.arange(0.0, 5.0, 0.01)
        zero = np.zeros_like(s)
        self.reset(SimpleNamespace(north_m=s, east_m=zero, heading_rad=zero, curvature_1pm=zero,
                                   speed_mps=np.full_like(s, 0.5), s_m=s))
        state = VesselState(stamp_s=0.0, north_m=0.0, east_m=0.1, heading_rad=0.0, u_mps=0.3, v_mps=0.0,
                            r_radps=0.0, current_ne_mps=(0.05, 0.0))
        for k in range(3):
            self.update(0.1 * k, state)
        self.path = None
        self.failures = 0
        self.solve_times_ms = []
        self.qp_solves = 0
        self._reset_state()

    def q_trim(self, speed: np.ndarray) -> np.ndarray:
        """Scaled thrust q of each azimuth for a steady surge speed (seed eq. 22 at v = r = 0)."""
        p = self.model.params
        T = surge_drag(p, speed) / 2.0
        return T / (p.mu_az * self.scale[2])

    def w_to_command(self, w: np.ndarray) -> tuple[float, float, float, float, float]:
        q = w[2:] * self.scale[2:]
        n = np.sign(q) * np.sqrt(np.abs(q))
        return (float(w[0]), float(w[1]), float(n[0]), float(n[1]), float(n[2]))

    def command_to_w(self, cmd: tuple[float, ...]) -> np.ndarray:
        n = np.array(cmd[2:])
        return np.array([cmd[0], cmd[1], *(n * np.abs(n) / self.scale[2:])])

    def _crab_alignment(self, x: np.ndarray, path_heading: float, s0: float) -> bool:
        """The crab alignment (MPCConfig.align_*): enter after align_stall_s slow along the path, within
        align_max_cross_track_m of it, where the current asks a crab angle above align_min_crab_deg; while
        in it, the heading row's reference carries the crab angle at align_q_heading. True while aligning."""
        cfg = self.config
        self._Qy[2] = cfg.q_heading
        self._crab_max[0] = 0.0
        if not math.isfinite(cfg.align_min_crab_deg):
            return False
        pt, at = self._path_table, self._align_point
        _path_at(s0, pt.s_m, pt.table, pt.dtable, pt.ds_m, pt.end[0], pt.end[1], pt.end[2], at)  # compiled: ~1 us
        v_ref = float(at[4])
        limit = math.radians(cfg.max_crab_deg)
        crab = crab_angle(path_heading, v_ref, (self._current[0], self._current[1]), limit)
        if math.isnan(self._aligning_s):
            off = x[2] - path_heading
            speed_along = x[3] * math.cos(off) - x[4] * math.sin(off)
            # the offset across the path's heading (also behind its start, where the cross-track error is the
            # distance to the first point: a boat backed off the start is on the line, not joining it)
            across = -math.sin(path_heading) * (x[0] - float(at[0])) + math.cos(path_heading) * (x[1] - float(at[1]))
            slow = (speed_along < cfg.align_stall_fraction * v_ref and abs(crab) > math.radians(cfg.align_min_crab_deg)
                    and abs(across) < cfg.align_max_cross_track_m)
            self._stalled_s = self._stalled_s + cfg.dt_s if slow else 0.0
            if self._stalled_s < cfg.align_stall_s - 1e-9:
                return False
            self._stalled_s = 0.0
            self._aligning_s = 0.0
        self._aligning_s += cfg.dt_s
        if abs(wrap_angle(x[2] - path_heading - crab)) < math.radians(cfg.align_done_deg) \
                or self._aligning_s > cfg.align_max_s:
            self._aligning_s = math.nan
            return False
        self._Qy[2] = cfg.align_q_heading
        self._crab_max[0] = limit
        return True

    def _current_estimate(self, state: VesselState) -> np.ndarray:
        """The estimator's water current (earth frame, m/s; zero when unknown or switched off)."""
        if not self.config.current_in_prediction:
            return np.zeros(2)
        cur = np.array(getattr(state, "current_ne_mps", (0.0, 0.0)), dtype=float)
        if cur.shape != (2,) or not np.all(np.isfinite(cur)) or float(np.hypot(*cur)) > self.config.max_current_mps:
            return np.zeros(2)
        return cur

    def _update_disturbance(self, x: np.ndarray) -> None:
        """Observer: d += g * M * (measured - predicted velocity) / dt (one-step prediction error)."""
        cfg = self.config
        if self._obs is not None and cfg.disturbance_gain > 0:
            x_prev, cmd = self._obs
            xp, _ = rk4_step(tuple(x_prev), tuple(cmd), self.model.arrays.packed,
                             float(self._current[0]), float(self._current[1]),
                             float(self._dist[0]), float(self._dist[1]), float(self._dist[2]), cfg.dt_s)
            p = self.model.params
            err = (x[3:6] - np.array(xp[3:6])) / cfg.dt_s * np.array([p.m11, p.m22, p.m33])
            if np.all(np.isfinite(err)):
                self._dist = np.clip(self._dist + cfg.disturbance_gain * err, -cfg.disturbance_max_N,
                                     cfg.disturbance_max_N)

    def _nominal(self, x: np.ndarray) -> None:
        """Shift the previous solution; the first state is the measurement."""
        N = self.N
        if self._xb is None:
            # cold start: the azimuths at the trim thrust of the reference speed (or the previous
            # input, if it pushes harder), angles and bow as before, integrated with the model. At
            # q = 0 the angles have no authority in the linearisation (the side force T sin(alpha)
            # is bilinear), so a nominal at rest hides crabbing from the first QPs (the
            # bench's start 30 cm off the path: tracking gap to do-mpc 5.6 -> 4.7 % with one QP per
            # step, 6.8 -> 1.3 % with two).
            xb = np.empty((N + 1, NX))
            xb[0] = x
            w0 = self._w_prev.copy()
            v0 = float(self.path.sample(np.array([self._s]))[4][0])
            q_trim = float(self.q_trim(np.array(v0)))
            w0[2:4] = np.where(np.abs(w0[2:4]) > q_trim, w0[2:4], q_trim)
            wb = np.tile(w0, (N, 1))
            cmd = self.w_to_command(w0)
            for k in range(N):
                x1, _ = rk4_step(tuple(xb[k]), cmd, self.model.arrays.packed,
                                 float(self._current[0]), float(self._current[1]),
                                 float(self._dist[0]), float(self._dist[1]), float(self._dist[2]),
                                 self.config.dt_s)
                xb[k + 1] = x1
            self._xb, self._wb = xb, wb
        else:
            self._xb = np.concatenate([self._xb[1:], self._xb[-1:]])
            self._wb = np.concatenate([self._wb[1:], self._wb[-1:]])
            # keep the nominal heading on the measured branch (psi is not wrapped by the model)
            self._xb[:, 2] += 2.0 * math.pi * round((x[2] - self._xb[0, 2]) / (2.0 * math.pi))
            self._xb[0] = x

    def update(self, t: float, state: VesselState) -> tuple[ThrustCommand, ControllerStatus]:
        if self.path is None:
            raise RuntimeError("MPCController.update before reset(path)")
        t0 = time.perf_counter()  # measurement for reporting only, not control logic
        if not state_is_finite(state):
            return self._failure(t, state, "state not finite", t0, 0.0, 0.0, self._s, 0.0)
        cfg, N = self.config, self.N
        x = np.array(state.as_array_tuple(), dtype=float)
        self._schedule_rate(state)
        self._current = self._current_estimate(state)
        self._update_disturbance(x)
        s0, cte, hdg = self.path.project(x[0], x[1], self._s)
        self._s = s0
        self._Qy[0] = cross_track_weight(cfg, cte)  # self._weights.q_y is this array
        aligning = self._crab_alignment(x, hdg, s0)
        if s0 >= self.path.length - 0.02:
            self._done = True
        self._nominal(x)
        xb, wb = self._xb, self._wb
        assert xb is not None
        # progress guess: the previous prediction shifted (or the reference speed), refined in _assemble
        if self._s_pred is None or cfg.progress_reference == "time":
            v0 = float(self.path.sample(np.array([s0]))[4][0])
            s_pred = s0 + np.arange(N + 1) * v0 * cfg.dt_s
        else:
            s_pred = np.concatenate([self._s_pred[1:], self._s_pred[-1:]])
            s_pred[0] = s0
            np.maximum(s_pred, s0, out=s_pred)
        qa = self._q_achieved()
        origin = x[:2].copy()
        newton = 2 if cfg.progress_reference == "predicted" else 0
        # real-time iteration: one QP on the shifted plan's linearisation; with qp_iterations > 1 the
        # model is re-linearised along the new solution and the QP solved again (warm-started)
        w_before = np.concatenate([self._w_prev[:2], qa])  # servo angles and ESC thrust before the step
        self._crossing_costs()
        for _iteration in range(cfg.qp_iterations):
            # actuator lags: the linearisation runs on the step-average input of each stage
            prev = np.concatenate([w_before[None, :], wb[:-1]])
            self._lag_weights(wb, prev, self._beta)
            ub = self._beta * wb + (1.0 - self._beta) * prev
            if self._split[0] > 0.0:  # in a sea the azimuths' thrust is priced about the plan's common mode
                np.multiply(0.5, wb[:, 2] + wb[:, 3], out=self._q_common)
            _assemble(x, xb, ub, s_pred, self._path_table, self.scale, self.model.arrays.packed, cfg.dt_s, self._dist,
                      self._current, cfg.n_floor_rps, self._w_prev, self._weights, self._pattern, self._qp, newton)
            _input_lag_block(self._Bd, self._bd_idx[0], self._bd_idx[1], self._beta, w_before, self._Ax,
                             self._a_b_pos, self._a_lag_pos, self._l, self._u)
            self._s_pred = s_pred
            pv = self._ref[:, 4]
            if not (np.isfinite(self._Ax).all() and np.isfinite(self._l).all() and np.isfinite(self._q).all()):
                return self._failure(t, state, "QP data not finite", t0, cte, hdg, s0, float(pv[0]))
            self.solver.update(q=self._q, l=self._l, u=self._u, Px=self._Px, Ax=self._Ax)
            if cfg.warm_start_shifted and _iteration == 0:
                xr = xb.copy()
                xr[:, 0] -= origin[0]
                xr[:, 1] -= origin[1]
                tb = np.maximum(0.0, -self._sigma * wb[:, 2:] + self._l[self._row_rev + NREV:self._row_rev + 2 * NREV])
                tb = tb.ravel()
                self.solver.warm_start(x=np.concatenate([xr.ravel(), wb.ravel(), tb]))
            res = self.solver.solve(raise_error=False)
            self.qp_solves += 1
            z = None if res.x is None else np.array(res.x, dtype=float)
            ok = (res.info.status_val in _SOLVED and z is not None and z.shape == (self.nz,)
                  and bool(np.all(np.isfinite(z))))
            if not ok:
                return self._failure(t, state, f"solver: {res.info.status}", t0, cte, hdg, s0, float(pv[0]))
            assert z is not None
            xs = z[:NX * (N + 1)].reshape(N + 1, NX).copy()
            ws = z[NX * (N + 1):NX * (N + 1) + NW * N].reshape(N, NW).copy()
            ws = np.clip(ws, -self._w_max, self._w_max)
            xs[:, 0] += origin[0]
            xs[:, 1] += origin[1]
            moved = float(np.max(np.abs(ws - wb)))
            xb, wb = xs, ws
            if moved <= cfg.reiterate_dw:
                break
        self._xb, self._wb = xs, ws
        self._plan = ws.copy()
        self._plan_age = 0
        cmd = self._apply(ws[0])
        self._obs = (x, self._cmd_effective)
        solve_ms = (time.perf_counter() - t0) * 1e3
        self.solve_times_ms.append(solve_ms)
        status = make_status(t, self.name, cte, wrap_angle(x[2] - hdg), state, float(pv[0]), s0, solve_ms,
                             "aligning" if aligning else "ok", self.failures, (xs[:, 0], xs[:, 1]))
        return ThrustCommand.from_tuple(t, cmd, source=self.name), status

    def _apply(self, w: np.ndarray) -> tuple[float, ...]:
        cmd = rate_limit(self._cmd_prev, self.w_to_command(w), self.config.dt_s, self.limits)
        self._commit(cmd)
        return cmd

    def _commit(self, cmd: tuple[float, ...]) -> None:
        """cmd goes to the actuators: remember it, count reversals, step the ESC model (the
        observer's input is the step-average angle and thrust from the actuators before the step)."""
        previous = self._cmd_prev if self._cmd_prev is not None else cmd  # first command: servo angle unknown
        self._cmd_prev = cmd
        self._w_prev = self.command_to_w(cmd)
        self._cmd_effective = self._effective_command(cmd, previous)
        self._advance_esc(cmd)
        self._update_direction()

    def _failure(self, t: float, state: VesselState, why: str, t0: float, cte: float, hdg: float,
                 s0: float, v_ref: float) -> tuple[ThrustCommand, ControllerStatus]:
        """Previous plan shifted for a bounded time, then neutral; never the failed output."""
        self.failures += 1
        self._plan_age += 1
        self._xb = None  # the nominal is rebuilt (cold start) once the solver succeeds again
        self._s_pred = None
        if self._plan is not None and self._plan_age <= min(self.config.max_fallback_steps, self.N - 1):
            cmd = self._apply(self._plan[self._plan_age])
            status = f"fallback_plan ({why})"
        else:
            cmd = (0.0, 0.0, 0.0, 0.0, 0.0)  # safe stop: neutral
            self._commit(cmd)
            status = f"safe_stop ({why})"
        x = np.array(state.as_array_tuple(), dtype=float)
        self._obs = (x, self._cmd_effective) if np.all(np.isfinite(x)) else None
        solve_ms = (time.perf_counter() - t0) * 1e3
        self.solve_times_ms.append(solve_ms)
        heading_err = wrap_angle(state.heading_rad - hdg) if math.isfinite(state.heading_rad) else float("nan")
        st = make_status(t, self.name, cte, heading_err, state, v_ref, s0, solve_ms, status, self.failures)
        return ThrustCommand.from_tuple(t, cmd, source=self.name), st
