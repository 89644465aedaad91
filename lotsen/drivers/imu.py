"""MPU9250 (accelerometer + gyro) and its AK8963 magnetometer over I2C with smbus2.

Frames (InvenSense MPU-9250 product specification, section 9.1 "Orientation of axes"):
- the MPU9250 accel/gyro frame is right-handed with z out of the chip's top face;
- the AK8963 inside the package has x_mag = y_accel, y_mag = x_accel, z_mag = -z_accel.
The driver first brings the magnetometer into the accel/gyro ("chip") frame,
m_chip = (m_y, m_x, -m_z), then maps both into the body frame (x forward, y starboard, z down)
with the configured `axes`: body axis i = sign * chip axis. Default ("+x", "-y", "-z"): board
face up with the chip's x arrow pointing forward. At rest and level the accelerometer then
reads a specific force of (0, 0, -9.81) m/s^2, as lotsen.messages.ImuSample expects.

Scale factors: accel 32768 LSB per full-scale range (+-2/4/8/16 g), gyro 32768 LSB per
+-250/500/1000/2000 deg/s, magnetometer 0.15 uT/LSB in 16-bit mode times the factory
sensitivity adjustment (ASA - 128) / 256 + 1 read from the AK8963's fuse ROM.
"""

from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass
from typing import Any, Callable

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import ImuSection
from lotsen.messages import ImuSample, MagSample, Topic

G_MPS2 = 9.80665  # the accelerometer's "g" (standard gravity)

# MPU9250 registers
SMPLRT_DIV = 0x19
CONFIG = 0x1A
GYRO_CONFIG = 0x1B
ACCEL_CONFIG = 0x1C
ACCEL_CONFIG2 = 0x1D
INT_PIN_CFG = 0x37
ACCEL_XOUT_H = 0x3B
USER_CTRL = 0x6A
PWR_MGMT_1 = 0x6B
PWR_MGMT_2 = 0x6C
WHO_AM_I = 0x75
MPU9250_IDS = (0x71, 0x73)  # MPU9250, MPU9255 (same register map)

# AK8963 registers
AK_WIA = 0x00
AK_ID = 0x48
AK_ST1 = 0x02
AK_HXL = 0x03
AK_ST2 = 0x09
AK_CNTL1 = 0x0A
AK_ASAX = 0x10
AK_MODE_POWER_DOWN = 0x00
AK_MODE_FUSE_ROM = 0x0F
AK_MODE_CONT_100HZ_16BIT = 0x16  # BIT=1 (16-bit), MODE=0110 (continuous 2, 100 Hz)
AK_UT_PER_LSB_16BIT = 0.15

GYRO_RANGES_DPS = {250: 0, 500: 1, 1000: 2, 2000: 3}
ACCEL_RANGES_G = {2: 0, 4: 1, 8: 2, 16: 3}


class RegisterError(ValueError):
    """Register contents that cannot be a measurement (wrong length, overflow flag)."""


def decode_accel_gyro(block: Any) -> tuple[tuple[int, int, int], int, tuple[int, int, int]]:
    """14 bytes from ACCEL_XOUT_H: big-endian int16 accel xyz, temperature, gyro xyz."""
    data = bytes(block)
    if len(data) != 14:
        raise RegisterError(f"accel/gyro block has {len(data)} bytes, expected 14")
    ax, ay, az, temp, gx, gy, gz = struct.unpack(">7h", data)
    return (ax, ay, az), temp, (gx, gy, gz)


def decode_mag(block: Any) -> tuple[int, int, int]:
    """7 bytes HXL..ST2: little-endian int16 xyz, then ST2 (HOFL bit 3: magnetic overflow)."""
    data = bytes(block)
    if len(data) != 7:
        raise RegisterError(f"magnetometer block has {len(data)} bytes, expected 7")
    if data[6] & 0x08:
        raise RegisterError("magnetometer overflow (ST2.HOFL)")
    x, y, z = struct.unpack("<3h", data[:6])
    return x, y, z


def asa_factor(asa: int) -> float:
    """AK8963 sensitivity adjustment: H_adj = H ((ASA - 128) 0.5 / 128 + 1)."""
    return (asa - 128) * 0.5 / 128.0 + 1.0


def parse_axes(axes: tuple[str, str, str]) -> tuple[tuple[int, float], ...]:
    """("+x", "-y", "-z") -> ((0, 1.0), (1, -1.0), (2, -1.0)); a permutation with signs."""
    out = []
    for a in axes:
        a = a.strip().lower()
        if len(a) != 2 or a[0] not in "+-" or a[1] not in "xyz":
            raise ValueError(f"imu.axes: {a!r} is not one of +x, -x, +y, -y, +z, -z")
        out.append(("xyz".index(a[1]), 1.0 if a[0] == "+" else -1.0))
    if sorted(i for i, _ in out) != [0, 1, 2]:
        raise ValueError(f"imu.axes: {axes} must use each of x, y, z once")
    return tuple(out)


