"""Emulated twins of the boat's devices, speaking the real protocols at byte and register level,
fed by `lotsen.sim.Simulator`, so the real driver code runs end to end on any machine.

- `EmulatedSerialPort`: the pyserial subset the drivers use (read, write, in_waiting, close),
  thread-safe, with a device side (`push`, `on_write`).
- `EmulatedZedF9P`: UART1 outputs NMEA until a UBX-CFG-VALSET turns NAV-PVT on (and NMEA off),
  ACKs the VALSET, then one NAV-PVT per simulated fix; UART2 accepts RTCM3 (CRC-checked).
- `EmulatedI2CBus` with `Mpu9250Twin`, `Ak8963Twin` (visible only with the MPU's bypass on),
  `Ina219Twin`: the smbus2.SMBus methods the drivers use; absent addresses raise OSError 121
  (Remote I/O error) as the kernel does; `error_probability` injects read errors.
- `EmulatedX8R`: the RC receiver's SBUS frames from the transmitter's channels, with the
  frame-lost and failsafe flags of a lost transmitter and a cut wire (no bytes).
- `EmulatedEchosounder`: a single-beam sounder's NMEA 0183 bytes (DPT, or DBT, or both per ping)
  from the simulator's sounder (`lotsen.sim.lakebed`): depth below the transducer, an empty depth
  field when it found no bottom; `corrupt_probability` flips bytes.
- `EmulatedPigpio`: stores pulse widths and calls tachometer callbacks with edges at the
  simulated propeller speeds.
- `EmulatedBoatNode`: steps the simulator at its dt: reads the ESC/servo pulses, turns them into
  set-points with the *true* ESC calibration (which differs from the driver's by
  `esc_gain`, so the speed loop has work to do; ESCs arm only after 1 s of neutral, as
  real ones do), steps, and writes the simulator's sensor samples (computed from sim.x,
  sim.x_dot, sim.actuators with the simulator's noise models) into the twins' registers/bytes.
"""

from __future__ import annotations

import errno
import math
import threading
from datetime import datetime, timedelta, timezone
from typing import Any, Callable

import numpy as np

from lotsen.drivers import actuators as act
from lotsen.drivers import battery as ina
from lotsen.drivers import imu as mpu
from lotsen.drivers import sbus
from lotsen.drivers.config import HardwareConfig
from lotsen.drivers.ubx import StreamFramer, encode_nav_pvt, ubx_frame
from lotsen.drivers import nmea_depth
from lotsen.messages import BatteryStatus, DepthSample, GnssFix, GnssFixType, ImuSample, MagSample, Topic
from lotsen.runtime.executor import Node, NodeContext
from lotsen.sim import Simulator

GPS_EPOCH = datetime(1980, 1, 6, tzinfo=timezone.utc)
GPS_LEAP_S = 18


# -- serial -----------------------------------------------------------------------------------

class EmulatedSerialPort:
    """Host side: pyserial-like. Device side: `push(bytes)` to the host, `on_write(bytes)` from it."""

    def __init__(self, name: str = "emulated", timeout: float | None = 0.1) -> None:
        self.name = name
        self.port = name
        self.timeout = timeout
        self.is_open = True
        self._rx = bytearray()
        self._cv = threading.Condition()
        self.on_write: Callable[[bytes], None] = lambda data: None
        self.written = 0

    # host side
    @property
    def in_waiting(self) -> int:
        with self._cv:
            return len(self._rx)

    def read(self, size: int = 1) -> bytes:
        with self._cv:
            if size > 0 and not self._rx and self.timeout:
                self._cv.wait_for(lambda: bool(self._rx) or not self.is_open, self.timeout)
            if not self.is_open:
                raise OSError(errno.EIO, "port closed")
            data = bytes(self._rx[:size])
            del self._rx[:size]
            return data

    def write(self, data: bytes) -> int:
        if not self.is_open:
            raise OSError(errno.EIO, "port closed")
        self.written += len(data)
        self.on_write(bytes(data))
        return len(data)

    def reset_input_buffer(self) -> None:
        with self._cv:
            self._rx.clear()

    def close(self) -> None:
        with self._cv:
            self.is_open = False
            self._cv.notify_all()

    def reopen(self) -> "EmulatedSerialPort":
        with self._cv:
            self.is_open = True
            self._rx.clear()
        return self

    # device side
    def push(self, data: bytes) -> None:
        with self._cv:
            if len(self._rx) > 1 << 16:  # nobody reads: a real UART overruns too
                del self._rx[:len(data)]
            self._rx += data
            self._cv.notify_all()


