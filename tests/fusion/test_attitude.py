"""TiltFilter: what `level` takes out of the accelerometer. A level hull must stay (nearly)
untouched whatever the known acceleration's errors, wave-frequency roll must be levelled out, and a
constant heel is left to the navigation filter's accelerometer offset states."""

import math

import numpy as np

from lotsen.fusion.attitude import GRAVITY_MPS2, TiltConfig, TiltFilter

DT = 0.01  # the IMU at 100 Hz
GYRO_NOISE = 0.003  # rad/s a sample, as the simulator's IMU
ACCEL_NOISE = 0.04


def run(duration_s: float, roll_of_t, rng: np.random.Generator, known_error_of_t=lambda t: (0.0, 0.0),
        r_of_t=lambda t: 0.0, config: TiltConfig = TiltConfig(), accel_offset: tuple[float, float] = (0.0, 0.0)):
    """A hull with roll(t) only (no pitch, no acceleration of its own), yawing at r(t) about the
    vertical; the filter gets the noisy IMU and known acceleration = its error. Yields (t, levelled x,
    levelled y, the noise-free specific force) a sample: on this hull the true levelled reading is 0."""
    tilt = TiltFilter(config)
    n = int(round(duration_s / DT))
    for k in range(n + 1):
        t = k * DT
        ph = roll_of_t(t)
        p = (roll_of_t(t + 1e-4) - roll_of_t(t - 1e-4)) / 2e-4
        r = r_of_t(t)
        # a rolled hull yawing about the vertical: the body rates carry r on y and z
        gyro = (p + GYRO_NOISE * rng.standard_normal(), r * math.sin(ph) + GYRO_NOISE * rng.standard_normal(),
                r * math.cos(ph) + GYRO_NOISE * rng.standard_normal())
        f = (0.0, -GRAVITY_MPS2 * math.sin(ph), -GRAVITY_MPS2 * math.cos(ph))
        noisy = tuple(v + o + ACCEL_NOISE * rng.standard_normal() for v, o in zip(f, accel_offset + (0.0,)))
        tilt.update(t, gyro, noisy, known_error_of_t(t))
        lx, ly = tilt.level(f)  # the noise-free reading: what levelling alone adds
        yield t, lx, ly, f


def lagged_gnss_error(t: float) -> tuple[float, float]:
    """The differenced GNSS velocity's error in sharp manoeuvres: 0.1 m/s^2 pulses of a few seconds,
    in both axes, plus 8-Hz-ish noise (velocity noise 0.02 m/s over 0.125 s)."""
    pulse = 0.1 if (t % 20.0) < 3.0 else -0.1 if 10.0 <= (t % 20.0) < 12.0 else 0.0
    wiggle = 0.16 * math.sin(2 * math.pi * 3.7 * t) * math.sin(2 * math.pi * 0.31 * t)
    return pulse + wiggle, -pulse + 0.5 * wiggle


def turning(t: float) -> float:
    """Yaw rate: turns of up to 0.4 rad/s to either side, 63 s a cycle."""
    return 0.4 * math.sin(0.1 * t)


def test_level_hull_with_wrong_known_acceleration_is_barely_touched():
    """A level hull turning, an accelerometer with the simulator's offsets (which read as a trim of
    0.3 deg: the tilt filter cannot tell them apart) and a known acceleration with GNSS-like errors."""
    rng = np.random.default_rng(1)
    errs = [math.hypot(lx - f[0], ly - f[1])
            for t, lx, ly, f in run(180.0, lambda t: 0.0, rng, lagged_gnss_error, r_of_t=turning, accel_offset=(0.05, -0.03))
            if t > 20.0]
    # the gyro's own noise, integrated, is ~0.01 rms; levelling with tilt - slow tilt: 0.16-0.23 max, 0.07-0.09 rms
    assert max(errs) < 0.04
    assert float(np.sqrt(np.mean(np.square(errs)))) < 0.02


def test_level_hull_old_levelling_would_be_moved_by_known_acceleration_errors():
    """The comparison the first test's bar stands on: levelling with tilt - slow tilt."""
    rng = np.random.default_rng(1)
    errs = [math.hypot(lx - f[0], ly - f[1])
            for t, lx, ly, f in run(180.0, lambda t: 0.0, rng, lagged_gnss_error, r_of_t=turning, accel_offset=(0.05, -0.03),
                                    config=TiltConfig(level_time_constant_s=0.0))
            if t > 20.0]
    assert max(errs) > 0.1


def test_wave_frequency_roll_is_levelled_out():
    rng = np.random.default_rng(2)
    amp = math.radians(3.0)
    resid = [ly for t, lx, ly, f in run(60.0, lambda t: amp * math.sin(2 * math.pi * t), rng) if t > 30.0]
    raw = GRAVITY_MPS2 * math.sin(amp)  # 0.51 m/s^2
    assert max(abs(v) for v in resid) < 0.1 * raw  # 7%: the gyro noise integrated, the Euler step's lag


def test_constant_heel_is_left_to_the_offset_states():
    """A heel that builds up in 2 s (the gyro sees it) is levelled at first, then handed over: after
    a few leak time constants the levelled reading keeps the heel's gravity share, as an offset."""
    rng = np.random.default_rng(3)
    heel = math.radians(5.0)
    roll = lambda t: heel * min(max((t - 10.0) / 2.0, 0.0), 1.0)  # noqa: E731
    out = {round(t, 2): (ly, f) for t, lx, ly, f in run(100.0, roll, rng)}
    ly, f = out[12.5]
    assert abs(ly) < 0.2 * GRAVITY_MPS2 * math.sin(heel)  # levelled while fresh
    ly, f = out[100.0]
    assert abs(ly - f[1]) < 0.1 * GRAVITY_MPS2 * math.sin(heel)  # left as it reads