def chip_to_body(v: tuple[float, float, float], axes: tuple[tuple[int, float], ...]) -> tuple[float, float, float]:
    return (axes[0][1] * v[axes[0][0]], axes[1][1] * v[axes[1][0]], axes[2][1] * v[axes[2][0]])


def body_to_chip(v: tuple[float, float, float], axes: tuple[tuple[int, float], ...]) -> tuple[float, float, float]:
    out = [0.0, 0.0, 0.0]
    for i, (j, s) in enumerate(axes):
        out[j] = s * v[i]
    return (out[0], out[1], out[2])


def ak_to_chip(m: tuple[float, float, float]) -> tuple[float, float, float]:
    """AK8963 axes into the MPU9250 accel/gyro frame."""
    return (m[1], m[0], -m[2])


@dataclass(frozen=True)
class ImuScales:
    accel_mps2_per_lsb: float
    gyro_radps_per_lsb: float
    mag_uT_per_lsb: tuple[float, float, float]  # including ASA, AK axes

    @classmethod
    def of(cls, cfg: ImuSection, asa: tuple[int, int, int] = (128, 128, 128)) -> "ImuScales":
        return cls(accel_mps2_per_lsb=cfg.accel_range_g * G_MPS2 / 32768.0,
                   gyro_radps_per_lsb=math.radians(cfg.gyro_range_dps) / 32768.0,
                   mag_uT_per_lsb=tuple(AK_UT_PER_LSB_16BIT * asa_factor(a) for a in asa))  # type: ignore[arg-type]


