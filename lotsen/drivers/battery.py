"""Battery voltage and current from a TI INA219 on I2C, published as BatteryStatus, with
low-battery warnings (LogEvent on `log`) for the supervisor.

INA219 registers are 16-bit big-endian (smbus2's read_word_data is little-endian, so the driver
reads two-byte blocks). Configuration: 32 V bus range, PGA /8 (+-320 mV shunt), 12-bit ADCs,
continuous shunt + bus. Current is computed from the shunt voltage (10 uV/LSB) and
`shunt_ohm`, which needs no trust in the calibration register; the calibration register (0x05)
is still written so the chip's own current register (0x04) reads in amperes * current_lsb.

Warnings: below `warn_cell_v` per cell for `persistence_s` -> warning; below `critical_cell_v`
-> error; cleared only above the threshold plus `hysteresis_v` (no flapping under load).
"""

from __future__ import annotations

import math
from typing import Any, Callable

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import BatterySection
from lotsen.messages import BatteryStatus, Topic

INA_CONFIG = 0x00
INA_SHUNT = 0x01
INA_BUS = 0x02
INA_POWER = 0x03
INA_CURRENT = 0x04
INA_CALIBRATION = 0x05
INA_CONFIG_VALUE = 0x399F  # BRNG 32 V, PG /8, BADC 12 bit, SADC 12 bit, shunt+bus continuous
INA_RESET = 0x8000
SHUNT_V_PER_LSB = 10e-6
BUS_V_PER_LSB = 4e-3


def decode_bus_voltage(raw: int) -> float:
    """Bus voltage register: bits 15..3 in 4 mV; bit 0 OVF (math overflow) is an error."""
    if not 0 <= raw <= 0xFFFF:
        raise ValueError(f"INA219 bus register {raw} outside 16 bits")
    if raw & 0x01:
        raise ValueError("INA219 math overflow (OVF): shunt current beyond the range")
    return (raw >> 3) * BUS_V_PER_LSB


def decode_shunt_voltage(raw: int) -> float:
    """Shunt voltage register: two's complement, 10 uV/LSB."""
    if not 0 <= raw <= 0xFFFF:
        raise ValueError(f"INA219 shunt register {raw} outside 16 bits")
    return (raw - 0x10000 if raw & 0x8000 else raw) * SHUNT_V_PER_LSB


def calibration_value(cfg: BatterySection) -> tuple[int, float]:
    """(CAL register, current LSB in A): CAL = trunc(0.04096 / (current_lsb R_shunt))."""
    current_lsb = cfg.max_current_a / 32768.0
    cal = int(0.04096 / (current_lsb * cfg.shunt_ohm))
    return min(cal, 0xFFFE) & 0xFFFE, current_lsb  # bit 0 is read-only


class Ina219:
    def __init__(self, bus: Any, cfg: BatterySection) -> None:
        self.bus = bus
        self.cfg = cfg

    def _read(self, reg: int) -> int:
        data = bytes(self.bus.read_i2c_block_data(self.cfg.address, reg, 2))
        if len(data) != 2:
            raise ValueError(f"INA219 register 0x{reg:02x}: {len(data)} bytes, expected 2")
        return (data[0] << 8) | data[1]

    def _write(self, reg: int, value: int) -> None:
        self.bus.write_i2c_block_data(self.cfg.address, reg, [(value >> 8) & 0xFF, value & 0xFF])

    def init(self) -> None:
        self._write(INA_CONFIG, INA_RESET)
        self._write(INA_CONFIG, INA_CONFIG_VALUE)
        cal, _ = calibration_value(self.cfg)
        self._write(INA_CALIBRATION, cal)
        if self._read(INA_CONFIG) != INA_CONFIG_VALUE:
            raise ValueError(f"INA219 at 0x{self.cfg.address:02x} did not take the configuration")

    def read(self) -> tuple[float, float]:
        """(bus voltage V, current A)."""
        v = decode_bus_voltage(self._read(INA_BUS))
        i = decode_shunt_voltage(self._read(INA_SHUNT)) / self.cfg.shunt_ohm
        return v, i


class LowBatteryMonitor:
    """Level with persistence and hysteresis: "ok", "low", "critical"."""

    def __init__(self, cfg: BatterySection) -> None:
        self.cfg = cfg
        self.level = "ok"
        self._below_since: dict[str, float] = {}

    def update(self, voltage_v: float, now: float) -> str | None:
        """The new level when it changes, else None."""
        c = self.cfg
        thresholds = {"critical": c.critical_cell_v * c.cells, "low": c.warn_cell_v * c.cells}
        want = "ok"
        for level in ("critical", "low"):
            if voltage_v < thresholds[level]:
                self._below_since.setdefault(level, now)
                if now - self._below_since[level] >= c.persistence_s:
                    want = level
                    break
            else:
                self._below_since.pop(level, None)
        rank = {"ok": 0, "low": 1, "critical": 2}
        if rank[want] < rank[self.level]:  # recover only above threshold + hysteresis
            limit = thresholds[self.level] + c.hysteresis_v
            if voltage_v < limit:
                return None
        if want != self.level:
            self.level = want
            return want
        return None


class BatteryNode(DriverNode):
    name = "battery"

    def __init__(self, cfg: BatterySection, open_bus: Callable[[], Any], threaded: bool = False) -> None:
        self.period_s = 1.0 / cfg.rate_hz
        super().__init__(threaded)
        self.cfg = cfg
        self.device = f"INA219 i2c-{cfg.bus} 0x{cfg.address:02x}"
        self.health.device = self.device
        self._open_bus = open_bus
        self.ina: Ina219 | None = None
        self.monitor = LowBatteryMonitor(cfg)

    def open(self, now: float) -> None:
        ina = Ina219(self._open_bus(), self.cfg)
        ina.init()
        self.ina = ina

    def poll(self, now: float) -> Out:
        out: Out = []
        assert self.ina is not None
        try:
            v, i = self.ina.read()
        except OSError as exc:
            self.error(out, now, "i2c_errors", f"{self.device}: read failed: {exc}")
            return out
        except ValueError as exc:
            self.error(out, now, "bad_registers", f"{self.device}: {exc}")
            return out
        c = self.cfg
        frac = (v / c.cells - c.empty_cell_v) / (c.full_cell_v - c.empty_cell_v)
        self.produced(now)
        out.append((Topic.BATTERY, BatteryStatus(stamp_s=now, voltage_v=v, current_a=i,
                                                 remaining_frac=min(1.0, max(0.0, frac)) if math.isfinite(frac) else math.nan)))
        level = self.monitor.update(v, now)
        if level is not None:
            lvl = {"ok": "info", "low": "warning", "critical": "error"}[level]
            self.log(out, now, lvl, f"battery {level}: {v:.2f} V ({v / c.cells:.2f} V per cell)",
                     battery_level=level, voltage_v=v)
        return out
