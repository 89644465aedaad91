"""Hardware configuration: pin map, ports, buses, calibrations and gains of the real boat, and the
RC transmitter's channel map.

Defaults follow the seed's pin map (section 1, Table 2 of the design specification). It is the
launch config's ``extra.hardware`` section, typed when the config is loaded
(`lotsen.stack.config.load_stack_config`; the stack reads ``config.extra.hardware``).

Every field is a plain number, text or list, so `deploy/hardware.yaml` documents all of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from lotsen.settings import value_range as _r


@dataclass(frozen=True)
class NtripSection:
    """RTCM3 corrections from an NTRIP caster (rev 2 over plain TCP); off unless `enabled`."""

    enabled: bool = False
    host: str = ""
    port: int = field(default=2101, metadata=_r(1, 65535))
    mountpoint: str = ""
    user: str = ""
    password: str = ""
    send_gga: bool = True  # VRS casters need the rover's position (GGA) every `gga_period_s`
    gga_period_s: float = field(default=10.0, metadata=_r(1.0, 600.0))
    reconnect_s: float = field(default=5.0, metadata=_r(0.5, 600.0))


@dataclass(frozen=True)
class GnssSection:
    """u-blox ZED-F9P. The Pi reads UBX on the receiver's UART1 (seed: GPIO 0/1, Pi 4 uart2)
    and writes RTCM3 to the receiver's UART2 (seed: GPIO 14/15, the Pi's primary UART)."""

    enabled: bool = True
    port: str = "/dev/ttyAMA1"  # Pi 4 uart2 on GPIO 0/1 (check `ls -l /dev/ttyAMA*`, see docs/drivers.md)
    baudrate: int = field(default=115200, metadata=_r(9600, 921600))
    rtcm_port: str = "/dev/serial0"  # primary UART on GPIO 14/15 -> receiver UART2 (RTCM3 in)
    rtcm_baudrate: int = field(default=38400, metadata=_r(9600, 921600))
    # corrections source: "ntrip" (caster over the network), "serial" (a radio modem on
    # `base_port`), "bus" (RtcmData on the gps_rtk/rtcm_data topic) or "none"
    rtcm_source: str = "bus"
    base_port: str = ""
    base_baudrate: int = field(default=57600, metadata=_r(1200, 921600))
    receiver_output: Literal["UART1", "USB"] = "UART1"  # where the receiver sends NAV-PVT (port is the Pi's side)
    rate_hz: float = field(default=8.0, metadata=_r(1.0, 20.0))  # CFG_RATE_MEAS = 1000 / rate_hz ms
    configure: bool = True  # send UBX-CFG-VALSET at start (RAM + BBR layers)
    poll_hz: float = field(default=25.0, metadata=_r(1.0, 200.0))  # synchronous mode: how often to read
    correction_timeout_s: float = field(default=10.0, metadata=_r(1.0, 120.0))
    ntrip: NtripSection = field(default_factory=NtripSection)


@dataclass(frozen=True)
class ImuSection:
    """MPU9250 (accel/gyro) + AK8963 (magnetometer, through the I2C bypass) on I2C bus 1 (GPIO 2/3)."""

    enabled: bool = True
    bus: int = field(default=1, metadata=_r(0, 20))
    address: int = field(default=0x68, metadata=_r(0x68, 0x69))  # AD0 low / high
    mag_address: int = field(default=0x0C, metadata=_r(0x0C, 0x0F))
    rate_hz: float = field(default=100.0, metadata=_r(1.0, 100.0))
    mag_rate_hz: float = field(default=50.0, metadata=_r(1.0, 100.0))
    gyro_range_dps: Literal[250, 500, 1000, 2000] = 500
    accel_range_g: Literal[2, 4, 8, 16] = 4
    dlpf_cfg: int = field(default=3, metadata=_r(0, 6))  # CONFIG DLPF: 3 = 41 Hz gyro bandwidth
    # body axis i = sign * chip axis: "+x", "-y", ... for the MPU9250's accel/gyro frame.
    # Default: chip face up, chip x forward -> body (x fwd, y stbd, z down) = (+x, -y, -z).
    axes: tuple[str, str, str] = ("+x", "-y", "-z")


@dataclass(frozen=True)
class ServoCalibration:
    """Steering servo: pulse = center_us + sign * angle_rad * us_per_rad, clipped to [min_us, max_us]."""

    center_us: float = field(default=1500.0, metadata=_r(1000.0, 2000.0))
    us_per_rad: float = field(default=500.0 / math.radians(45.0), metadata=_r(50.0, 3000.0))
    sign: float = field(default=1.0, metadata=_r(-1.0, 1.0))
    min_us: float = field(default=1000.0, metadata=_r(500.0, 2500.0))
    max_us: float = field(default=2000.0, metadata=_r(500.0, 2500.0))

    def __post_init__(self) -> None:
        # ValueError: from_mapping turns it into a ConfigError naming the section
        if self.sign not in (-1.0, 1.0):
            raise ValueError(f"sign {self.sign!r} must be 1 or -1 (a servo mounted the other way round)")
        if not self.min_us <= self.center_us <= self.max_us or self.min_us >= self.max_us:
            raise ValueError(f"pulse limits must satisfy min_us < max_us with center_us between them, got "
                             f"min_us {self.min_us:g}, center_us {self.center_us:g}, max_us {self.max_us:g}")


@dataclass(frozen=True)
class EscCalibration:
    """Bidirectional ESC: 1500 us neutral, +-deadband_us dead, then linear up to max/min_us at
    +-n_max_rps (n_max_reverse_rps backwards). `sign` flips a motor wired backwards."""

    neutral_us: float = field(default=1500.0, metadata=_r(1000.0, 2000.0))
    deadband_us: float = field(default=25.0, metadata=_r(0.0, 200.0))
    max_us: float = field(default=2000.0, metadata=_r(1500.0, 2500.0))
    min_us: float = field(default=1000.0, metadata=_r(500.0, 1500.0))
    n_max_rps: float = field(default=100.0, metadata=_r(1.0, 1000.0))
    n_max_reverse_rps: float = field(default=100.0, metadata=_r(1.0, 1000.0))
    sign: float = field(default=1.0, metadata=_r(-1.0, 1.0))

    def __post_init__(self) -> None:
        if self.sign not in (-1.0, 1.0):
            raise ValueError(f"sign {self.sign!r} must be 1 or -1 (a motor wired backwards)")
        if not self.min_us < self.neutral_us - self.deadband_us or not self.neutral_us + self.deadband_us < self.max_us:
            raise ValueError(f"pulses must satisfy min_us < neutral_us - deadband_us and neutral_us + deadband_us "
                             f"< max_us, got min_us {self.min_us:g}, neutral_us {self.neutral_us:g}, deadband_us "
                             f"{self.deadband_us:g}, max_us {self.max_us:g}")


@dataclass(frozen=True)
class SpeedLoopGains:
    """Inner propeller-speed loop: n_out = n_ref + kp e + ki int(e), e = n_ref - n_measured."""

    enabled: bool = True
    kp: float = field(default=0.4, metadata=_r(0.0, 10.0))
    ki_per_s: float = field(default=4.0, metadata=_r(0.0, 100.0))
    integral_limit_rps: float = field(default=30.0, metadata=_r(0.0, 500.0))
    min_speed_rps: float = field(default=2.0, metadata=_r(0.0, 50.0))  # below: neutral, integrator reset


@dataclass(frozen=True)
class ActuatorSection:
    """ESCs, steering servos and tachometers on the Pi's GPIO through pigpio (seed Table 2)."""

    enabled: bool = True
    pigpio_host: str = "localhost"
    pigpio_port: int = field(default=8888, metadata=_r(1, 65535))
    esc_pins: tuple[int, int, int] = (16, 20, 21)  # thruster 1 (stbd), thruster 2 (port), bow
    servo_pins: tuple[int, int] = (19, 26)  # thruster 1, thruster 2
    tacho_pins: tuple[int, int, int] = (17, 27, 22)
    pulses_per_rev: int = field(default=6, metadata=_r(1, 100))
    tacho_timeout_s: float = field(default=0.5, metadata=_r(0.05, 5.0))  # no edge for this long: 0 rev/s
    tacho_pull_up: bool = True
    rate_hz: float = field(default=50.0, metadata=_r(5.0, 200.0))  # output and speed-loop rate
    rpm_publish_hz: float = field(default=20.0, metadata=_r(1.0, 100.0))
    arm_time_s: float = field(default=3.0, metadata=_r(0.0, 30.0))  # neutral this long before any thrust
    esc: tuple[EscCalibration, EscCalibration, EscCalibration] = (
        EscCalibration(), EscCalibration(), EscCalibration(n_max_rps=80.0, n_max_reverse_rps=80.0))
    servo: tuple[ServoCalibration, ServoCalibration] = (ServoCalibration(), ServoCalibration())
    speed_loop: SpeedLoopGains = field(default_factory=SpeedLoopGains)

    def __post_init__(self) -> None:
        pins = (*self.esc_pins, *self.servo_pins, *self.tacho_pins)
        bad = [p for p in pins if isinstance(p, bool) or not isinstance(p, int) or not 0 <= p <= 27]
        if bad:
            raise ValueError(f"GPIO pins must be whole numbers 0-27 (the Pi's header), got {bad[:3]}")
        if len(set(pins)) != len(pins):
            raise ValueError(f"a GPIO pin is used twice among esc_pins, servo_pins and tacho_pins: {list(pins)}")