def nmea_sentence(body: str) -> bytes:
    return nmea_depth.sentence(body)


class EmulatedZedF9P:
    """Receiver twin. `emit(fix, t)` is called by the boat twin at each simulated fix."""

    def __init__(self, start_utc: datetime = datetime(2026, 6, 1, 10, 0, 0, tzinfo=timezone.utc),
                 rng: np.random.Generator | None = None, corrupt_probability: float = 0.0) -> None:
        self.uart1 = EmulatedSerialPort("emulated:zed-f9p/uart1")
        self.uart2 = EmulatedSerialPort("emulated:zed-f9p/uart2")
        self.uart1.on_write = self._on_uart1
        self.uart2.on_write = self._on_uart2
        self.start_utc = start_utc
        self.rng = rng or np.random.default_rng(0)
        self.corrupt_probability = corrupt_probability
        self.nav_pvt_on = False  # factory default: NMEA only on UART1
        self.nmea_on = True
        self.rtcm_in_on = True
        self.meas_rate_ms = 1000
        self.valsets = 0
        self.rtcm_frames = 0
        self.rtcm_bad = 0
        self.last_rtcm_t = -math.inf
        self.t = 0.0
        self._rx1 = StreamFramer()
        self._rx2 = StreamFramer()

    def itow_ms(self, t: float) -> int:
        gps = self.start_utc + timedelta(seconds=t + GPS_LEAP_S) - GPS_EPOCH
        return int(round(gps.total_seconds() * 1000.0)) % 604_800_000

    def _on_uart1(self, data: bytes) -> None:
        from pyubx2 import SET, UBXReader

        for frame in self._rx1.feed(data):
            if frame.kind != "ubx" or frame.data[2:4] != b"\x06\x8a":
                continue
            try:
                msg = UBXReader.parse(frame.data, msgmode=SET)
            except Exception:  # noqa: BLE001 - a real receiver NAKs what it cannot parse
                self.uart1.push(ubx_frame(0x05, 0x00, b"\x06\x8a"))
                continue
            self.valsets += 1
            d = msg.__dict__
            if "CFG_MSGOUT_UBX_NAV_PVT_UART1" in d:
                self.nav_pvt_on = bool(d["CFG_MSGOUT_UBX_NAV_PVT_UART1"])
            if "CFG_UART1OUTPROT_NMEA" in d:
                self.nmea_on = bool(d["CFG_UART1OUTPROT_NMEA"])
            if "CFG_RATE_MEAS" in d:
                self.meas_rate_ms = int(d["CFG_RATE_MEAS"])
            self.uart1.push(ubx_frame(0x05, 0x01, b"\x06\x8a"))  # ACK-ACK for CFG-VALSET

    def _on_uart2(self, data: bytes) -> None:
        for frame in self._rx2.feed(data):
            if frame.kind == "rtcm":
                self.rtcm_frames += 1
                self.last_rtcm_t = self.t
        self.rtcm_bad = self._rx2.counters.bad_checksums

    def emit(self, fix: GnssFix, t: float) -> None:
        self.t = t
        utc = self.start_utc + timedelta(seconds=t)
        out = b""
        if self.nmea_on:
            lat, lon = abs(fix.lat_deg) if math.isfinite(fix.lat_deg) else 0.0, abs(fix.lon_deg) if math.isfinite(fix.lon_deg) else 0.0
            q = {GnssFixType.RTK_FIXED: 4, GnssFixType.RTK_FLOAT: 5, GnssFixType.NO_FIX: 0}.get(fix.fix_type, 1)
            out += nmea_sentence(f"GNGGA,{utc:%H%M%S}.{utc.microsecond // 10000:02d},{int(lat):02d}{(lat % 1) * 60:010.7f},N,"
                                 f"{int(lon):03d}{(lon % 1) * 60:010.7f},E,{q},{fix.num_sv:02d},0.6,"
                                 f"{fix.height_m if math.isfinite(fix.height_m) else 0:.3f},M,0.0,M,1.0,0000")
        if self.nav_pvt_on:
            out += encode_nav_pvt(fix, self.itow_ms(t), utc)
        if out and self.corrupt_probability and self.rng.random() < self.corrupt_probability:
            b = bytearray(out)
            b[int(self.rng.integers(len(b)))] ^= 0xFF
            out = bytes(b)
        if out:
            self.uart1.push(out)

    def has_corrections(self, t: float, timeout_s: float = 5.0) -> bool:
        return t - self.last_rtcm_t < timeout_s


