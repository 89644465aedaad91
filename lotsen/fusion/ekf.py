"""Model-aided extended Kalman filter (beyond the seed): one filter for pose, velocity, biases and
the slowly varying disturbance (water current, optionally a body force).

State x = [N, E, psi, u, v, r, b_g, (b_ax, b_ay), (c_N, c_E), (tau_X, tau_Y, tau_N), (wave states)]:
position in local NED (m), heading (rad, clockwise from north), body velocities over ground
(m/s, rad/s), gyro z bias (rad/s), by default the accelerometer's horizontal biases (m/s^2), by
default the water current over ground (north, east, m/s), optionally an external
body force and moment (N, N m: wind and other slowly varying forces), and by default the
wave-frequency motion (below). The optional blocks are switched by `EkfConfig`; the indices live
on the instance (`i_ba`, `i_cur`, `i_tau`, `i_wave`).

Waves (docs/fusion.md "Waves"; Fossen 2021 sec. 10.2.4 and ch. 13, the dynamic-positioning wave
filter): the measured motion is the sum of the low-frequency motion the vessel model describes
(the first six states: what the controllers get) and the wave-frequency motion no model of the
hull's forces predicts. The latter has states of its own, a damped oscillator per axis for north,
east and heading, eta = [eta_N, eta_N_dot, eta_E, eta_E_dot, eta_psi, eta_psi_dot]:

    eta_ddot = -w0^2 eta - 2 zeta w0 eta_dot + w,   w ~ N(0, 4 zeta w0^3 sigma^2)

(stationary standard deviation sigma). GNSS position measures N + eta_N (and E), GNSS velocity
adds eta_dot, the magnetometer psi + eta_psi, the gyro r + eta_psi_dot + b_g, the accelerometer the
wave accelerations (the oscillator's deterministic part; its white part is measurement noise).
w0 is the wave model's frequency: the sea-state estimate's encounter frequency where one is given
(`set_wave_frequency`), else the mean frequency of the wave band (`lotsen.fusion.waveband`); sigma
per axis follows the wave band's measured yaw-rate and acceleration within seconds, floored at
`wave_*_std_floor` so that in flat water the states sleep. So wave-frequency motion is explained,
not rejected as a sensor fault, and does not reach the controllers. What the wave states hold
beyond a few of their periods is not wave motion: the estimate the controllers get adds their slow
part (a low-pass over `wave_mean_periods` periods) back to the low-frequency pose and velocity.
The accelerometer is levelled first with the hull's roll and pitch (`lotsen.fusion.attitude.TiltFilter`): gravity's share on a
heeled axis is 0.17 m/s^2 a degree.

Process model: the vessel model (lotsen.model, seed eq. 7-8, 22) with the estimated current and
body force, driven by the achieved (or emulated) actuator values of `ActuatorInputFilter`,
integrated with RK4 (`rk4_step`). Covariance propagated with F = I + J dt + (J dt)^2 / 2 from the
analytic Jacobian J = df/dx: `VesselModel.jacobians` (calm water) evaluated at the velocity
relative to the water, extended by the chain rule to psi, the current and the force
(`_dynamics_jacobian`). White-acceleration process noise on u, v, r for the model's errors;
random walks for biases, current and force:

    c_N_dot = w_cN,  c_E_dot = w_cE,      w ~ N(0, sigma_current_walk^2)   (m/s / sqrt(s))
    tau_dot = w_tau,                      w ~ N(0, diag(sigma_tau_walk)^2) (N / sqrt(s), N m / sqrt(s))

The current is observable from GNSS and the model: GNSS (position and velocity) gives the
velocity over ground, the model with the achieved thrust predicts the velocity through the
water; the difference, seen at several headings, is the current.

Measurements (each gated by its squared Mahalanobis distance against a chi-square quantile;
NaN / non-finite samples are skipped and counted, never used):
- GNSS position (lat/lon -> NED in `lotsen.model.geodetic.FixFrame`: the configured origin, else
  the first usable fix), R per fix type
  from h_acc_m (`GnssNoise`); optionally the receiver's NED velocity.
- Gyro z: r + b_g, every IMU sample.
- Accelerometer x, y (averaged over `accel_decimation` samples): the model's specific force
  [u_dot - v r, v_dot + u r] + b_a of a level boat.
- Calibrated magnetometer heading: psi (innovation wrapped to [-pi, pi)); samples whose
  calibrated field norm is far from 1 are rejected as disturbed before the gate.

Integrity (lotsen.fusion.integrity): every gated test, raw sample and heading goes to an
`IntegrityMonitor`; a sensor declared stuck is not used; a gate that rejects a sensor
`max_consecutive_rejects` times in a row re-opens (inflating the covariance of the states that
sensor sees) only when the monitor allows it (start, re-acquisition after an outage, operator
reset), so a persistent GNSS jump or magnetic disturbance is declared, not accepted; a sensor
that jumped is accepted again only when it is nearer its old agreement than the jump.
`health(t)` returns the `EstimatorHealth` message (contract: docs/fusion.md).

Time comes only from message stamps: every message first predicts the filter to its stamp. A
message older than `max_lag_s` is skipped as stale; a slightly late one is applied at the
filter's time. A message more than `max_jump_s` ahead of the filter is not believed on its own
(one bad stamp must not make every later message stale): it is skipped, and the filter jumps
only when `jump_confirm` messages in a row are that far ahead (a real gap in the data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from statistics import NormalDist

import numpy as np

from lotsen.fusion.attitude import TiltConfig, TiltFilter
from lotsen.fusion.common import Counters, GnssNoise, finite, wrap_angle
from lotsen.fusion.waveband import WaveBand, WaveBandConfig
from lotsen.model.geodetic import FixFrame
from lotsen.fusion.inputs import ActuatorInputFilter, InputConfig
from lotsen.fusion.integrity import IntegrityConfig, IntegrityMonitor
from lotsen.fusion.magcal import MagCalibration
from lotsen.messages import (
    ActuatorState, EstimatorHealth, GnssFix, ImuSample, MagSample, RpmSample, ThrustCommand, VesselState,
)
from lotsen.model.angles import lever_arm_ne, mast_swing_body
from lotsen.model.dynamics import VesselModel, _jacobians_current, rk4_step

IN, IE, IPSI, IU, IV, IR, IBG = range(7)
IBAX, IBAY = 7, 8  # when accel_bias_states (the default)

FUSION_FAULTS = frozenset({"fusion.non_finite", "fusion.starved", "fusion.stalled"})



def chi2_quantile(p: float, dof: int) -> float:
    """The chi-square quantile of probability `p` for 1 or 2 degrees of freedom (the innovation
    gates), in closed form: (Phi^-1((1 - p) / 2))^2 and -2 ln(1 - p). Exact to double precision,
    without scipy.stats (0.8 s and ~45 MB of a process's start-up for two numbers)."""
    if dof == 1:
        return NormalDist().inv_cdf((1.0 - p) / 2.0) ** 2  # the lower tail: precise for p near 1
    if dof == 2:
        return -2.0 * math.log1p(-p)
    raise ValueError(f"chi2_quantile: 1 or 2 degrees of freedom, got {dof}")

@dataclass(frozen=True)
class EkfConfig:
    # process noise (continuous-time spectral densities, per second)
    sigma_pos_mps: float = 0.02  # slack on N, E (m/sqrt(s)): what the model's velocity misses
    sigma_psi_radps: float = 0.001
    sigma_nu_dot: tuple[float, float, float] = (0.08, 0.08, 0.1)  # model error on u_dot, v_dot, r_dot
    sigma_gyro_bias_walk: float = 0.0005  # rad/s/sqrt(s)
    sigma_accel_bias_walk: float = 0.002  # m/s^2/sqrt(s)
    sigma_current_walk_mps: float = 0.003  # m/s/sqrt(s): 0.03 m/s in 100 s
    # N, N, N m per sqrt(s), with disturbance_states: fast enough to follow the force error of a hull
    # 10-20 % off its model through a speed change, slow enough to leave the current observable in turns
    sigma_tau_walk: tuple[float, float, float] = (0.3, 0.5, 0.08)
    # The actuators' forces are known only to a fraction: a real thruster's coefficient is 10-20 %
    # off its model's, 20 % weaker astern, dead near zero speed. Each propeller's thrust has a relative
    # standard deviation sigma_thrust_rel (its speed sigma_thrust_rel / 2, thrust ~ n|n|), each
    # azimuth angle sigma_azimuth_rad; through the model's input Jacobian B this is acceleration
    # noise proportional to the thrust in use: process noise B S B' tau (error correlation time tau)
    # and, for the accelerometer that sees the true force, measurement noise B S B'. A crash stop
    # then widens the velocity's uncertainty and GNSS velocity pulls it back, instead of the model's
    # deceleration being trusted until GNSS disagrees beyond the gate (docs/fusion.md).
    sigma_thrust_rel: float = 0.35
    sigma_azimuth_rad: float = math.radians(2.0)
    thrust_error_correlation_s: float = 1.0
    # measurement noise
    sigma_gyro_radps: float = 0.005
    sigma_accel_mps2: float = 0.08  # of the decimated mean: noise, vibration, model's force error
    sigma_mag_heading_rad: float = math.radians(2.0)
    mag_norm_tolerance: float = 0.3
    # a GNSS "jump" is a step in the receiver's own track: position minus (last position + mean of the
    # two Doppler velocities x dt) beyond max(gnss_step_m, 5 sigma). A rejection streak without such a
    # step in the second before it means the estimate diverged (e.g. a wrong model): the gate re-opens.
    gnss_step_m: float = 0.5
    gnss_noise: GnssNoise = field(default_factory=GnssNoise)
    # where the GNSS antenna sits on the hull (body x forward, y starboard, m from the model's
    # origin): the receiver locates the antenna, which swings around the origin as the boat turns
    gnss_antenna_m: tuple[float, float] = (0.0, 0.0)
    # its height above the roll and pitch centre: the hull's roll and pitch swing it (1.3 cm at 3 deg
    # and 0.25 m), which the fixes are corrected for with the IMU's tilt and body rates
    gnss_antenna_height_m: float = 0.0
    use_gnss_velocity: bool = True
    use_accel: bool = True
    accel_bias_states: bool = True
    current_states: bool = True  # water current north / east
    # body force X, Y and moment N (wind and the model's force error); off by default: docs/fusion.md
    disturbance_states: bool = False
    # ... and the same states in a sea only (without `disturbance_states`): they sleep at zero in flat water
    # and walk at `sigma_tau_walk` while the wave band's heave acceleration is above
    # `wave_accel_sea_heave_mps2`. The waves' mean drift force is not a current: it pushes along the waves
    # and turns with the hull's heading to them, so as a current it moves by the damping's anisotropy (sway
    # ~3 x surge) through every turn, and the current's slow walk cannot follow (figure eight 0.5 m/s, Hs 6
    # cm, the drift force alone: slow cross-track 1.2 cm against 0.4 calm, in phase with twice the heading
    # to the waves; docs/fusion.md "Waves")
    # These sea-only states are the filter's own: `VesselState.disturbance_tau` reports the force only
    # with `disturbance_states` (the station keeper feeds it forward, and fed a force that follows the
    # waves' groups it reversed its thrusters 3 x as often as in calm water).
    wave_disturbance_states: bool = True
    # The force states learn only while a GNSS fix was accepted within this many seconds: in dead reckoning
    # the accelerometer alone cannot part a force from its own bias and the waves', and a force walking
    # there drifted the position (10 m GNSS jump, 20 s of dead reckoning: 2.6-2.9 m against the limit 2)
    force_learning_gnss_age_s: float = 1.0
    max_current_mps: float = 1.0  # the current estimate is clipped to this (a safety net, not a model)
    # wave-frequency motion (module docstring): its states, their model and how they adapt
    wave_states: bool = True
    wave_damping: float = 0.3  # zeta of the wave model: broad, since the encounter spectrum is
    wave_period_s: float = 1.0  # the wave model's period until the wave band or a sea-state estimate gives one
    wave_frequency_range_radps: tuple[float, float] = (1.5, 20.0)
    wave_position_std_floor_m: float = 0.0005
    wave_heading_std_floor_rad: float = 0.0003
    # the wave states' sigma from the wave band: position per heave displacement (a deep-water
    # particle's orbit is a circle), heading per roll-and-pitch angle (docs/fusion.md: measured)
    wave_position_per_heave: float = 1.0
    wave_heading_per_tilt: float = 0.3
    # In a sea the low-frequency states' white slack (`sigma_nu_dot`, and the thrusters' uncertain force
    # as process noise) tightens towards these values as the wave band's heave grows to
    # `wave_slack_heave_m`: the wave states take up the fast motion, and a loose low-frequency model
    # would share it (with the calm slack ~40 % of the sway and ~25 % of the yaw at wave frequency
    # reached the controllers; docs/fusion.md "Waves")
    wave_sigma_nu_dot: tuple[float, float, float] = (0.08, 0.05, 0.05)
    wave_sigma_thrust_rel: float = 0.25
    wave_slack_heave_m: float = 0.005
    # ... once the sea state gives the encounter frequency (`set_wave_frequency`), and only where the waves
    # are met well above the hull's own dynamics: none at or below the first
    # frequency, fully from the second (rad/s). In following seas at speed the encounter frequency falls to
    # 2-3 rad/s, where the waves drive the hull slowly and strongly and a tight model loses it (1 m/s, Hs
    # 10 cm: the GNSS 40 cm off in 0.75 s, declared inconsistent)
    wave_slack_frequency_radps: tuple[float, float] = (3.0, 5.0)
    # The low-frequency model's own error, as the accelerometer measures it: the accelerometer's
    # innovation averaged over `model_error_time_s` (the waves' accelerations, at 4-12 rad/s, average
    # out; a force the model does not have stays) beyond `model_error_sigmas` of that average's noise
    # becomes surge and sway process noise (its square x `model_error_time_s`), so GNSS velocity
    # takes over while the model is wrong, instead of being rejected by a model it disagrees with
    # (an independent hull heeled 22 deg and sliding 0.7 m/s sideways in a hard turn in Hs 6 cm: the
    # accelerometer read 1.4 m/s^2 the model did not predict, GNSS velocity was gated out and the
    # integrity monitor declared the GNSS inconsistent; covariance matching, Mehra 1972). 0: off.
    model_error_time_s: float = 0.5
    model_error_sigmas: float = 4.0
    # In a sea the accelerometer's wave-frequency acceleration (the measurement noise the wave band's heave
    # sets) is not white: it is narrow-band at the encounter frequency and lasts ~1 / (zeta w) = 0.3-0.5 s,
    # while the accelerometer's means arrive every 0.05 s (`accel_decimation` at 100 Hz). An update
    # that takes them for independent samples believes one wave 2 tau / dt ~ 10-20 times over; the standard
    # treatment of time-correlated noise not carried as states inflates its variance by that count. Bench
    # waves' figure eight at 0.5 and 1.0 m/s in Hs 6 and 10 cm on both hulls, seeds 0-4 (40 missions),
    # against 1 (no inflation): 15 tracked 4 % better with 9 % less azimuth travel, 10 % fewer reversals,
    # 5 % less energy, no failsafe; 4 and 40 did less well (docs/fusion.md "Waves"; measured with the
    # inflation from the first sample, before the sea threshold below). 1: off.
    wave_accel_correlated_samples: float = 15.0
    # ... once the wave band's heave acceleration is above this: flat water reads <= 0.02 m/s^2 on both
    # hulls (the 6-DOF hull turning at 1 m/s included), Hs 3 cm 0.2-0.3 within 2-5 s. Not the sea-state
    # estimator's flat-water floor (`SeaStateConfig.min_heave_accel_mps2`, 0.03): that one reads a 2-min
    # spectrum decimated to 10 Hz, this the EKF's running wave band: each sits above its own flat-water
    # reading. Flat water: unchanged
    wave_accel_sea_heave_mps2: float = 0.05
    # ... and as GNSS velocity measures it (covariance matching on its innovation, Mehra 1972): a hull not
    # built like the model settles, in a hard turn at speed, at another sway speed than the model's, so the
    # model's force balance holds at the wrong velocity and the accelerometer hardly sees it. The
    # body-frame innovation's mean square over `model_error_time_s` beyond `model_error_sigmas` of its
    # spread is the velocity error that built up between fixes: surge and sway process noise (the excess
    # / the fix interval), so the velocity follows the receiver instead of the error being booked as a
    # water current (hull B in a full-power turn at 1.6-2 m/s: 0.2-0.3 m/s of "current" in calm water,
    # the fixes gated out, GNSS declared inconsistent; docs/fusion.md)
    velocity_error_matching: bool = True
    # What the wave states hold beyond a few of their own periods is not wave-frequency motion: the
    # low-frequency estimate the controllers get (`estimate`) takes the wave states' running mean over
    # `wave_mean_periods` periods of the wave model back (and the wave motion reported loses it). The gyro
    # sees r + eta_psi_dot, and in a sea the tightened yaw model sent the difference between its own
    # turn rate and the hull's to the wave state (figure eight 0.5 m/s, Hs 6 cm: 3-4.7 deg/s held there
    # for 15-45 s on both hulls; the controller saw a turn rate that was not there and left 1.5-3.7 cm of
    # slow cross-track; docs/fusion.md "Waves"). 0: off.
    wave_mean_periods: float = 2.0
    wave_band: WaveBandConfig = field(default_factory=WaveBandConfig)
    # roll and pitch from the IMU, to take gravity out of the accelerometer's horizontal axes
    tilt_compensation: bool = True
    tilt: TiltConfig = field(default_factory=TiltConfig)
    accel_decimation: int = 5
    # gating
    gate_probability: float = 0.9999  # chi-square quantile: 1 dof -> 15.1, 2 dof -> 18.4
    max_consecutive_rejects: dict = field(default_factory=lambda: {
        "gnss": 16, "gnss_vel": 16, "mag": 100, "gyro": 50, "accel": 40})
    # timing
    max_step_s: float = 0.02  # prediction sub-step
    max_lag_s: float = 0.25  # older messages are skipped
    max_jump_s: float = 0.5  # a message further ahead of the filter is skipped until confirmed
    jump_confirm: int = 5  # messages in a row that far ahead: a real gap, the filter jumps
    max_coast_s: float = 10.0  # a longer gap is predicted this long; the rest only grows P
    inputs: InputConfig = field(default_factory=InputConfig)
    integrity: IntegrityConfig = field(default_factory=IntegrityConfig)
    origin: tuple[float, float, float] | None = None  # lat, lon, h; None: the first usable fix
    # initial uncertainty: N, E, psi, u, v, r, b_g, b_ax, b_ay; then current and force blocks
    P0_std: tuple[float, ...] = (100.0, 100.0, math.pi, 1.0, 0.5, 0.5, 0.03, 0.2, 0.2)
    # The current's start uncertainty: a lake's current is a few cm/s, 0.2 m/s a strong one. 0.2 (before
    # 2026-11-29) let a model's force error in the first seconds of a run become current before any turn
    # could tell the two apart, and the MPC, which flies the velocity through the water, then pushed
    # harder, which grew the error: hull B on the lab loop's identified model booked 0.9-1.0 m/s of
    # current in 5 s (true 0.08), lost its first turn by 57 cm and, over the seam, held on dead reckoning
    # (tests/physics/test_hull_b_experiment.py). 0.15: at most 0.16-0.23 m/s in the first 20 s (seeds
    # 0-3). Smaller values kept more of the error out (0.1: 0.15-0.20; 0.05: 0.11-0.14) but moved two
    # of the fault suite's marginal cases in Hs 6 cm to a failure (0.1: imu_bias seed 0, the frozen-
    # heading check at 0.24 of the gyro's turn against its 0.25; 0.05: current_toward_geofence seed 1,
    # GNSS declared inconsistent 1.75 s after power-up, before AUTO: the waves' orbital velocity, which the
    # wave states do not yet take while the wave band fills, went nowhere). A stronger current is learnt
    # through the walk.
    P0_current_std_mps: float = 0.15
    P0_tau_std: tuple[float, float, float] = (0.5, 0.5, 0.1)
    P0_wave_std: tuple[float, float] = (0.01, 0.01)  # m, rad (the rates: times the wave frequency)


class ModelAidedEKF:
    """Pure estimator: feed messages in stamp order, read `estimate(t)` and `health(t)`."""

    source = "ekf"

    def __init__(self, model: VesselModel | None = None, calibration: MagCalibration | None = None,
                 config: EkfConfig = EkfConfig(), initial: VesselState | None = None,
                 initial_std: tuple[float, ...] | None = None) -> None:
        self.model = model or VesselModel()
        self.calibration = calibration or MagCalibration.identity()
        self.config = c = config
        n = 7
        self.i_ba = n if c.accel_bias_states else None
        n += 2 if c.accel_bias_states else 0
        self.i_cur = n if c.current_states else None
        n += 2 if c.current_states else 0
        tau_states = c.disturbance_states or (c.wave_disturbance_states and c.wave_states)
        self.i_tau = n if tau_states else None
        n += 3 if tau_states else 0
        self.i_wave = n if c.wave_states else None
        n += 6 if c.wave_states else 0
        self.n = n
        self.x = np.zeros(n)
        std = list(c.P0_std[:7]) + (list(c.P0_std[7:9]) if c.accel_bias_states else [])
        std += [c.P0_current_std_mps] * 2 if c.current_states else []
        std += list(c.P0_tau_std) if c.disturbance_states else [0.0] * 3 if tau_states else []
        w0 = 2.0 * math.pi / c.wave_period_s
        if c.wave_states:
            ps, hs = c.P0_wave_std
            std += [ps, ps * w0, ps, ps * w0, hs, hs * w0]
        if initial_std is not None:  # the given values first, the rest from the config
            std[:len(initial_std)] = list(initial_std)[:n]
        self.P = np.diag(np.array(std, dtype=float) ** 2)
        self.t: float | None = None
        if initial is not None:
            self.x[:6] = initial.as_array_tuple()
            self.x[IBG] = initial.gyro_bias_radps
            if self.i_cur is not None:
                self.x[self.i_cur:self.i_cur + 2] = initial.current_ne_mps
            if self.i_tau is not None:
                self.x[self.i_tau:self.i_tau + 3] = initial.disturbance_tau
            self.t = initial.stamp_s
        self.inputs = ActuatorInputFilter(c.inputs)
        self.frame = FixFrame(c.origin)
        self.counters = Counters()
        self.monitor = IntegrityMonitor(c.integrity)
        self._rejects: dict[str, int] = {}
        self._jump: dict[str, np.ndarray] = {}  # last rejected innovation of a sensor that jumped
        self._gnss_track: tuple[float, float, float, float, float] | None = None  # t, N, E, vN, vE
        self._gnss_step_t = -math.inf  # stamp of the last step in the receiver's own track
        self._acc_sum = [0.0, 0.0]
        self._acc_n = 0
        self._future: list = []  # messages stamped beyond max_jump_s, held until confirmed
        self._gate = {k: chi2_quantile(c.gate_probability, k) for k in (1, 2)}
        q = [c.sigma_pos_mps ** 2, c.sigma_pos_mps ** 2, c.sigma_psi_radps ** 2,
             c.sigma_nu_dot[0] ** 2, c.sigma_nu_dot[1] ** 2, c.sigma_nu_dot[2] ** 2, c.sigma_gyro_bias_walk ** 2]
        q += [c.sigma_accel_bias_walk ** 2] * 2 if c.accel_bias_states else []
        q += [c.sigma_current_walk_mps ** 2] * 2 if c.current_states else []
        q += [s ** 2 for s in c.sigma_tau_walk] if c.disturbance_states else [0.0] * 3 if tau_states else []
        q += [0.0] * 6 if c.wave_states else []  # the wave states' noise: `_wave_transition`
        self._q = np.array(q)
        self.tilt = TiltFilter(c.tilt)
        self.wave_band = WaveBand(c.wave_band)
        self._wave_w0 = w0
        self._wave_w0_given: float | None = None  # from a sea-state estimate (`set_wave_frequency`)
        self._wave_cache: tuple | None = None
        # the body acceleration the tilt filter subtracts from the accelerometer: the receiver's velocity
        # differentiated (independent of the model, whose force errors would otherwise read as tilt),
        # the model's prediction while there is no GNSS velocity
        self._accel_pred = (0.0, 0.0)
        # the accelerometer's innovation averaged over model_error_time_s (surge, sway), its noise's
        # variance in that average, and the process noise it makes (EkfConfig.model_error_time_s)
        self._accel_innovation_mean = np.zeros(2)
        self._accel_innovation_t = -math.inf
        self._accel_error_q = np.zeros(2)
        # GNSS velocity's body-frame innovation: its running mean square and predicted variance (surge, sway)
        self._velocity_innovation_sq = np.zeros(2)
        self._velocity_innovation_var = np.zeros(2)
        self._velocity_innovation_t = -math.inf
        self._velocity_error_q = np.zeros(2)
        self._gnss_accepted_t = -math.inf  # the last accepted GNSS position (EkfConfig.force_learning_gnss_age_s)
        # the wave states' running mean over wave_mean_periods periods (`_track_wave_mean`)
        self._wave_mean = np.zeros(6)
        self._wave_mean_t = -math.inf
        self._innovation_cov = np.zeros((0, 0))  # S of the last update (`_update`)
        self._gnss_accel: tuple[float, float, float] | None = None  # (stamp, a_N, a_E)
        self._gnss_vel_prev: tuple[float, float, float] | None = None  # (stamp, v_N, v_E)
        self._body_rates_pq = (0.0, 0.0)  # the last gyro's x and y rates, offsets removed (the mast's swing)
        # what the gyro may move: the heading, its rate, the gyro's offset and the heading's wave states. A yaw
        # rate says nothing of the speed; through the covariance the thrusters' shared force uncertainty
        # builds between them, the gyro's wave-frequency innovations moved the surge speed by 0.33 m/s
        # in 0.8 s on the 6-DOF hull in Hs 10 cm (then GNSS velocity disagreed beyond its gate)
        self._gyro_moves = np.zeros(n, dtype=bool)
        self._gyro_moves[[IPSI, IR, IBG]] = True
        if self.i_wave is not None:
            self._gyro_moves[[self.i_wave + 4, self.i_wave + 5]] = True
        self._I = np.eye(n)
        p = self.model.params
        self._inv_m = (1.0 / p.m11, 1.0 / p.m22, 1.0 / p.m33)
        self._pending: list = []  # model inputs stamped ahead of the filter, applied when it gets there

    # -- model ---------------------------------------------------------------------------------
    @property
    def u_act(self) -> tuple[float, ...]:
        """The actuator values the prediction uses now (angles rad, speeds rev/s)."""
        return self.inputs.value()

    def _environment(self, x: np.ndarray) -> tuple[float, float, float, float, float]:
        cn = ce = tx = ty = tn = 0.0
        if self.i_cur is not None:
            cn, ce = float(x[self.i_cur]), float(x[self.i_cur + 1])
        if self.i_tau is not None:
            tx, ty, tn = (float(v) for v in x[self.i_tau:self.i_tau + 3])
        return cn, ce, tx, ty, tn

    def _dynamics_jacobian(self, x: np.ndarray, u: tuple[float, ...]) -> np.ndarray:
        """J = df/dx (6 x n) of the kinematics and kinetics with current and body force."""
        return self._jacobians(x, u)[0]

    def _jacobians(self, x: np.ndarray, u: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray]:
        """J = df/dx (6 x n) of the kinematics and kinetics with current and body force, and the
        model's input Jacobian B = df/du (6 x 5) at the same point.

        The calm-water Jacobian at the velocity relative to the water, nu_r = nu - nu_c, gives
        G = d nu_dot / d nu_r; with u_dot = g_u(nu_r) + r v_c, v_dot = g_v(nu_r) - r u_c and
        [u_c, v_c] = R(psi)^T [c_N, c_E], the chain rule adds the heading and current columns.
        """
        xl = x.tolist()
        psi, r = xl[2], xl[5]
        c, s = math.cos(psi), math.sin(psi)
        cn, ce = (xl[self.i_cur], xl[self.i_cur + 1]) if self.i_cur is not None else (0.0, 0.0)
        # the six vessel states: the model's Jacobian with the current (heading and r columns included)
        uf = tuple(float(v) for v in u)  # canonical types: the signature VesselModel.warm_up compiled
        A, B = _jacobians_current((xl[0], xl[1], psi, xl[3], xl[4], r), uf, self.model.arrays.packed, cn, ce)
        J = np.zeros((6, self.n))
        J[:, :6] = A
        if self.i_cur is not None:
            (g00, g01, _), (g10, g11, _), (g20, g21, _) = A[3:6, 3:6].tolist()
            ic = self.i_cur
            J[3, ic], J[4, ic], J[5, ic] = -g00 * c + g01 * s - r * s, -g10 * c + g11 * s - r * c, -g20 * c + g21 * s
            J[3, ic + 1], J[4, ic + 1], J[5, ic + 1] = (-g00 * s - g01 * c + r * c, -g10 * s - g11 * c - r * s,
                                                        -g20 * s - g21 * c)
        if self.i_tau is not None:
            it = self.i_tau
            J[3, it], J[4, it + 1], J[5, it + 2] = self._inv_m
        return J, B

    def _actuator_accel_cov(self, B: np.ndarray, u: tuple[float, ...], thrust_rel: float | None = None) -> np.ndarray:
        """Covariance (3 x 3) of [u_dot, v_dot, r_dot] from the actuators' uncertain forces:
        B S B' with S = diag(sigma_alpha^2 x 2, (sigma_thrust_rel / 2 |n_i|)^2 x 3)."""
        c = self.config
        k = 0.5 * (c.sigma_thrust_rel if thrust_rel is None else thrust_rel)
        s = np.array([c.sigma_azimuth_rad, c.sigma_azimuth_rad, k * u[2], k * u[3], k * u[4]])
        Bs = B[3:6] * s  # columns scaled by the inputs' standard deviations
        return Bs @ Bs.T

    def _rhs(self, x: np.ndarray, u: tuple[float, ...]) -> tuple[float, ...]:
        """f(x, u) of the six kinematic/kinetic states (RK4's first stage with dt = 0)."""
        model = self.model
        _, k1 = rk4_step((float(x[0]), float(x[1]), float(x[2]), float(x[3]), float(x[4]), float(x[5])),
                         u, model.arrays.packed, *self._environment(x), 0.0)
        return k1

    # -- prediction ------------------------------------------------------------------------------
    def _predict(self, x: np.ndarray, P: np.ndarray, t0: float, dt_total: float, inputs: ActuatorInputFilter,
                 pending: list | None = None) -> tuple[np.ndarray, np.ndarray]:
        """x, P from t0 to t0 + dt_total. The input emulation `inputs` advances with them, and the
        model inputs in `pending` ((stamp, message), in stamp order) are applied to it at their
        stamps (the filter's own pending list is consumed; pass a copy to leave it alone)."""
        t1 = t0 + dt_total
        t = t0
        while pending and pending[0][0] <= t1:
            stamp, msg = pending.pop(0)
            if stamp > t:
                x, P = self._predict_span(x, P, t, stamp - t, inputs)
                t = stamp
            self._apply_input(inputs, msg)
        if t1 > t:
            x, P = self._predict_span(x, P, t, t1 - t, inputs)
        return x, P

    def _predict_span(self, x: np.ndarray, P: np.ndarray, t0: float, dt_total: float,
                      inputs: ActuatorInputFilter) -> tuple[np.ndarray, np.ndarray]:
        model = self.model
        steps = max(1, int(math.ceil(dt_total / self.config.max_step_s - 1e-9)))
        dt = dt_total / steps
        n = self.n
        diag = slice(None, None, n + 1)
        q, thrust_rel = self._low_frequency_slack()
        model_error_q = self.model_error_q
        for k in range(steps):
            u = inputs.advance(t0 + (k + 1) * dt, dt)
            J, B = self._jacobians(x, u)
            xl = x.tolist()
            cn, ce, tx, ty, tn = self._environment(x)
            x1, _ = rk4_step((xl[0], xl[1], xl[2], xl[3], xl[4], xl[5]), u, model.arrays.packed,
                             cn, ce, tx, ty, tn, dt)
            x = x.copy()
            x[:6] = x1
            x[IPSI] = wrap_angle(x[IPSI])
            # P = F P F' + Q dt with F = I + G, G = J dt + (J dt)^2 / 2 nonzero in the first six rows
            G = J * dt
            G += 0.5 * (G[:, :6] @ G)
            GP = G @ P
            P = P.copy()
            P[:6] += GP
            P[:, :6] += GP.T
            P[:6, :6] += GP @ G.T
            P.flat[diag] += q * dt
            P[3, 3] += model_error_q[0] * dt
            P[4, 4] += model_error_q[1] * dt
            if self.config.sigma_thrust_rel > 0.0 or self.config.sigma_azimuth_rad > 0.0:
                P[3:6, 3:6] += self._actuator_accel_cov(B, u, thrust_rel) * (self.config.thrust_error_correlation_s * dt)
            if self.i_wave is not None:
                x, P = self._predict_waves(x, P, dt)
        return x, P

    def _low_frequency_slack(self) -> tuple[np.ndarray, float]:
        """The process noise densities and the thrusters' relative force uncertainty now: the
        calm values, tightened towards the wave values as the heave grows (EkfConfig)."""
        c = self.config
        q = self._q
        if self.i_tau is not None:
            walks = self._force_learns() and (c.disturbance_states or self._in_sea())
            q = q.copy()  # EkfConfig.disturbance_states, or wave_disturbance_states: only in a sea
            q[self.i_tau:self.i_tau + 3] = np.square(c.sigma_tau_walk) if walks else 0.0
        if self.i_wave is None or not c.wave_slack_heave_m > 0.0 or self._wave_w0_given is None:
            # only once the sea and the frequency it is met at are known (the sea-state estimate): a
            # tight model with the wrong wave frequency lost a hull thrown about by a following sea
            return q, c.sigma_thrust_rel
        w0 = self.wave_model()[0]
        lo, hi = c.wave_slack_frequency_radps
        s = min(1.0, self.wave_band.heave_std_m(w0) / c.wave_slack_heave_m) * min(1.0, max(0.0, (w0 - lo) / (hi - lo)))
        if s <= 0.0:
            return q, c.sigma_thrust_rel
        q = q.copy()
        for i in range(3):
            q[3 + i] = ((1.0 - s) * c.sigma_nu_dot[i] + s * c.wave_sigma_nu_dot[i]) ** 2
        return q, (1.0 - s) * c.sigma_thrust_rel + s * c.wave_sigma_thrust_rel

    def _in_sea(self) -> bool:
        """Whether the wave band's heave acceleration says there is a sea (EkfConfig.wave_accel_sea_heave_mps2):
        the one test behind the coloured accelerometer noise and the sea-only force states."""
        return self.i_wave is not None and self.wave_band.heave_accel_std_mps2 > self.config.wave_accel_sea_heave_mps2

    def _force_learns(self) -> bool:
        """Whether the body-force states may learn now: a GNSS fix accepted within
        EkfConfig.force_learning_gnss_age_s (not in dead reckoning)."""
        t = self.t if self.t is not None else 0.0
        return t - self._gnss_accepted_t <= self.config.force_learning_gnss_age_s

    # -- waves -----------------------------------------------------------------------------------
    def set_wave_frequency(self, w_radps: float | None) -> None:
        """The wave model's frequency (rad/s) from a sea-state estimate: the encounter frequency of the
        sea's peak at the present speed and heading. None: the wave band's own mean frequency again."""
        self._wave_w0_given = w_radps if w_radps is not None and math.isfinite(w_radps) and w_radps > 0 else None

    def wave_model(self) -> tuple[float, float, float]:
        """(w0 in rad/s, the position wave states' sigma in m, the heading's in rad) now (module docstring)."""
        c, band = self.config, self.wave_band
        lo, hi = c.wave_frequency_range_radps
        f = band.frequency_radps
        w_band = min(max(f if math.isfinite(f) else 2.0 * math.pi / c.wave_period_s, lo), hi)
        # the oscillator at the encounter frequency given (the sea state's peak at this heading and speed),
        # else the band's; the intensities from the band's own frequency (its accelerations and rates)
        w0 = min(max(self._wave_w0_given, lo), hi) if self._wave_w0_given is not None else w_band
        return (w0, max(c.wave_position_std_floor_m, c.wave_position_per_heave * band.heave_std_m(w_band)),
                max(c.wave_heading_std_floor_rad, c.wave_heading_per_tilt * band.tilt_std_rad(w_band)))

    def _wave_transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi, Q) of the six wave states over dt: the oscillator's exact transition per axis and
        its white acceleration's covariance (the double integrator's, w0 dt <= 0.4 here)."""
        w0, sp, sh = self.wave_model()
        key = (dt, w0, sp, sh)
        if self._wave_cache is not None and self._wave_cache[0] == key:
            return self._wave_cache[1], self._wave_cache[2]
        z = self.config.wave_damping
        wd = w0 * math.sqrt(1.0 - z * z)
        e = math.exp(-z * w0 * dt)
        cs, sn = math.cos(wd * dt), math.sin(wd * dt)
        phi = e * np.array([[cs + z * w0 / wd * sn, sn / wd], [-w0 * w0 / wd * sn, cs - z * w0 / wd * sn]])
        Phi = np.zeros((6, 6))
        Q = np.zeros((6, 6))
        q2 = np.array([[dt ** 3 / 3.0, dt * dt / 2.0], [dt * dt / 2.0, dt]])
        for i, sigma in enumerate((sp, sp, sh)):
            Phi[2 * i:2 * i + 2, 2 * i:2 * i + 2] = phi
            Q[2 * i:2 * i + 2, 2 * i:2 * i + 2] = 4.0 * z * w0 ** 3 * sigma * sigma * q2
        self._wave_cache = (key, Phi, Q)
        return Phi, Q

    def _predict_waves(self, x: np.ndarray, P: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The wave block of F P F' + Q (F is block diagonal: the vessel's states never depend on the waves')."""
        Phi, Q = self._wave_transition(dt)
        w = slice(self.i_wave, self.i_wave + 6)
        x = x.copy()
        x[w] = Phi @ x[w]
        P[w, :] = Phi @ P[w, :]
        P[:, w] = P[:, w] @ Phi.T
        P[w, w] += Q
        return x, P

    def _wave(self, k: int) -> float:
        """Wave state k (0-5: eta_N, eta_N_dot, eta_E, eta_E_dot, eta_psi, eta_psi_dot); 0 without them."""
        return float(self.x[self.i_wave + k]) if self.i_wave is not None else 0.0

    @property
    def wave_motion(self) -> tuple[float, float, float]:
        """The estimated wave-frequency displacement now: north (m), east (m), heading (rad)."""
        return (self._wave(0), self._wave(2), self._wave(4))

    def _advance(self, stamp: float, sensor: str, replay: tuple | None = None) -> bool:
        """Predict to `stamp`. False (and counted as skipped) if the message is stale or bad;
        False too for a message more than `max_jump_s` ahead of the filter: it is held, and
        replayed (through `replay` = (handler, message)) only if `jump_confirm` messages in a
        row are that far ahead (a real gap in the data); otherwise it was a bad stamp, dropped."""
        if not math.isfinite(stamp):
            self.counters.count("skipped", sensor)
            return False
        if self.t is None:
            self.t = stamp
            return True
        c = self.config
        dt = stamp - self.t
        if dt > c.max_jump_s:
            # one message far ahead of all the others is a bad stamp, not a reason to move the
            # filter (every later message would be stale); several in a row are a real gap
            self._future.append((stamp, sensor, replay))
            if len(self._future) < c.jump_confirm:
                return False
            held = sorted(self._future, key=lambda h: h[0])
            self._future = []
            first = held[0][0]
            gap = first - self.t
            self.monitor.event(first, f"fusion: time jumped {gap:.2f} s ahead ({len(held)} messages in a row)")
            coast = min(gap, c.max_coast_s)
            self.x, self.P = self._predict(self.x, self.P, self.t, coast, self.inputs, self._pending)
            if gap > coast:  # beyond the coast limit the model is not trusted; only P grows
                rest = gap - coast
                self.P.flat[::self.n + 1] += self._q * rest
                self.P[IU, IU] += 0.25 * rest
                self.P[IV, IV] += 0.25 * rest
                self.P[IR, IR] += 0.01 * rest
                self._pending = [p for p in self._pending if p[0] > first]
            self.t = first
            for _, s, rep in held:  # the held messages, the current one included, in stamp order
                if rep is not None:
                    rep[0](rep[1])
                else:
                    self.counters.count("skipped", s)
            return False
        if self._future:  # the far-ahead messages were not followed by others: bad stamps
            for _, s, _ in self._future:
                self.counters.count("skipped", s)
                self.counters.count("skipped", "future_stamp")
            self.monitor.event(self.t, f"fusion: {len(self._future)} message(s) stamped "
                                                    f"{self._future[0][0] - self.t:.2f} s ahead skipped")
            self._future = []
        if dt > 0.0:
            self.x, self.P = self._predict(self.x, self.P, self.t, dt, self.inputs, self._pending)
            self.t = stamp
        elif dt < -c.max_lag_s:
            self.counters.count("skipped", sensor)
            self.counters.count("skipped", "stale")
            return False
        return True

    # -- update ----------------------------------------------------------------------------------
    def _update(self, sensor: str, y: np.ndarray, H: np.ndarray, R: np.ndarray,
                reopen: tuple[int, ...] = (), moves: np.ndarray | None = None) -> bool:
        """Gated EKF update. y = z - h(x). After many consecutive rejections, re-opens (inflating
        the covariance of the states in `reopen` by the innovation) if the monitor allows it.
        `moves` (a boolean mask): the only states the update may change; the others are considered,
        not estimated, by this measurement (the Schmidt-Kalman filter: their gain is zero and the
        covariance is the Joseph form's for that gain, so it stays consistent)."""
        P = self.P
        PHt = P @ H.T
        S = H @ PHt + R
        self._innovation_cov = S  # the last update's, for what a caller derives from its innovation
        m = len(y)
        if m == 1:
            s00 = float(S[0, 0])
            if not s00 > 0.0:
                self.counters.count("skipped", sensor)
                return False
            Sinv = np.array([[1.0 / s00]])
            d2 = float(y[0]) ** 2 / s00
        else:
            try:
                Sinv = np.linalg.inv(S)
            except np.linalg.LinAlgError:
                self.counters.count("skipped", sensor)
                return False
            d2 = float(y @ Sinv @ y)
        if not math.isfinite(d2):
            self.counters.count("skipped", sensor)
            return False
        t = self.t if self.t is not None else 0.0
        gate = self._gate[m]
        # A sensor that jumped away from an estimate it agreed with comes back only when it is
        # nearer its old agreement than the jump: y . d < |d|^2 / 2, d = the last rejected
        # innovation. Without this, dead reckoning widens the gate until a persistent offset
        # fits inside it and is accepted (10 m after ~110 s in the 10 m / 120 s case).
        jump = self._jump.get(sensor)
        still_jumped = (d2 <= gate and jump is not None and self.monitor.rejecting(sensor)
                        and float(y @ jump) >= 0.5 * float(jump @ jump))
        if d2 > gate or still_jumped:
            if not still_jumped and self.monitor.config.reopen_policy.get(sensor) == "reacquire":
                self._jump[sensor] = np.array(y, dtype=float)
            k = self._rejects.get(sensor, 0) + 1
            self._rejects[sensor] = k
            self.counters.count("rejected", sensor)
            self.monitor.test(sensor, t, gate if still_jumped else d2, m, gate, False)
            k_max = self.config.max_consecutive_rejects.get(sensor, 50)
            if self.monitor.reacquiring(sensor):
                k_max = min(k_max, self.config.integrity.reacquire_rejects)
            if k >= k_max and reopen and (self.monitor.reopen_allowed(sensor, t) or self._estimate_suspect(sensor, t)):
                # the estimate is the suspect (start, after an outage, operator): believe the
                # sensor again, at the size of the disagreement
                big = float(np.max(np.abs(y)))
                inflate = big ** 2 + float(np.max(np.diag(R)))
                for i in reopen:
                    self.P[i, :] *= 0.0
                    self.P[:, i] *= 0.0
                    self.P[i, i] = inflate * 4.0
                self._rejects[sensor] = 0
                self._jump.pop(sensor, None)
                self.monitor.reopened(sensor, t, f"{sensor}: gate re-opened after {k} rejections "
                                                 f"(disagreement {big:.3g})")
            return False
        self._rejects[sensor] = 0
        self._jump.pop(sensor, None)
        it = self.i_tau
        if it is not None and not self._force_learns() and P[it, it] + P[it + 1, it + 1] + P[it + 2, it + 2] > 0.0:
            # dead reckoning: the force (if it has learnt at all) is considered, held
            moves = np.ones(self.n, dtype=bool) if moves is None else moves.copy()
            moves[it:it + 3] = False
        K = PHt @ Sinv  # K = P H' S^-1
        if moves is not None:  # the considered states' gain is zero: P - K PHt' - PHt K' + K S K'
            K = K * moves[:, None]
            KPHt = K @ PHt.T
            Pn = P - KPHt - KPHt.T + K @ S @ K.T
        else:
            Pn = P - K @ PHt.T  # P - K S K' (exactly symmetric for one dof)
        x = self.x + K @ y  # x = x + K y
        if m > 1 or moves is not None:
            Pn = 0.5 * (Pn + Pn.T)
        if min(Pn.diagonal().tolist()) <= 0.0:  # round-off: fall back to the Joseph form
            IKH = self._I - K @ H
            Pn = IKH @ P @ IKH.T + K @ R @ K.T
        if not math.isfinite(float(x.sum()) + float(Pn.trace())):
            self.counters.count("skipped", sensor)
            return False
        x[IPSI] = wrap_angle(x[IPSI])
        if self.i_cur is not None:
            ic = self.i_cur
            sp = math.hypot(x[ic], x[ic + 1])
            if sp > self.config.max_current_mps:
                x[ic:ic + 2] *= self.config.max_current_mps / sp
        self.x, self.P = x, Pn
        self.counters.count("used", sensor, t)
        self.monitor.test(sensor, t, d2, m, gate, True)
        self.monitor.used(sensor, t)
        return True

    def _estimate_suspect(self, sensor: str, t: float) -> bool:
        """The sensor is self-consistent, so a rejection streak means the estimate diverged:
        GNSS position without a step in its own track since just before the streak began; GNSS
        velocity while the position of the same receiver agrees with the estimate."""
        if sensor == "gnss":
            start = self.monitor.streak_start("gnss")
            return (start is not None and self._gnss_track is not None
                    and not self._gnss_step_t >= start - self.config.integrity.reacquire_gap_s)
        if sensor == "gnss_vel":
            return not (self.monitor.rejecting("gnss") or self.monitor.inconsistent("gnss"))
        return False

    def _gnss_self_check(self, t: float, n: float, e: float, fix: GnssFix, sigma_m: float) -> None:
        """Track the receiver's own consistency (position step against its Doppler velocity)."""
        vn, ve = fix.vel_n_mps, fix.vel_e_mps
        prev = self._gnss_track
        if not finite(vn, ve):
            self._gnss_track = None
            self._gnss_step_t = t  # nothing to check against: a rejection streak counts as a jump
            return
        if prev is not None and 0.0 < t - prev[0] <= 1.0:
            dt = t - prev[0]
            step = math.hypot(n - prev[1] - 0.5 * (vn + prev[3]) * dt, e - prev[2] - 0.5 * (ve + prev[4]) * dt)
            if step > max(self.config.gnss_step_m, 5.0 * sigma_m):
                self._gnss_step_t = t
        elif prev is None or t - prev[0] > 1.0:
            self._gnss_step_t = t  # a gap: what happened in it is unknown
        self._gnss_track = (t, n, e, vn, ve)

    # -- messages --------------------------------------------------------------------------------
    def on_command(self, m: ThrustCommand | ActuatorState) -> None:
        """Model input. A ThrustCommand (set-point) drives the actuator emulation; an
        ActuatorState (achieved servo angles, measured propeller speeds, ESCs armed) corrects it
        (see lotsen.fusion.inputs). Applied at its stamp: an input stamped ahead of the filter
        waits until a sensor sample brings the filter there (no prediction of its own)."""
        if not finite(m.stamp_s, *m.as_tuple()):
            self.counters.count("skipped", "command")
            return
        self._queue_input(m, "actuators" if isinstance(m, ActuatorState) else "command")

    def on_rpm(self, m: RpmSample) -> None:
        """Measured propeller speeds (tachometers) alone, for a stack without ActuatorState."""
        if not finite(m.stamp_s, m.n1_rps, m.n2_rps, m.nt_rps):
            self.counters.count("skipped", "rpm")
            return
        self._queue_input(m, "rpm")

    def _queue_input(self, m: ThrustCommand | ActuatorState | RpmSample, kind: str) -> None:
        stamp = m.stamp_s
        if self.t is None:
            self.t = stamp
        c = self.config
        if stamp > self.t + c.max_jump_s or stamp < self.t - c.max_lag_s:
            self.counters.count("skipped", kind)
            self.counters.count("skipped", "future_stamp" if stamp > self.t else "stale")
            return
        if stamp <= self.t:
            self._apply_input(self.inputs, m)
        else:
            pend = self._pending
            i = len(pend)
            while i > 0 and pend[i - 1][0] > stamp:
                i -= 1
            pend.insert(i, (stamp, m))
            if len(pend) > 256:  # inputs but no sensor samples: move the filter along with them
                self._advance(pend[0][0], kind)
        self.counters.count("inputs", kind, stamp)

    @staticmethod
    def _apply_input(inputs: ActuatorInputFilter, m: ThrustCommand | ActuatorState | RpmSample) -> None:
        if isinstance(m, ActuatorState):
            inputs.set_armed(m.escs_armed)
            inputs.set_angles(m.stamp_s, m.alpha1_rad, m.alpha2_rad)
            inputs.measure_speeds(m.stamp_s, (m.n1_rps, m.n2_rps, m.nt_rps))
        elif isinstance(m, RpmSample):
            inputs.measure_speeds(m.stamp_s, (m.n1_rps, m.n2_rps, m.nt_rps))
        else:
            inputs.set_command(m.stamp_s, m.as_tuple())

    def on_imu(self, m: ImuSample) -> None:
        gz = self._heading_rate(m.gyro_radps)
        mon = self.monitor
        if not self._advance(m.stamp_s, "gyro", (self.on_imu, m)):
            if not math.isfinite(m.stamp_s):
                self.counters.count("skipped", "accel")
            return
        mon.raw("gyro", m.stamp_s, m.gyro_radps)
        mon.raw("accel", m.stamp_s, m.accel_mps2)
        c = self.config
        accel_ok = finite(*m.accel_mps2) and not mon.stuck("accel")
        if accel_ok and finite(*m.gyro_radps) and not mon.stuck("gyro"):
            self.tilt.update(m.stamp_s, m.gyro_radps, m.accel_mps2, self._known_accel(m.stamp_s))
            self._body_rates_pq = (m.gyro_radps[0] - self.tilt.bias_p, m.gyro_radps[1] - self.tilt.bias_q)
        ax, ay = (self.tilt.level(m.accel_mps2) if c.tilt_compensation and accel_ok
                  else (m.accel_mps2[0], m.accel_mps2[1]))
        if accel_ok:
            self.wave_band.update(m.stamp_s, m.gyro_radps, m.accel_mps2[2])
        if not finite(gz) or mon.stuck("gyro"):
            self.counters.count("skipped", "gyro")
        else:
            H = np.zeros((1, self.n))
            H[0, IR] = 1.0
            H[0, IBG] = 1.0
            y = gz - self.x[IR] - self.x[IBG]
            if self.i_wave is not None:  # the gyro feels the wave-frequency yaw rate too
                H[0, self.i_wave + 5] = 1.0
                y -= self.x[self.i_wave + 5]
            ok = self._update("gyro", np.array([y]), H, np.array([[c.sigma_gyro_radps ** 2]]), reopen=(IBG, IR),
                              moves=self._gyro_moves)
            self._track_wave_mean()
            # the frozen-heading test integrates the gyro the filter believed: a spike the gate
            # rejected stands in with the filter's own rate (else one spike "turns" the boat); the
            # heading is the whole one, wave-frequency motion included, as the gyro's is
            mon.heading(self.t, float(self.x[IPSI]) + self._wave(4),
                        gz - float(self.x[IBG]) if ok else float(self.x[IR]) + self._wave(5))
        if not c.use_accel:
            return
        if not accel_ok:
            self.counters.count("skipped", "accel")
            return
        self._acc_sum[0] += ax
        self._acc_sum[1] += ay
        self._acc_n += 1
        if self._acc_n >= self.config.accel_decimation:
            a = (self._acc_sum[0] / self._acc_n, self._acc_sum[1] / self._acc_n)
            self._acc_sum = [0.0, 0.0]
            self._acc_n = 0
            self._accel_update(a)

    def _heading_rate(self, gyro_radps: tuple[float, float, float]) -> float:
        """What the model's r is, the heading's rate, from the body rates and the tilt (ZYX Euler
        kinematics, Fossen 2021 eq. 2.41): (q sin(roll) + r cos(roll)) / cos(pitch). On a hull rolling
        and pitching at wave frequency the body z rate alone is not it: the product of the roll and
        pitch oscillations leaves a mean (coning), and the integrated heading wanders off the compass.
        The tilt filter's y-offset is removed from q; r keeps its own (the gyro bias state)."""
        p, q, r = gyro_radps
        if not self.config.tilt_compensation or not finite(q):
            return r
        ph, th = self.tilt.roll_rad, self.tilt.pitch_rad
        return ((q - self.tilt.bias_q) * math.sin(ph) + r * math.cos(ph)) / math.cos(th)

    def _known_accel(self, t: float) -> tuple[float, float]:
        """The body acceleration in the plane the tilt filter takes as known: the GNSS velocity's
        rate of change turned into body axes while it is fresh, else the model's prediction."""
        g = self._gnss_accel
        if g is None or not 0.0 <= t - g[0] <= 0.5:
            return self._accel_pred
        c, s = math.cos(self.x[IPSI]), math.sin(self.x[IPSI])
        return (c * g[1] + s * g[2], -s * g[1] + c * g[2])

    def _track_gnss_velocity(self, fix: GnssFix) -> None:
        """The receiver's acceleration from consecutive velocities (for the tilt filter)."""
        prev = self._gnss_vel_prev
        if not finite(fix.vel_n_mps, fix.vel_e_mps):
            self._gnss_vel_prev = None
            return
        if prev is not None and 0.0 < fix.stamp_s - prev[0] <= 0.5:
            dt = fix.stamp_s - prev[0]
            self._gnss_accel = (fix.stamp_s, (fix.vel_n_mps - prev[1]) / dt, (fix.vel_e_mps - prev[2]) / dt)
        self._gnss_vel_prev = (fix.stamp_s, fix.vel_n_mps, fix.vel_e_mps)

    def _accel_update(self, a: tuple[float, float]) -> None:
        x = self.x
        u_in = self.inputs.value()
        f = self._rhs(x, u_in)
        J, B = self._jacobians(x, u_in)
        u, v, r = x[IU], x[IV], x[IR]
        h = np.array([f[3] - v * r, f[4] + u * r])  # specific force of a level boat, body frame
        H = np.zeros((2, self.n))
        H[0] = J[3]
        H[1] = J[4]
        H[0, IV] -= r
        H[0, IR] -= v
        H[1, IU] += r
        H[1, IR] += u
        reopen: tuple[int, ...] = (IU, IV, IR)
        self._accel_pred = (float(h[0]), float(h[1]))  # the tilt filter's known acceleration
        if self.i_ba is not None:
            h += x[self.i_ba:self.i_ba + 2]
            H[0, self.i_ba] = 1.0
            H[1, self.i_ba + 1] = 1.0
            reopen += (self.i_ba, self.i_ba + 1)
        # the accelerometer feels the actuators' true force, the model predicts their modelled one;
        # and it feels the waves' acceleration, which no state predicts well (the wave model's is
        # broadband): the wave band's measured variance is measurement noise
        R = np.eye(2) * self.config.sigma_accel_mps2 ** 2 + self._actuator_accel_cov(B, u_in)[:2, :2]
        R_coloured = np.zeros((2, 2))
        if self.i_wave is not None:  # horizontal wave accelerations are about the heave's (circular orbits)
            heave = self.wave_band.heave_accel_std_mps2
            R += np.eye(2) * heave ** 2
            # ... and narrow-band: one wave's acceleration is in many updates in a row (EkfConfig.
            # wave_accel_correlated_samples), which a white-noise update takes for independent evidence
            if self._in_sea():
                R_coloured = np.eye(2) * (max(self.config.wave_accel_correlated_samples, 1.0) - 1.0) * heave ** 2
        # a model force error GNSS velocity has shown is in the model's acceleration too: else the
        # accelerometer pulls the velocity back to where the wrong model's forces balance (hull B: the
        # sway 0.35 m/s off within 0.2 s of each fix once its process noise had freed it)
        if self.config.model_error_time_s > 0.0:  # 0: the matching is off (qv / 0 made R NaN: no accelerometer)
            qv = self._velocity_error_q_now()
            R[0, 0] += qv[0] / self.config.model_error_time_s
            R[1, 1] += qv[1] / self.config.model_error_time_s
        y = np.array(a) - h
        if self._update("accel", y, H, R + R_coloured, reopen=reopen):  # a spike the gate rejects is no model error
            # the model-error test keeps the per-sample noise: its own running mean is what averages the waves
            self._track_model_error(y, self._innovation_cov - R_coloured)

    def _track_model_error(self, y: np.ndarray, S: np.ndarray) -> None:
        """The low-frequency model's force error from the accelerometer (EkfConfig.model_error_time_s):
        the innovation's running mean; beyond model_error_sigmas of the mean's own noise (for white
        innovations of covariance S the mean's variance is S k / (2 - k)), its square is process noise."""
        c = self.config
        if not c.model_error_time_s > 0.0 or not np.all(np.isfinite(y)):
            return
        t = self.t if self.t is not None else 0.0
        dt, self._accel_innovation_t = t - self._accel_innovation_t, t
        k = min(1.0, max(0.0, dt) / c.model_error_time_s)
        m = self._accel_innovation_mean
        m += k * (y - m)
        noise = np.sqrt(np.clip(np.diag(S), 0.0, None) * k / (2.0 - k))
        excess = np.clip(np.abs(m) - c.model_error_sigmas * noise, 0.0, None)
        self._accel_error_q = excess * excess * c.model_error_time_s

    def _track_wave_mean(self) -> None:
        """The wave states' running mean over T = wave_mean_periods periods of the wave model
        (EkfConfig.wave_mean_periods): an oscillator's own mean over T is about its amplitude / T, so
        what stays there is slow motion the low-frequency states did not take."""
        c, iw = self.config, self.i_wave
        if iw is None or not c.wave_mean_periods > 0.0:
            return
        t = self.t if self.t is not None else 0.0
        dt, self._wave_mean_t = t - self._wave_mean_t, t
        if self._wave_w0_given is None or self.monitor.faulty("gyro") or self.monitor.faulty("mag"):
            # no sea (the sea-state estimate gives no encounter frequency: in flat water the states sleep
            # at their floors), or the heading's two sensors disagree: slow content in the wave states
            # may then be the fault (a gyro offset the wave rate took), not the hull's motion
            self._wave_mean[:] = 0.0
            return
        T = c.wave_mean_periods * 2.0 * math.pi / self.wave_model()[0]
        self._wave_mean += min(1.0, max(0.0, dt) / T) * (self.x[iw:iw + 6] - self._wave_mean)

    def _track_velocity_error(self, y: np.ndarray, S: np.ndarray, psi: float) -> None:
        """The model's velocity error from GNSS velocity (EkfConfig.velocity_error_matching), by
        covariance matching: the body-frame innovation's running mean square against the variance the
        filter predicts without this process noise (S less the q dt it added since the last fix). For
        consistent innovations their ratio averages 1 with spread sqrt(2 k / (2 - k)) (chi-square, 1
        dof); beyond model_error_sigmas of that, the whole excess is the velocity error that builds up
        between fixes: process noise excess / dt. (With the receiver believed, the velocity's error
        before an update is the model's drift over one fix interval.) At the fixed point the mean square
        is the predicted variance, so q neither runs away nor switches off while the error lasts."""
        c = self.config
        if not (c.velocity_error_matching and c.model_error_time_s > 0.0) or not np.all(np.isfinite(y)):
            return
        if self.i_wave is not None and not self.wave_band.ready:
            # until the wave band has its first time constant of data the wave states do not yet take
            # the orbital velocity out of the innovation: in a sea it read as a model error, and the
            # current learnt then cost dead reckoning after a GNSS jump (Hs 6 cm: 2.35 m against 1.71)
            return
        t = self.t if self.t is not None else 0.0
        # a heading error turns the velocity over ground sideways just as a sway error does: only while
        # the compass vouches for the heading is the residual the model's (a 17 deg/s gyro bias in Hs 6 cm
        # was otherwise taken as a sway error, and the compass declared it after 11.6 s instead of 4.6)
        mag_nis = self.monitor.window_figures("mag", t)[0]
        if not mag_nis <= c.integrity.nis_limit.get("mag", 4.0) / 2.0:
            self._velocity_error_q = np.zeros(2)
            return
        dt, self._velocity_innovation_t = t - self._velocity_innovation_t, t
        if not dt > 0.0:
            return
        dt = min(dt, c.model_error_time_s)
        k = dt / c.model_error_time_s
        cs, sn = math.cos(psi), math.sin(psi)
        Rb = np.array([[cs, sn], [-sn, cs]])  # north-east -> body (surge, sway)
        yb = Rb @ y
        base = np.clip(np.diag(Rb @ S @ Rb.T) - self._velocity_error_q * dt, 1e-12, None)
        self._velocity_innovation_sq += k * (yb * yb - self._velocity_innovation_sq)
        self._velocity_innovation_var += k * (base - self._velocity_innovation_var)
        limit = 1.0 + c.model_error_sigmas * math.sqrt(2.0 * k / (2.0 - k))
        ms, var = self._velocity_innovation_sq, self._velocity_innovation_var
        self._velocity_error_q = np.where(ms > limit * var, (ms - var) / dt, 0.0)

    @property
    def model_error_q(self) -> np.ndarray:
        """Surge and sway process noise from the model's own error now ((m/s^2)^2 s): the larger of
        what the accelerometer and GNSS velocity show (one error, seen by two sensors)."""
        return np.maximum(self._accel_error_q, self._velocity_error_q_now())

    def _velocity_error_q_now(self) -> np.ndarray:
        """GNSS velocity's share, while it keeps showing the error: not in dead reckoning (after a GNSS
        jump, Hs 6 cm: held on, it let the accelerometer go and the 20 s of dead reckoning drifted 2.35 m
        instead of 1.71)."""
        t = self.t if self.t is not None else 0.0
        fresh = t - self._velocity_innovation_t <= self.config.model_error_time_s
        return self._velocity_error_q if fresh else np.zeros(2)

    def on_mag(self, m: MagSample) -> None:
        mx, my = m.field_uT[0], m.field_uT[1]
        if not finite(mx, my):
            self.counters.count("skipped", "mag")
            return
        if not self._advance(m.stamp_s, "mag", (self.on_mag, m)):
            return
        self.monitor.raw("mag", m.stamp_s, m.field_uT)
        if self.monitor.stuck("mag"):
            self.counters.count("skipped", "mag")
            return
        wx, wy = self.calibration.apply(mx, my)
        gate = self._gate[1]
        if abs(math.hypot(wx, wy) - 1.0) > self.config.mag_norm_tolerance:
            self.counters.count("rejected", "mag")  # disturbed field (motor currents, steel nearby)
            self.monitor.test("mag", self.t, math.inf, 1, gate, False)
            return
        z = wrap_angle(math.atan2(-wy, wx) + self.calibration.heading_offset_rad)
        self.monitor.compass(self.t, z)
        H = np.zeros((1, self.n))
        H[0, IPSI] = 1.0
        if self.i_wave is not None:
            H[0, self.i_wave + 4] = 1.0
        y = np.array([wrap_angle(z - self.x[IPSI] - self._wave(4))])  # innovation across +-180 deg
        self._update("mag", y, H, np.array([[self.config.sigma_mag_heading_rad ** 2]]), reopen=(IPSI,))

    def on_gnss(self, fix: GnssFix) -> None:
        if not fix.usable or not finite(fix.stamp_s, fix.lat_deg, fix.lon_deg):
            self.counters.count("skipped", "gnss")
            return
        if not self._advance(fix.stamp_s, "gnss", (self.on_gnss, fix)):
            return
        mon = self.monitor
        if finite(fix.vel_n_mps, fix.vel_e_mps):
            moving = math.hypot(self.x[IU], self.x[IV]) > 0.1  # a receiver may hold its velocity at rest
            mon.raw("gnss", fix.stamp_s, (fix.vel_n_mps, fix.vel_e_mps), active=moving)
        if mon.stuck("gnss"):
            self.counters.count("skipped", "gnss")
            self.counters.count("skipped", "gnss_vel")
            return
        n, e = self.frame.to_ne(fix.lat_deg, fix.lon_deg, fix.height_m)
        self._track_gnss_velocity(fix)
        noise = self.config.gnss_noise
        s = noise.position_sigma_m(fix)
        self._gnss_self_check(fix.stamp_s, n, e, fix, s)
        iw = self.i_wave
        psi_all = self.x[IPSI] + self._wave(4)
        dn, de = lever_arm_ne(psi_all, self.config.gnss_antenna_m)
        hm = self.config.gnss_antenna_height_m
        swing = lever_arm_ne(psi_all, mast_swing_body(hm, self.tilt.roll_rad, self.tilt.pitch_rad)) if hm else (0.0, 0.0)
        H = np.zeros((2, self.n))
        H[0, IN] = H[1, IE] = 1.0
        H[0, IPSI], H[1, IPSI] = -de, dn  # the lever arm turns with psi
        if iw is not None:  # and with the wave-frequency heading; the antenna moves with the waves
            H[0, iw + 4], H[1, iw + 4] = -de, dn
            H[0, iw], H[1, iw + 2] = 1.0, 1.0
        y = np.array([n - (self.x[IN] + self._wave(0) + dn + swing[0]), e - (self.x[IE] + self._wave(2) + de + swing[1])])
        if self._update("gnss", y, H, np.eye(2) * s * s, reopen=(IN, IE)):
            self._gnss_accepted_t = self.t
        if not (self.config.use_gnss_velocity and finite(fix.vel_n_mps, fix.vel_e_mps)):
            return
        if mon.rejecting("gnss") or mon.inconsistent("gnss"):
            # the receiver's position jumped away from an estimate it agreed with: its velocity
            # (same receiver, same message) is not trusted either until the position agrees again
            self.counters.count("skipped", "gnss_vel")
        else:
            psi, r = self.x[IPSI], self.x[IR] + self._wave(5)
            ax, ay = self.config.gnss_antenna_m
            u, v = self.x[IU] - r * ay, self.x[IV] + r * ax  # the antenna's body velocity
            c, sn = math.cos(psi), math.sin(psi)
            if hm:  # the mast's swing velocity (-h q, h p) in body axes
                p_, q_ = self._body_rates_pq
                u, v = u - hm * q_, v + hm * p_
            h = np.array([c * u - sn * v + self._wave(1), sn * u + c * v + self._wave(3)])
            Hv = np.zeros((2, self.n))
            Hv[0, IPSI], Hv[0, IU], Hv[0, IV], Hv[0, IR] = -sn * u - c * v, c, -sn, -c * ay - sn * ax
            Hv[1, IPSI], Hv[1, IU], Hv[1, IV], Hv[1, IR] = c * u - sn * v, sn, c, -sn * ay + c * ax
            if iw is not None:  # the wave-frequency velocity, and the yaw rate's swing of the antenna
                Hv[0, iw + 1], Hv[1, iw + 3] = 1.0, 1.0
                Hv[0, iw + 5], Hv[1, iw + 5] = Hv[0, IR], Hv[1, IR]
            sv = noise.velocity_floor_mps * noise.inflation.get(fix.fix_type, 3.0)
            y = np.array([fix.vel_n_mps, fix.vel_e_mps]) - h
            if self._update("gnss_vel", y, Hv, np.eye(2) * sv * sv, reopen=(IU, IV)):
                self._track_velocity_error(y, self._innovation_cov, psi)  # a rejected jump is no model error

    def reset_integrity(self, t: float, sensor: str | None = None) -> None:
        """Operator: forget a declared inconsistency (of `sensor`, or all) and let the gate
        re-open on the next rejection streak (e.g. accept a GNSS that moved for good)."""
        self.monitor.reset(t, sensor)

    # -- output ----------------------------------------------------------------------------------
    @property
    def gyro_bias_radps(self) -> float:
        return float(self.x[IBG])

    @property
    def current_ne_mps(self) -> tuple[float, float]:
        if self.i_cur is None:
            return (0.0, 0.0)
        return (float(self.x[self.i_cur]), float(self.x[self.i_cur + 1]))

    def estimate(self, t: float | None = None) -> VesselState:
        """The estimate predicted to `t` (the filter itself is not advanced)."""
        x, P, stamp = self.x, self.P, self.t if self.t is not None else (t or 0.0)
        if t is not None and self.t is not None and t > self.t:
            x, P = self._predict(x, P, self.t, min(t - self.t, self.config.max_coast_s), self.inputs.copy(),
                                 list(self._pending))
            stamp = t
        var = np.clip(np.diag(P)[:6], 0.0, None)
        wave = (0.0, 0.0, 0.0)
        iw = self.i_wave
        if iw is not None:  # where the boat is: the low-frequency pose plus the wave displacement
            wave = (float(x[iw]), float(x[iw + 2]), float(x[iw + 4]))
            for i, k in ((IN, iw), (IE, iw + 2), (IPSI, iw + 4)):
                var[i] = max(0.0, var[i] + P[k, k] + 2.0 * P[i, k])
        std = np.sqrt(var)
        cn, ce, tx, ty, tn = self._environment(x)
        lf = x[:6].copy()
        if iw is not None:  # the wave states' slow part is low-frequency motion (EkfConfig.wave_mean_periods)
            m = self._wave_mean
            cs, sn = math.cos(lf[IPSI]), math.sin(lf[IPSI])
            lf += (m[0], m[2], m[4], cs * m[1] + sn * m[3], -sn * m[1] + cs * m[3], m[5])
            wave = (wave[0] - float(m[0]), wave[1] - float(m[2]), wave[2] - float(m[4]))
        return VesselState(stamp_s=float(stamp), north_m=float(lf[0]), east_m=float(lf[1]),
                           heading_rad=float(wrap_angle(lf[2])), u_mps=float(lf[3]), v_mps=float(lf[4]),
                           r_radps=float(lf[5]), source=self.source, std=tuple(float(s) for s in std),
                           gyro_bias_radps=float(x[IBG]), current_ne_mps=(cn, ce),
                           # the sea-only force (wave_disturbance_states) stays the filter's own: fed forward by
                           # the station keeper it followed the waves' groups (reversals 1.0 -> 3.3 x calm)
                           disturbance_tau=(tx, ty, tn) if self.config.disturbance_states else (0.0, 0.0, 0.0),
                           wave_motion=wave)

    def health(self, t: float | None = None) -> EstimatorHealth:
        """Integrity of the estimate at time `t` (the caller's clock; default: the filter's time).
        The contract (flags, fault codes, when they go false and back) is in docs/fusion.md."""
        t = float(t) if t is not None else (self.t if self.t is not None else 0.0)
        mon, c = self.monitor, self.config.integrity
        state_finite = bool(np.all(np.isfinite(self.x)) and np.all(np.isfinite(self.P)))
        faults = mon.faults(t, self.t, state_finite)
        codes = {code for code, _ in faults}
        d = np.diag(self.P)
        std = np.sqrt(np.clip(d, 0.0, None)) if state_finite else np.full(self.n, math.inf)
        pos_std, hdg_std, vel_std = float(max(std[IN], std[IE])), float(std[IPSI]), float(max(std[IU], std[IV]))
        common = bool(codes & FUSION_FAULTS)
        # the heading between magnetometer samples and the yaw rate the controllers use come from
        # the gyro: without a healthy gyro the heading is not trustworthy (the magnetometer alone,
        # at its rate and with its disturbances, does not carry a controller)
        no_heading_sensor = mon.faulty("gyro")
        position_ok = not common and "gnss.inconsistent" not in codes and pos_std <= c.max_position_std_m
        heading_ok = (not common and "heading.frozen" not in codes and not no_heading_sensor
                      and hdg_std <= c.max_heading_std_rad)
        velocity_ok = not common and vel_std <= c.max_velocity_std_mps
        sensors = mon.sensors
        figures = [mon.window_figures(s, t) for s in sensors]
        cur_std = (math.nan, math.nan)
        if self.i_cur is not None and state_finite:
            cur_std = (float(std[self.i_cur]), float(std[self.i_cur + 1]))
        return EstimatorHealth(
            stamp_s=t, position_ok=position_ok, heading_ok=heading_ok, velocity_ok=velocity_ok,
            faults=tuple(text for _, text in faults), fault_codes=tuple(code for code, _ in faults),
            source=self.source, sensors=sensors, nis=tuple(f[0] for f in figures),
            used_frac=tuple(f[1] for f in figures),
            last_used_age_s=tuple(t - mon.last_used.get(s, -math.inf) for s in sensors),
            filter_age_s=t - self.t if self.t is not None else math.inf,
            position_std_m=pos_std, heading_std_rad=hdg_std, velocity_std_mps=vel_std,
            current_ne_mps=self.current_ne_mps, current_std_mps=cur_std,
            event_count=mon.event_count, events=tuple(mon.events))