@dataclass(frozen=True)
class BatterySection:
    """INA219 on I2C: bus voltage and shunt current."""

    enabled: bool = True
    bus: int = field(default=1, metadata=_r(0, 20))
    address: int = field(default=0x40, metadata=_r(0x40, 0x4F))
    shunt_ohm: float = field(default=0.01, metadata=_r(0.0001, 10.0))
    max_current_a: float = field(default=30.0, metadata=_r(0.1, 400.0))
    rate_hz: float = field(default=2.0, metadata=_r(0.1, 50.0))
    cells: int = field(default=3, metadata=_r(1, 12))
    full_cell_v: float = field(default=4.2, metadata=_r(3.0, 4.5))
    empty_cell_v: float = field(default=3.5, metadata=_r(2.5, 4.0))
    warn_cell_v: float = field(default=3.6, metadata=_r(2.5, 4.2))  # LogEvent warning below
    critical_cell_v: float = field(default=3.4, metadata=_r(2.5, 4.2))  # LogEvent error below
    hysteresis_v: float = field(default=0.1, metadata=_r(0.0, 2.0))  # per pack, to clear a warning
    persistence_s: float = field(default=2.0, metadata=_r(0.0, 60.0))  # below threshold this long


@dataclass(frozen=True)
class RcStick:
    """One stick channel of the transmitter: raw SBUS value -> [-1, 1], linear on each side of
    `center_raw`, 0 within `deadband` (a fraction of full deflection)."""

    channel: int = field(default=0, metadata=_r(1, 16))  # required: which channel the stick is on
    min_raw: int = field(default=172, metadata=_r(0, 2047))  # FrSky -100 %
    center_raw: int = field(default=992, metadata=_r(0, 2047))
    max_raw: int = field(default=1811, metadata=_r(0, 2047))  # FrSky +100 %
    deadband: float = field(default=0.05, metadata=_r(0.0, 0.5))
    reverse: bool = False

    def __post_init__(self) -> None:
        if self.channel == 0:
            raise ValueError("channel: say which channel (1-16) this stick is on")
        if not self.min_raw + 100 <= self.center_raw <= self.max_raw - 100:
            raise ValueError(f"channel {self.channel}: needs min_raw + 100 <= center_raw <= max_raw - 100 "
                             f"(a usable stick travel), got min_raw {self.min_raw}, center_raw "
                             f"{self.center_raw}, max_raw {self.max_raw}")