class EmulatedEchosounder:
    """Echosounder twin: `emit(sample)` writes the ping as the sounder's NMEA sentences."""

    def __init__(self, sentences: tuple[str, ...] = ("DPT", "DBT"), offset_m: float = 0.1, talker: str = "SD",
                 rng: np.random.Generator | None = None, corrupt_probability: float = 0.0) -> None:
        self.port = EmulatedSerialPort("emulated:echosounder")
        self.sentences = sentences
        self.offset_m = offset_m
        self.talker = talker
        self.rng = rng or np.random.default_rng(0)
        self.corrupt_probability = corrupt_probability
        self.pings = 0

    def emit(self, sample: DepthSample) -> None:
        out = b""
        for kind in self.sentences:
            out += (nmea_depth.dpt(sample.depth_m, self.offset_m, self.talker) if kind == "DPT"
                    else nmea_depth.dbt(sample.depth_m, self.talker))
        if self.corrupt_probability > 0:
            data = bytearray(out)
            flips = self.rng.random(len(data)) < self.corrupt_probability
            for i in np.flatnonzero(flips):
                data[i] ^= 1 << int(self.rng.integers(0, 8))
            out = bytes(data)
        self.pings += 1
        self.port.push(out)


class EmulatedX8R:
    """FrSky X8R twin: one SBUS frame every `frame_period_s` of simulated time on `port` (the
    bytes a real X8R sends, after the inverter). The transmitter side is `channels` (raw values,
    FrSky's 172..1811; set them with lotsen.drivers.rc.stick_raw / switch_raw).

    `transmitter_on = False`: the receiver repeats the last channels with the frame-lost flag and
    after `failsafe_after_s` sets the failsafe flag too, with its failsafe values (`failsafe_hold`:
    the last ones, else `failsafe_channels`). `output_on = False`: no bytes at all (a cut wire,
    or the receiver's "no pulses" failsafe). `corrupt_probability` flips bytes."""

    def __init__(self, frame_period_s: float = 0.009, failsafe_after_s: float = 1.0,
                 rng: np.random.Generator | None = None) -> None:
        self.port = EmulatedSerialPort("emulated:x8r/sbus", timeout=0.05)
        self.frame_period_s = frame_period_s
        self.failsafe_after_s = failsafe_after_s
        self.channels = [sbus.RAW_CENTER] * 4 + [sbus.RAW_LOW] * 12  # sticks centred, switches off
        self.ch17 = self.ch18 = False
        self.transmitter_on = True
        self.output_on = True
        self.failsafe_hold = True
        self.failsafe_channels = [sbus.RAW_CENTER] * 16
        self.corrupt_probability = 0.0
        self.rng = rng or np.random.default_rng(2)
        self.frames_sent = 0
        self._held: tuple[int, ...] = tuple(self.channels)
        self._off_since: float | None = None
        self._next_s = 0.0

    def frame(self, t: float) -> sbus.SbusFrame:
        if self.transmitter_on:
            self._off_since = None
            self._held = tuple(self.channels)
            return sbus.SbusFrame(self._held, ch17=self.ch17, ch18=self.ch18)
        if self._off_since is None:
            self._off_since = t
        if t - self._off_since < self.failsafe_after_s:
            return sbus.SbusFrame(self._held, ch17=self.ch17, ch18=self.ch18, frame_lost=True)
        chans = self._held if self.failsafe_hold else tuple(self.failsafe_channels)
        return sbus.SbusFrame(chans, frame_lost=True, failsafe=True)

    def advance(self, t: float) -> None:
        """Send the frames due up to simulated time t."""
        out = bytearray()
        while self._next_s <= t:
            f = self.frame(self._next_s)
            self._next_s += self.frame_period_s
            if self.output_on:
                out += sbus.encode_frame(f)
                self.frames_sent += 1
        if out and self.corrupt_probability:
            for i in range(len(out)):
                if self.rng.random() < self.corrupt_probability:
                    out[i] ^= 1 << int(self.rng.integers(8))
        if out:
            self.port.push(bytes(out))


