"""The sea state from the boat's own IMU: significant wave height, peak period and the direction the
waves come from, the hull used as a wave buoy (docs/fusion.md "Sea state").

Inputs: the IMU's heave acceleration (the accelerometer's z axis plus g), its roll and pitch rates and
its horizontal axes levelled by the navigation filter's tilt (lotsen.fusion.attitude), decimated to
`rate_hz` (means of the samples in each interval), the last `window_s` of them; the boat's heading and
speed from the state estimate. Every `update_s` the spectra are estimated by
Welch's method (Hann windows of `segment_s`, half overlapping; numpy's FFT) and, within the wave band
`band_hz`:

- direction (a displacement buoy's method, Longuet-Higgins, Cartwright and Smith 1963, with the
  hull's horizontal motion): the water's orbit is a circle in the vertical plane of the waves'
  travel, and a hull shorter than the waves goes round with it: its horizontal acceleration along
  the travel leads the heave's acceleration by a quarter period. So the quadrature spectra of the
  heave acceleration with the levelled x and y accelerations, summed over the band, point along the
  travel (The roll
  and pitch rates carry the same information through the slopes, but a hull near its roll resonance
  shifts their phase by up to 90 deg: with them the direction was 36-65 deg off in Hs 6-10 cm). The
  horizontal accelerations are turned into north and east with the heading as they arrive (a boat
  drifting in waves turns through tens of degrees in the window), so the spectra give the travel's
  direction over ground, and the waves come from 180 deg opposite;
- heave: the elevation's encounter spectrum S(w) = S_a(w) / w^4 (the heave acceleration a = w^2 z)
  divided by the hull's heave transfer function |H|^2, H = sinc(k L cos(chi) / 2) sinc(k B sin(chi)
  / 2) e^{-k T / 2} (the elevation averaged over the waterplane, its pressure at half the draft; L, B,
  T the hull's, `hull_m`; chi the waves' travel relative to the bow, |H|^2 averaged over a segment's
  headings and floored at `min_transfer`): Hs = 4 sqrt(m0), Tp_encounter at the
  spectrum's peak. Without it a 1 m hull in 1.5 m waves heading into them read 0.47 of the Hs;
- the true frequencies from the encounter ones, per Welch segment: w_e = w - w^2 U cos(chi) / g
  solved for w (deep water) at the boat's velocity over ground along the waves' travel, U cos(chi)
  averaged over that segment (the whole velocity: a boat adrift lies beam-on and drifts sideways down
  the waves at 0.1-0.2 m/s in a 4 m/s wind; with the speed along the heading, which misses that, Tp
  read 7-16 % long adrift and live); each segment's elevation spectrum divided by |H|^2 at its own true
  wavenumbers and its headings, and its energy put on the true-frequency axis, before the segments
  are averaged. A manoeuvring boat meets one sea at several encounter frequencies: one speed for the
  whole window (the boat's speed now, or the window's mean) read Hs 6 cm as 8-12 cm and Tp 1.0 s as
  0.6 s on a boat that drifted, ran north and turned into following seas within the window (the live
  test's route), where the segments' own speeds read 6.6-6.9 cm and 1.07-1.16 s. In following seas
  faster than half the waves' group speed the encounter frequency is ambiguous and the smaller root is
  taken.

A sea below the IMU's noise reads as flat water (`hs_m` 0, `valid` True); too little data as not
valid. Pure: time only from the sample stamps.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from lotsen.messages import ImuSample, SeaState, VesselState
from lotsen.model.angles import ground_velocity
from lotsen.model.environment import GRAVITY_MPS2


@dataclass(frozen=True)
class SeaStateConfig:
    rate_hz: float = 10.0  # the IMU decimated to this for the spectra (the wave band ends at 3 Hz)
    window_s: float = 120.0
    segment_s: float = 25.6  # Welch segments (Hann, half overlapping): 0.04 Hz resolution
    min_data_s: float = 30.0  # no estimate before this much data (more than one Welch segment)
    update_s: float = 2.0
    band_hz: tuple[float, float] = (0.3, 3.0)
    # below this heave acceleration standard deviation in the band the sea is flat water (the
    # MPU9250's 0.04 m/s^2 per sample is ~0.01 in the band after the decimation)
    min_heave_accel_mps2: float = 0.03
    max_gap_s: float = 1.0  # a longer gap in the IMU starts the window again
    hull_m: tuple[float, float, float] = (0.99, 0.30, 0.08)  # waterline length, beam, draft (the lake boat's)
    min_transfer: float = 0.15  # |H|^2 floor: waves much shorter than the hull are not read back from nothing


class SeaStateEstimator:
    """Feed `on_imu` and `on_state`; `estimate(t)` returns a `SeaState` every `update_s` (else None)."""

    def __init__(self, config: SeaStateConfig = SeaStateConfig()) -> None:
        self.config = config
        n = int(round(config.window_s * config.rate_hz))
        # rows (t, heave acceleration, p, q, a_north, a_east, heading, velocity over ground north, east)
        self._buf: deque = deque(maxlen=n)
        self._acc = [0.0] * 6  # sums over the present decimation interval (the last: the count)
        self._bin: int | None = None
        self._t_last: float | None = None
        self._heading = math.nan
        self._velocity_ne = (0.0, 0.0)
        self._next_update = -math.inf
        self.last: SeaState | None = None

    def on_imu(self, m: ImuSample, level_xy: tuple[float, float] | None = None) -> None:
        """One IMU sample, with its horizontal axes levelled (gravity's share of the tilt out; None:
        as measured, for a level hull)."""
        t = m.stamp_s
        ax, ay = level_xy if level_xy is not None else (m.accel_mps2[0], m.accel_mps2[1])
        if not math.isfinite(self._heading):
            return  # no heading yet: the horizontal axes cannot be put on the map
        c_, s_ = math.cos(self._heading), math.sin(self._heading)
        row = (m.accel_mps2[2] + GRAVITY_MPS2, m.gyro_radps[0], m.gyro_radps[1], c_ * ax - s_ * ay, s_ * ax + c_ * ay)
        if not all(math.isfinite(v) for v in (t, *row)):
            return
        c = self.config
        if self._t_last is not None and (t - self._t_last > c.max_gap_s or t < self._t_last):
            self._buf.clear()
            self._acc = [0.0] * 6
            self._bin = None
        self._t_last = t
        b = int(math.floor(t * c.rate_hz))
        if self._bin is not None and b != self._bin and self._acc[5]:
            k = self._acc[5]
            self._buf.append(((self._bin + 0.5) / c.rate_hz, *(v / k for v in self._acc[:5]), self._heading,
                              *self._velocity_ne))
            self._acc = [0.0] * 6
        self._bin = b
        for i, v in enumerate(row):
            self._acc[i] += v
        self._acc[5] += 1

    def on_state(self, s: VesselState) -> None:
        """The boat's heading and velocity over ground (for the absolute direction and period)."""
        self.on_motion(s.heading_rad, ground_velocity(s.u_mps, s.v_mps, s.heading_rad))

    def on_motion(self, heading_rad: float, velocity_ne_mps: tuple[float, float]) -> None:
        """The boat's heading (puts the IMU's axes on the map) and its velocity over ground, north and east
        (undoes the encounter frequency: all of it, sway included; a non-finite value keeps the previous)."""
        if math.isfinite(heading_rad):
            self._heading = heading_rad
        if all(math.isfinite(v) for v in velocity_ne_mps):
            self._velocity_ne = (float(velocity_ne_mps[0]), float(velocity_ne_mps[1]))

    def encounter_frequency_radps(self) -> float | None:
        """The frequency (rad/s) at which the boat met the sea's peak over the window, for the EKF's wave
        model; None without an estimate of a sea. (The peak at the present heading and speed, from the
        true period, is the theory; on a figure eight at 1 m/s in Hs 6 cm it lost one 6-DOF mission of
        three to the estimator where the window's own peak lost none: a turning boat meets a mixture.)"""
        s = self.last
        if s is None or not (s.valid and s.hs_m > 0 and math.isfinite(s.tp_encounter_s)):
            return None
        return 2.0 * math.pi / s.tp_encounter_s

    def estimate(self, t: float) -> SeaState | None:
        """A new estimate when one is due (None otherwise); the latest is `last`."""
        if t < self._next_update:
            return None
        self._next_update = t + self.config.update_s
        self.last = self.compute(t)
        return self.last

    def compute(self, t: float) -> SeaState:
        c = self.config
        data = np.array(self._buf, dtype=float).reshape(-1, 9)
        span = float(data[-1, 0] - data[0, 0]) if len(data) > 1 else 0.0
        nan = math.nan
        if span < c.min_data_s:
            return SeaState(stamp_s=t, valid=False, window_s=span, hs_m=nan, tp_s=nan, tp_encounter_s=nan,
                            from_deg=nan, heave_std_m=nan, roll_std_deg=nan, pitch_std_deg=nan)
        nseg = min(int(round(c.segment_s * c.rate_hz)), len(data))
        f, P, starts = _welch(data[:, 1:6] - data[:, 1:6].mean(axis=0), c.rate_hz, nseg)
        S = P.mean(axis=0)
        band = (f >= c.band_hz[0]) & (f <= c.band_hz[1])
        fb, df = f[band], float(f[1] - f[0])
        w = 2.0 * math.pi * fb
        Saa = S[0, 0][band].real  # heave acceleration
        acc_std = math.sqrt(float(np.sum(Saa) * df))
        # the angles' spectra from the rates' (1 / w^2), per degree
        roll_std = math.degrees(math.sqrt(float(np.sum(S[1, 1][band].real / w ** 2) * df)))
        pitch_std = math.degrees(math.sqrt(float(np.sum(S[2, 2][band].real / w ** 2) * df)))
        if acc_std < c.min_heave_accel_mps2:  # flat water: nothing above the IMU's noise
            return SeaState(stamp_s=t, valid=True, window_s=span, hs_m=0.0, tp_s=nan, tp_encounter_s=nan,
                            from_deg=nan, heave_std_m=0.0, roll_std_deg=roll_std, pitch_std_deg=pitch_std)
        heave_std = math.sqrt(float(np.sum(Saa / w ** 4) * df))
        # direction of travel over ground: the horizontal orbit leads the heave by a quarter period
        q_an = float(np.sum(S[0, 3][band].imag))
        q_ae = float(np.sum(S[0, 4][band].imag))
        travel = math.atan2(q_ae, q_an)
        # each segment's elevation spectrum at the true frequencies its own speed along the waves' travel
        # met them at, through the hull's heave transfer at its own headings
        L, B, T = c.hull_m
        Szeta_encounter = np.zeros_like(w)  # the segments' mean, on the encounter axis
        E_true = np.zeros_like(w)  # energy per true-frequency bin (the band's own grid)
        for j, start in enumerate(starts):
            rows = data[start:start + nseg]
            along = float(np.mean(rows[:, 7] * math.cos(travel) + rows[:, 8] * math.sin(travel)))
            w_true = np.array([true_frequency(float(x), along) for x in w])
            k = w_true ** 2 / GRAVITY_MPS2
            rel = travel - rows[:: max(1, len(rows) // 30), 6]  # the waves' direction from the bow
            H2 = np.mean((_sinc(0.5 * np.outer(np.cos(rel), k) * L) * _sinc(0.5 * np.outer(np.sin(rel), k) * B)) ** 2,
                         axis=0) * np.exp(-k * T)
            Szeta = P[j, 0, 0][band].real / w ** 4 / np.maximum(H2, c.min_transfer)
            Szeta_encounter += Szeta / len(starts)
            idx = np.clip(np.rint((w_true / (2.0 * math.pi) - fb[0]) / df).astype(int), 0, len(w) - 1)
            np.add.at(E_true, idx, Szeta * df / len(starts))
        m0 = float(np.sum(Szeta_encounter) * df)
        smooth = np.ones(3) / 3.0
        w_e = float(w[int(np.argmax(np.convolve(Szeta_encounter, smooth, mode="same")))])
        w_p = float(w[int(np.argmax(np.convolve(E_true, smooth, mode="same")))])
        from_deg = math.degrees(travel + math.pi) % 360.0
        return SeaState(stamp_s=t, valid=True, window_s=span, hs_m=4.0 * math.sqrt(m0),
                        tp_s=2.0 * math.pi / w_p, tp_encounter_s=2.0 * math.pi / w_e,
                        from_deg=from_deg, heave_std_m=heave_std, roll_std_deg=roll_std, pitch_std_deg=pitch_std)


#: the wave band of an identification record: its manoeuvres heave and pitch the hull at the inputs' own
#: frequencies, below it (a PRBS of 1.5-s bits, ~0.33 Hz: on the 6-DOF hull in Hs 3 cm, Tp 0.8 s a 10-min
#: record read Tp 2.8 s with the 0.3-Hz band, 0.81 s from 0.4 Hz). A lake's wind sea (Tp 0.7-1.5 s) has
#: little energy below 0.6 of its peak frequency, 0.4 Hz
RECORD_BAND_HZ = (0.4, 3.0)


def record_sea_state(t: np.ndarray, imu: np.ndarray, heading_rad: np.ndarray, velocity_ne_mps: np.ndarray,
                     config: SeaStateConfig = SeaStateConfig(band_hz=RECORD_BAND_HZ)) -> SeaState:
    """The sea state of a whole record, from its own IMU: the same `SeaStateEstimator` the running boat
    uses, fed the record's IMU rows in time order (`imu`: K x 6, specific force x, y, z and rates p, q, r,
    each the mean over its row interval or a sample; NaN rows skipped) with the horizontal axes levelled
    by the navigation filter's tilt filter (lotsen.fusion.attitude), its heading (K) and velocity over
    ground north and east (K x 2; NaN where unknown: the last known value holds), the window the whole
    record (at least `config.window_s`). Pure."""
    from lotsen.fusion.attitude import TiltFilter  # the one tilt filter (the EKF's), offline

    t = np.asarray(t, float)
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    cfg = replace(config, window_s=max(config.window_s, span + 1.0))
    est = SeaStateEstimator(cfg)
    tilt = TiltFilter()
    for k in range(len(t)):
        est.on_motion(float(heading_rad[k]), (float(velocity_ne_mps[k][0]), float(velocity_ne_mps[k][1])))
        row = imu[k]
        if not np.all(np.isfinite(row)):
            continue
        accel, gyro = (float(row[0]), float(row[1]), float(row[2])), (float(row[3]), float(row[4]), float(row[5]))
        tilt.update(float(t[k]), gyro, accel)
        est.on_imu(ImuSample(stamp_s=float(t[k]), gyro_radps=gyro, accel_mps2=accel), tilt.level(accel))
    return est.compute(float(t[-1]) if len(t) else 0.0)


def true_frequency(w_encounter: float, speed_along_waves_mps: float) -> float:
    """The wave frequency w met at w_e by a boat moving at U cos(chi) along the waves' travel (deep
    water: w_e = w - w^2 U cos(chi) / g). Head seas (U cos(chi) < 0): the one positive root. Following
    seas: the smaller root, or the frequency of the largest encounter frequency when there is none."""
    a = speed_along_waves_mps / GRAVITY_MPS2
    if abs(a) < 1e-6:
        return w_encounter
    disc = 1.0 - 4.0 * a * w_encounter
    if disc < 0.0:  # following seas: w_e beyond its maximum (1 / 4a); take the maximum's frequency
        return 1.0 / (2.0 * a)
    return (1.0 - math.sqrt(disc)) / (2.0 * a)


def _sinc(z: np.ndarray) -> np.ndarray:
    return np.sinc(np.asarray(z) / math.pi)  # numpy's sinc is sin(pi x) / (pi x)


def _welch(x: np.ndarray, fs: float, nseg: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Welch's cross-spectral densities of the columns of x, segment by segment (Hann windows of nseg <=
    len(x), half overlapping), one-sided: (frequencies, P[segment, i, j, f], each segment's first row); their
    mean over the segments is Welch's estimate."""
    n, m = x.shape
    step = max(1, nseg // 2)
    win = np.hanning(nseg)
    scale = 1.0 / (fs * float(np.sum(win ** 2)))
    starts = list(range(0, n - nseg + 1, step))
    X = np.stack([np.fft.rfft(x[s:s + nseg] * win[:, None], axis=0) for s in starts])  # (segments, freqs, m)
    P = np.einsum("sfi,sfj->sijf", np.conj(X), X) * scale
    P[:, :, :, 1:-1] *= 2.0
    return np.fft.rfftfreq(nseg, 1.0 / fs), P, starts