@dataclass(frozen=True)
class RcSwitch:
    """A switch channel: on when the raw value is above `on_above_raw` (below it with `reverse`).
    Channels 17 and 18 are the SBUS digital channels."""

    channel: int = field(default=0, metadata=_r(1, 18))  # required: which channel the switch is on
    on_above_raw: int = field(default=1400, metadata=_r(1, 2046))
    reverse: bool = False

    def __post_init__(self) -> None:
        if self.channel == 0:
            raise ValueError("channel: say which channel (1-16, or 17/18 digital) this switch is on")


@dataclass(frozen=True)
class RcSection:
    """FrSky X8R on a Pi UART (SBUS) and the channel map. Default: Mode 2 transmitter in FrSky's
    AETR order; steering on the right stick (ch1), throttle on the spring-centred right stick
    (ch2: ahead / astern), bow thruster on the left stick sideways (ch4), takeover on a two-position
    switch (ch5), emergency stop on another (ch6)."""

    enabled: bool = True
    port: str = "/dev/ttyAMA2"  # Pi 4 uart3 on GPIO 4 (TX) / 5 (RX) through an inverter; see docs/drivers.md
    steering: RcStick = RcStick(channel=1)  # right: the bow turns to starboard going ahead
    throttle: RcStick = RcStick(channel=2)  # up: ahead
    bow: RcStick = RcStick(channel=4)  # right: the bow thruster pushes the bow to starboard
    takeover: RcSwitch = RcSwitch(channel=5)
    estop: RcSwitch = RcSwitch(channel=6)
    n_az_max_rps: float = field(default=60.0, metadata=_r(1.0, 200.0))  # full throttle stick
    n_bow_max_rps: float = field(default=50.0, metadata=_r(1.0, 200.0))  # full bow stick
    alpha_max_deg: float = field(default=35.0, metadata=_r(1.0, 90.0))  # full steering stick
    # frames flagged lost (or none at all) for this long: the link is lost. The supervisor adds
    # one control period (0.1 s) before the thrusters go neutral; keep the sum under 0.5 s.
    lost_after_s: float = field(default=0.2, metadata=_r(0.05, 0.35))
    publish_hz: float = field(default=20.0, metadata=_r(5.0, 100.0))  # rc/override (and at once on a change)
    min_frame_hz: float = field(default=50.0, metadata=_r(1.0, 200.0))  # `lotsen check`: frames at least this often

    def __post_init__(self) -> None:
        used: dict[int, str] = {}
        for name in ("steering", "throttle", "bow", "takeover", "estop"):
            ch = getattr(self, name).channel
            if ch in used:
                raise ValueError(f"{name}.channel {ch} is also {used[ch]}.channel: every function needs its own channel")
            used[ch] = name