# -- I2C --------------------------------------------------------------------------------------

class RegisterDevice:
    def __init__(self) -> None:
        self.regs = bytearray(256)

    def read(self, reg: int) -> int:
        return self.regs[reg & 0xFF]

    def write(self, reg: int, value: int) -> None:
        self.regs[reg & 0xFF] = value & 0xFF


def _int16(v: float) -> int:
    return max(-32768, min(32767, int(round(v))))


class Mpu9250Twin(RegisterDevice):
    def __init__(self, axes: tuple[str, str, str] = ("+x", "-y", "-z")) -> None:
        super().__init__()
        self.axes = mpu.parse_axes(axes)
        self.regs[mpu.WHO_AM_I] = 0x71
        self.regs[mpu.PWR_MGMT_1] = 0x40  # sleep after power-up

    def write(self, reg: int, value: int) -> None:
        if reg == mpu.PWR_MGMT_1 and value & 0x80:  # reset: registers to defaults
            self.regs[:] = bytes(256)
            self.regs[mpu.WHO_AM_I] = 0x71
            self.regs[mpu.PWR_MGMT_1] = 0x40
            return
        super().write(reg, value)

    @property
    def bypass(self) -> bool:
        return bool(self.regs[mpu.INT_PIN_CFG] & 0x02) and not self.regs[mpu.USER_CTRL] & 0x20

    @property
    def awake(self) -> bool:
        return not self.regs[mpu.PWR_MGMT_1] & 0x40

    def set_sample(self, gyro_radps: tuple[float, float, float], accel_mps2: tuple[float, float, float]) -> None:
        """Body-frame sample -> chip registers, scaled by the ranges the driver configured."""
        if not self.awake:
            return
        g_range = (250, 500, 1000, 2000)[(self.regs[mpu.GYRO_CONFIG] >> 3) & 3]
        a_range = (2, 4, 8, 16)[(self.regs[mpu.ACCEL_CONFIG] >> 3) & 3]
        a = mpu.body_to_chip(accel_mps2, self.axes)
        g = mpu.body_to_chip(gyro_radps, self.axes)
        a_lsb = 32768.0 / (a_range * mpu.G_MPS2)
        g_lsb = 32768.0 / math.radians(g_range)
        vals = [_int16(a[0] * a_lsb), _int16(a[1] * a_lsb), _int16(a[2] * a_lsb), _int16(25.0 * 333.87),
                _int16(g[0] * g_lsb), _int16(g[1] * g_lsb), _int16(g[2] * g_lsb)]
        for i, v in enumerate(vals):
            v &= 0xFFFF
            self.regs[mpu.ACCEL_XOUT_H + 2 * i] = v >> 8
            self.regs[mpu.ACCEL_XOUT_H + 2 * i + 1] = v & 0xFF


class Ak8963Twin(RegisterDevice):
    def __init__(self, axes: tuple[str, str, str] = ("+x", "-y", "-z"), asa: tuple[int, int, int] = (176, 177, 165)) -> None:
        super().__init__()
        self.axes = mpu.parse_axes(axes)
        self.asa = asa
        self.regs[mpu.AK_WIA] = mpu.AK_ID

    @property
    def mode(self) -> int:
        return self.regs[mpu.AK_CNTL1] & 0x0F

    def read(self, reg: int) -> int:
        if mpu.AK_ASAX <= reg <= mpu.AK_ASAX + 2:  # fuse ROM readable only in fuse ROM mode
            return self.asa[reg - mpu.AK_ASAX] if self.mode == mpu.AK_MODE_FUSE_ROM else 0
        value = self.regs[reg]
        if reg == mpu.AK_ST2:  # reading ST2 ends the measurement read: DRDY cleared
            self.regs[mpu.AK_ST1] &= ~0x01
        return value

    def set_field(self, field_uT: tuple[float, float, float]) -> None:
        if self.mode not in (0x02, 0x06) or not self.regs[mpu.AK_CNTL1] & 0x10:
            return  # not in 16-bit continuous mode
        chip = mpu.body_to_chip(field_uT, self.axes)
        ak = (chip[1], chip[0], -chip[2])  # inverse of ak_to_chip
        for i in range(3):
            raw = _int16(ak[i] / (mpu.AK_UT_PER_LSB_16BIT * mpu.asa_factor(self.asa[i]))) & 0xFFFF
            self.regs[mpu.AK_HXL + 2 * i] = raw & 0xFF
            self.regs[mpu.AK_HXL + 2 * i + 1] = raw >> 8
        self.regs[mpu.AK_ST1] |= 0x01
        self.regs[mpu.AK_ST2] = 0x10  # BITM: 16-bit output


