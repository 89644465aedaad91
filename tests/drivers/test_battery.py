from hypothesis import given, strategies as st

from lotsen.drivers.battery import (
    BatteryNode, LowBatteryMonitor, calibration_value, decode_bus_voltage, decode_shunt_voltage,
)
from lotsen.drivers.config import BatterySection
from lotsen.drivers.emulated import EmulatedI2CBus, Ina219Twin
from lotsen.messages import Topic


def test_registers_round_trip_through_the_twin():
    bus = EmulatedI2CBus()
    bus.ina = Ina219Twin(0.01)
    node = BatteryNode(BatterySection(), lambda: bus)
    node.step(0.0)
    assert bus.ina.regs[0x05] == calibration_value(BatterySection())[0] != 0
    bus.ina.set(11.84, 7.5)
    out = node.step(0.5)
    b = [m for t, m in out if t == Topic.BATTERY][0]
    assert abs(b.voltage_v - 11.84) <= 0.004 and abs(b.current_a - 7.5) <= 0.001
    assert 0.0 < b.remaining_frac < 1.0


def test_low_battery_warning_with_persistence_and_hysteresis():
    cfg = BatterySection(cells=3, warn_cell_v=3.6, critical_cell_v=3.4, hysteresis_v=0.1, persistence_s=2.0)
    bus = EmulatedI2CBus()
    bus.ina = Ina219Twin(cfg.shunt_ohm)
    node = BatteryNode(cfg, lambda: bus)
    events = []
    volts = [11.5] * 4 + [10.7] * 8 + [10.85] * 4 + [11.0] * 4  # (one reading every 0.5 s)
    for k, v in enumerate(volts):
        bus.ina.set(v, 3.0)
        events += [(k, m) for t, m in node.step(k * 0.5) if t == Topic.LOG and "battery" in m.text]
    levels = [(k, m.level, m.data["battery_level"]) for k, m in events]
    # 10.7 V < 10.8: low after 2 s; 10.85 is inside the hysteresis band; 11.0 > 10.9 clears
    assert levels == [(8, "warning", "low"), (16, "info", "ok")]


def test_monitor_goes_critical():
    m = LowBatteryMonitor(BatterySection(persistence_s=0.0))
    assert m.update(10.0, 0.0) == "critical"


@given(st.integers(0, 0xFFFF))
def test_register_decoding_fuzz(raw):
    try:
        assert 0 <= decode_bus_voltage(raw) <= 32.7640001
    except ValueError:
        assert raw & 1
    assert -0.33 <= decode_shunt_voltage(raw) <= 0.33