@dataclass(frozen=True)
class EchosounderSection:
    """A single-beam echosounder sending NMEA 0183 DPT/DBT on a serial port (a USB adapter, or
    Blue Robotics' Ping2 through its NMEA output). Off unless configured: not every boat has one.
    Where the transducer sits is the hull's (`vessel.antenna_to_transducer_m`, `vessel.transducer_draft_m`)."""

    enabled: bool = False
    port: str = "/dev/ttyUSB1"
    baudrate: int = field(default=4800, metadata=_r(1200, 921600))  # NMEA 0183's 4800; many sounders 9600-115200
    sentence: Literal["any", "DPT", "DBT"] = "any"  # any: DPT when the sounder sends it, else DBT
    rate_hz: float = field(default=5.0, metadata=_r(0.2, 50.0))  # pings per second (`lotsen check`)


@dataclass(frozen=True)
class EmulationSection:
    """How the emulated twins differ from the driver's assumptions (to exercise the loops)."""

    esc_gain: tuple[float, float, float] = (0.85, 0.9, 0.8)  # true rev/s per calibrated rev/s
    rtk_requires_corrections: bool = False  # fix degrades to 3D without RTCM input


@dataclass(frozen=True)
class HardwareConfig:
    gnss: GnssSection = field(default_factory=GnssSection)
    imu: ImuSection = field(default_factory=ImuSection)
    actuators: ActuatorSection = field(default_factory=ActuatorSection)
    battery: BatterySection = field(default_factory=BatterySection)
    rc: RcSection = field(default_factory=RcSection)
    echosounder: EchosounderSection = field(default_factory=EchosounderSection)
    emulation: EmulationSection = field(default_factory=EmulationSection)