class Ina219Twin:
    """16-bit big-endian registers."""

    def __init__(self, shunt_ohm: float = 0.01) -> None:
        self.shunt_ohm = shunt_ohm
        self.regs = {ina.INA_CONFIG: 0x399F, ina.INA_SHUNT: 0, ina.INA_BUS: 0, ina.INA_POWER: 0,
                     ina.INA_CURRENT: 0, ina.INA_CALIBRATION: 0}

    def read_word(self, reg: int) -> int:
        return self.regs.get(reg, 0)

    def write_word(self, reg: int, value: int) -> None:
        if reg == ina.INA_CONFIG and value & ina.INA_RESET:
            self.regs.update({ina.INA_CONFIG: 0x399F, ina.INA_CALIBRATION: 0})
            return
        if reg in (ina.INA_CONFIG, ina.INA_CALIBRATION):
            self.regs[reg] = value & 0xFFFF

    def set(self, voltage_v: float, current_a: float) -> None:
        shunt = _int16(current_a * self.shunt_ohm / ina.SHUNT_V_PER_LSB) & 0xFFFF
        self.regs[ina.INA_SHUNT] = shunt
        self.regs[ina.INA_BUS] = (max(0, min(8191, int(round(voltage_v / ina.BUS_V_PER_LSB)))) << 3) | 0x02


class EmulatedI2CBus:
    """The smbus2.SMBus methods the drivers use, over register twins."""

    def __init__(self, rng: np.random.Generator | None = None, error_probability: float = 0.0) -> None:
        self.mpu: Mpu9250Twin | None = None
        self.ak: Ak8963Twin | None = None
        self.ina: Ina219Twin | None = None
        self.mpu_address = 0x68
        self.ak_address = 0x0C
        self.ina_address = 0x40
        self.rng = rng or np.random.default_rng(1)
        self.error_probability = error_probability
        self.reads = 0
        self.errors_injected = 0
        self._lock = threading.Lock()

    def _dev(self, addr: int) -> Any:
        if self.error_probability and self.rng.random() < self.error_probability:
            self.errors_injected += 1
            raise OSError(errno.EREMOTEIO, "Remote I/O error (injected)")
        if addr == self.mpu_address and self.mpu is not None:
            return self.mpu
        if addr == self.ak_address and self.ak is not None and self.mpu is not None and self.mpu.bypass:
            return self.ak
        if addr == self.ina_address and self.ina is not None:
            return self.ina
        raise OSError(errno.EREMOTEIO, "Remote I/O error")  # what smbus2 raises on a NACK

    def read_byte_data(self, addr: int, reg: int) -> int:
        with self._lock:
            self.reads += 1
            dev = self._dev(addr)
            if isinstance(dev, Ina219Twin):
                return dev.read_word(reg) >> 8
            return dev.read(reg)

    def write_byte_data(self, addr: int, reg: int, value: int) -> None:
        with self._lock:
            dev = self._dev(addr)
            if isinstance(dev, Ina219Twin):
                raise OSError(errno.EREMOTEIO, "INA219 takes 16-bit writes")
            dev.write(reg, value)

    def read_i2c_block_data(self, addr: int, reg: int, length: int) -> list[int]:
        with self._lock:
            self.reads += 1
            dev = self._dev(addr)
            if isinstance(dev, Ina219Twin):
                w = dev.read_word(reg)
                return [w >> 8, w & 0xFF][:length] + [0] * max(0, length - 2)
            return [dev.read(reg + i) for i in range(length)]

    def write_i2c_block_data(self, addr: int, reg: int, data: list[int]) -> None:
        with self._lock:
            dev = self._dev(addr)
            if isinstance(dev, Ina219Twin):
                if len(data) != 2:
                    raise OSError(errno.EREMOTEIO, "INA219 takes 16-bit writes")
                dev.write_word(reg, (data[0] << 8) | data[1])
                return
            for i, v in enumerate(data):
                dev.write(reg + i, v)

    def close(self) -> None:
        pass