class Mpu9250:
    """Register-level driver over an smbus2.SMBus-like object (read_byte_data, write_byte_data,
    read_i2c_block_data). `sleep` is injectable so the emulated bus needs no real waiting."""

    def __init__(self, bus: Any, cfg: ImuSection, sleep: Callable[[float], None] = time.sleep) -> None:
        if cfg.gyro_range_dps not in GYRO_RANGES_DPS:
            raise ValueError(f"imu.gyro_range_dps: {cfg.gyro_range_dps} not one of {sorted(GYRO_RANGES_DPS)}")
        if cfg.accel_range_g not in ACCEL_RANGES_G:
            raise ValueError(f"imu.accel_range_g: {cfg.accel_range_g} not one of {sorted(ACCEL_RANGES_G)}")
        self.bus = bus
        self.cfg = cfg
        self.sleep = sleep
        self.axes = parse_axes(cfg.axes)
        self.scales = ImuScales.of(cfg)
        self.mag_ok = False

    def init(self) -> None:
        """Reset, clock, rates and ranges, bypass to the AK8963, AK8963 to 16-bit continuous 100 Hz.
        Raises OSError for a missing device and RegisterError for a wrong WHO_AM_I."""
        b, a, c = self.bus, self.cfg.address, self.cfg
        who = b.read_byte_data(a, WHO_AM_I)
        if who not in MPU9250_IDS:
            raise RegisterError(f"WHO_AM_I at 0x{a:02x} is 0x{who:02x}, expected 0x71 (MPU9250)")
        b.write_byte_data(a, PWR_MGMT_1, 0x80)  # device reset
        self.sleep(0.1)
        b.write_byte_data(a, PWR_MGMT_1, 0x01)  # clock: PLL with the gyro's reference
        b.write_byte_data(a, PWR_MGMT_2, 0x00)  # all axes on
        b.write_byte_data(a, CONFIG, c.dlpf_cfg)  # gyro DLPF (1 kHz internal rate)
        b.write_byte_data(a, SMPLRT_DIV, max(0, int(round(1000.0 / c.rate_hz)) - 1))
        b.write_byte_data(a, GYRO_CONFIG, GYRO_RANGES_DPS[c.gyro_range_dps] << 3)
        b.write_byte_data(a, ACCEL_CONFIG, ACCEL_RANGES_G[c.accel_range_g] << 3)
        b.write_byte_data(a, ACCEL_CONFIG2, 0x03)  # accel DLPF 41 Hz
        b.write_byte_data(a, USER_CTRL, 0x00)  # I2C master off: needed for the bypass
        b.write_byte_data(a, INT_PIN_CFG, 0x02)  # BYPASS_EN: the AK8963 appears on the Pi's bus
        self.sleep(0.01)
        self.init_mag()

    def init_mag(self) -> None:
        b, m = self.bus, self.cfg.mag_address
        wia = b.read_byte_data(m, AK_WIA)
        if wia != AK_ID:
            raise RegisterError(f"AK8963 WIA at 0x{m:02x} is 0x{wia:02x}, expected 0x48")
        b.write_byte_data(m, AK_CNTL1, AK_MODE_POWER_DOWN)
        self.sleep(0.01)
        b.write_byte_data(m, AK_CNTL1, AK_MODE_FUSE_ROM)
        self.sleep(0.01)
        asa = tuple(b.read_i2c_block_data(m, AK_ASAX, 3))
        if len(asa) != 3:
            raise RegisterError(f"AK8963 ASA: {len(asa)} bytes, expected 3")
        self.scales = ImuScales.of(self.cfg, asa)  # type: ignore[arg-type]
        b.write_byte_data(m, AK_CNTL1, AK_MODE_POWER_DOWN)
        self.sleep(0.01)
        b.write_byte_data(m, AK_CNTL1, AK_MODE_CONT_100HZ_16BIT)
        self.sleep(0.01)
        self.mag_ok = True

    def read_imu(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(gyro rad/s, specific force m/s^2) in the body frame."""
        acc, _temp, gyr = decode_accel_gyro(self.bus.read_i2c_block_data(self.cfg.address, ACCEL_XOUT_H, 14))
        s = self.scales
        a = chip_to_body((acc[0] * s.accel_mps2_per_lsb, acc[1] * s.accel_mps2_per_lsb,
                          acc[2] * s.accel_mps2_per_lsb), self.axes)
        # the accelerometer measures the reaction to gravity (+1 g up): specific force, as wanted
        g = chip_to_body((gyr[0] * s.gyro_radps_per_lsb, gyr[1] * s.gyro_radps_per_lsb,
                          gyr[2] * s.gyro_radps_per_lsb), self.axes)
        return g, a

    def read_mag(self) -> tuple[float, float, float] | None:
        """Field in uT in the body frame, or None when no new sample is ready (ST1.DRDY = 0)."""
        m = self.cfg.mag_address
        st1 = self.bus.read_byte_data(m, AK_ST1)
        if not st1 & 0x01:
            return None
        raw = decode_mag(self.bus.read_i2c_block_data(m, AK_HXL, 7))  # reading ST2 ends the cycle
        s = self.scales.mag_uT_per_lsb
        ak = (raw[0] * s[0], raw[1] * s[1], raw[2] * s[2])
        return chip_to_body(ak_to_chip(ak), self.axes)


class ImuNode(DriverNode):
    """Publishes ImuSample (imu/data_raw) at `rate_hz` and MagSample (imu/mag) at `mag_rate_hz`."""

    name = "imu"

    def __init__(self, cfg: ImuSection, open_bus: Callable[[], Any], threaded: bool = False,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.period_s = 1.0 / cfg.rate_hz
        super().__init__(threaded)
        self.cfg = cfg
        self.device = f"MPU9250 i2c-{cfg.bus} 0x{cfg.address:02x}"
        self.health.device = self.device
        self._open_bus = open_bus
        self._sleep = sleep
        self.mpu: Mpu9250 | None = None
        self._last_mag_s = -float("inf")
        self.mag_samples = 0

    def open(self, now: float) -> None:
        bus = self._open_bus()
        mpu = Mpu9250(bus, self.cfg, self._sleep)
        mpu.init()
        self.mpu = mpu

    def close(self) -> None:
        if self.mpu is not None and hasattr(self.mpu.bus, "close"):
            self.mpu.bus.close()

    def poll(self, now: float) -> Out:
        out: Out = []
        mpu = self.mpu
        assert mpu is not None
        try:
            gyro, accel = mpu.read_imu()
        except OSError as exc:  # I2C NACK / timeout: skip this sample
            self.error(out, now, "i2c_errors", f"{self.device}: read failed: {exc}")
        except RegisterError as exc:
            self.error(out, now, "bad_registers", f"{self.device}: {exc}")
        else:
            self.produced(now)
            out.append((Topic.IMU_RAW, ImuSample(stamp_s=now, gyro_radps=gyro, accel_mps2=accel)))
        # the magnetometer is asked whenever a new sample may be due (ST1.DRDY decides): reading
        # on a fixed every-k-th tick would miss samples when its clock and ours drift apart
        if now - self._last_mag_s >= 0.75 / self.cfg.mag_rate_hz:
            try:
                field = mpu.read_mag()
            except OSError as exc:
                self.error(out, now, "mag_i2c_errors", f"AK8963: read failed: {exc}")
            except RegisterError as exc:
                self.error(out, now, "mag_bad_registers", f"AK8963: {exc}")
            else:
                if field is not None:
                    self._last_mag_s = now
                    self.mag_samples += 1
                    out.append((Topic.IMU_MAG, MagSample(stamp_s=now, field_uT=field)))
        return out