# -- pigpio -----------------------------------------------------------------------------------

class _Callback:
    def __init__(self, owner: "EmulatedPigpio", gpio: int, func: Callable[[int, int, int], None]) -> None:
        self.owner, self.gpio, self.func = owner, gpio, func

    def cancel(self) -> None:
        self.owner._callbacks = [c for c in self.owner._callbacks if c is not self]


class EmulatedPigpio:
    connected = True

    def __init__(self) -> None:
        self.pulse_us: dict[int, int] = {}
        self.modes: dict[int, int] = {}
        self.pulls: dict[int, int] = {}
        self._callbacks: list[_Callback] = []
        self.tick_us = 0
        self.stopped = False
        self.writes = 0

    def set_mode(self, gpio: int, mode: int) -> int:
        self.modes[gpio] = mode
        return 0

    def set_pull_up_down(self, gpio: int, pud: int) -> int:
        self.pulls[gpio] = pud
        return 0

    def set_servo_pulsewidth(self, gpio: int, pulsewidth: int) -> int:
        if pulsewidth != 0 and not 500 <= pulsewidth <= 2500:
            raise ValueError(f"GPIO {gpio}: bad pulsewidth {pulsewidth}")  # pigpio's PI_BAD_PULSEWIDTH
        self.writes += 1
        self.pulse_us[gpio] = int(pulsewidth)
        return 0

    def get_servo_pulsewidth(self, gpio: int) -> int:
        return self.pulse_us.get(gpio, 0)

    def callback(self, gpio: int, edge: int = 0, func: Callable[[int, int, int], None] | None = None) -> _Callback:
        cb = _Callback(self, gpio, func or (lambda g, l, t: None))
        self._callbacks.append(cb)
        return cb

    def get_current_tick(self) -> int:
        return self.tick_us % act.TICK_WRAP

    def edge(self, gpio: int, tick_us: int) -> None:
        for cb in tuple(self._callbacks):
            if cb.gpio == gpio:
                cb.func(gpio, 1, tick_us % act.TICK_WRAP)

    def stop(self) -> None:
        self.stopped = True


# -- the boat twin ----------------------------------------------------------------------------

class EmulatedBoatNode(Node):
    """Steps the simulator and feeds the device twins (see the module docstring)."""

    name = "emulated_boat"

    def __init__(self, sim: Simulator, hw: HardwareConfig, truth_rate_hz: float = 20.0,
                 esc_arm_s: float = 1.0) -> None:
        self.sim = sim
        self.hw = hw
        rng = np.random.default_rng(sim.config.seed + 1000)
        self.zed = EmulatedZedF9P(rng=rng)
        self.i2c = EmulatedI2CBus(rng=np.random.default_rng(sim.config.seed + 1001))
        self.i2c.mpu_address, self.i2c.ak_address = hw.imu.address, hw.imu.mag_address
        self.i2c.ina_address = hw.battery.address
        self.i2c.mpu = Mpu9250Twin(hw.imu.axes) if hw.imu.enabled else None
        self.i2c.ak = Ak8963Twin(hw.imu.axes) if hw.imu.enabled else None
        self.i2c.ina = Ina219Twin(hw.battery.shunt_ohm) if hw.battery.enabled else None
        self.pi = EmulatedPigpio()
        self.x8r = EmulatedX8R(rng=np.random.default_rng(sim.config.seed + 1002)) if hw.rc.enabled else None
        self.sounder = (EmulatedEchosounder(rng=np.random.default_rng(sim.config.seed + 1003))
                        if hw.echosounder.enabled else None)
        a = hw.actuators
        # the *true* ESCs: the driver's calibration scaled by esc_gain
        from dataclasses import replace

        self.true_esc = [replace(a.esc[i], n_max_rps=a.esc[i].n_max_rps * hw.emulation.esc_gain[i],
                                 n_max_reverse_rps=a.esc[i].n_max_reverse_rps * hw.emulation.esc_gain[i])
                         for i in range(3)]
        self.esc_arm_s = esc_arm_s
        self._neutral_s = [0.0, 0.0, 0.0]
        self.esc_armed = [False, False, False]
        self._phase = [0.0, 0.0, 0.0]
        self.tacho_failed: set[int] = set()  # fault injection: 0, 1, 2
        self._truth_every = max(1, round(1.0 / (truth_rate_hz * sim.config.dt_s)))
        self._steps = 0
        self.last_fix: GnssFix | None = None
        self.last_imu: ImuSample | None = None
        self.last_mag: MagSample | None = None

    def start(self, ctx: NodeContext) -> None:
        self.ctx = ctx
        ctx.add_timer(self.sim.config.dt_s, self._tick)

    def set_points(self) -> tuple[float, float, float, float, float]:
        """What the actuators make of the pulses on the pins now."""
        a, dt = self.hw.actuators, self.sim.config.dt_s
        n = []
        for i in range(3):
            us = self.pi.get_servo_pulsewidth(a.esc_pins[i])
            cal = self.true_esc[i]
            if us == 0:  # no signal: ESC failsafe, disarmed
                self._neutral_s[i] = 0.0
                self.esc_armed[i] = False
            elif abs(us - cal.neutral_us) <= cal.deadband_us:
                self._neutral_s[i] += dt
                if self._neutral_s[i] >= self.esc_arm_s:
                    self.esc_armed[i] = True
            n.append(act.esc_rps(cal, us) if self.esc_armed[i] else 0.0)
        alpha = []
        for pin, cal in zip(a.servo_pins, a.servo):
            us = self.pi.get_servo_pulsewidth(pin)
            alpha.append(act.servo_angle(cal, us) if us else self.sim.actuators.state[len(alpha)])
        return (alpha[0], alpha[1], n[0], n[1], n[2])

    def _tick(self) -> None:
        # catch up when the realtime executor skipped periods (busy machine): simulated time
        # keeps pace with the clock, as the real world does; one step per tick on a SimExecutor
        dt = self.sim.config.dt_s
        n = int(round((self.ctx.now() + dt - self.sim.t) / dt))
        for _ in range(max(0, min(n, 3))):  # at most 3x speed while catching up: no bursts
            self._step()

    def _step(self) -> None:
        sim = self.sim
        sim.command(self.set_points())
        t0 = sim.t
        msgs = sim.step()
        t1 = sim.t
        self.zed.t = t1
        if self.hw.emulation.rtk_requires_corrections:
            want = GnssFixType.RTK_FIXED if self.zed.has_corrections(t1) else GnssFixType.FIX_3D
            if sim.gnss.fix_type != want:
                sim.set_gnss_fix_type(want)
        for m in msgs:
            if isinstance(m, ImuSample) and self.i2c.mpu is not None:
                with self.i2c._lock:
                    self.i2c.mpu.set_sample(m.gyro_radps, m.accel_mps2)
                self.last_imu = m
            elif isinstance(m, MagSample) and self.i2c.ak is not None:
                with self.i2c._lock:
                    self.i2c.ak.set_field(m.field_uT)
                self.last_mag = m
            elif isinstance(m, GnssFix):
                self.last_fix = m
                self.zed.emit(m, m.stamp_s)
            elif isinstance(m, BatteryStatus) and self.i2c.ina is not None:
                with self.i2c._lock:
                    self.i2c.ina.set(m.voltage_v, m.current_a)
            elif isinstance(m, DepthSample) and self.sounder is not None:
                self.sounder.emit(m)
        self._edges(t0, t1)
        if self.x8r is not None:
            self.x8r.advance(t1)
        self.pi.tick_us = int(round(t1 * 1e6))
        self._steps += 1
        if self._steps % self._truth_every == 0:
            self.ctx.publish(Topic.TRUTH, sim.truth())

    def _edges(self, t0: float, t1: float) -> None:
        """Tachometer edges: phase advances by |n| ppr dt; each integer crossing is an edge,
        at its interpolated time within the step."""
        a = self.hw.actuators
        ppr = a.pulses_per_rev
        state = self.sim.actuators.state
        for i in range(3):
            rate = abs(state[2 + i]) * ppr  # edges per second
            p0 = self._phase[i]
            p1 = p0 + rate * (t1 - t0)
            self._phase[i] = p1 % 1.0
            if i in self.tacho_failed or rate <= 0:
                continue
            for k in range(int(math.floor(p1)) - int(math.floor(p0))):
                te = t0 + (math.floor(p0) + 1 + k - p0) / rate
                self.pi.edge(a.tacho_pins[i], int(round(te * 1e6)))
