"""u-blox ZED-F9P driver: configure (UBX-CFG-VALSET), read NAV-PVT, publish `GnssFix`; forward
RTCM3 corrections to the receiver's second UART and publish their age.

The driver talks to any object with pyserial's `read(n)`, `write(b)`, `in_waiting` and `close()`:
`serial.serial_for_url(port)` on the boat (so `socket://host:port` or `rfc2217://` URLs work too),
the emulated receiver (`lotsen.drivers.emulated.EmulatedZedF9P`) in tests and `--emulated` runs.

Stamps: `GnssFix.stamp_s` is the arrival time on the runtime clock (the receiver's iTOW/UTC are
kept in `last_pvt` and printed by `lotsen gnss-replay`). At 115200 baud a 100-byte NAV-PVT takes
8.7 ms on the wire, and the F9P outputs the solution ~30-50 ms after the measurement epoch;
the fusion treats GNSS with this latency (a documented constant, not estimated here).

Correction age: the time since the last complete RTCM3 frame was written to the receiver, when
this process forwards corrections; otherwise the receiver's own NAV-PVT lastCorrectionAge (an
interval, reported by its upper bound), NaN when neither knows.
"""

from __future__ import annotations

import math
import threading
from typing import Any, Callable

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import GnssSection
from lotsen.drivers.ntrip import NtripClient
from lotsen.drivers.ubx import NavPvt, StreamFramer, ack_of, decode_nav_pvt, implausible_fix, valset_message
from lotsen.messages import GnssFix, GnssFixType, OperatorCommand, RtcmData, Topic
from lotsen.runtime.executor import NodeContext

PortOpener = Callable[[], Any]


def serial_opener(url: str, baudrate: int, timeout_s: float = 0.1) -> PortOpener:
    """Opens a real serial port (or a pyserial URL) when called."""

    def open_port() -> Any:
        import serial

        try:
            return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout_s)
        except serial.SerialException as exc:
            raise OSError(str(exc)) from None

    return open_port


class RtcmForwarder:
    """Writes correction bytes to the receiver's RTCM UART; thread-safe (NTRIP thread, radio
    thread and bus messages may all forward). Counts complete RTCM3 frames for the age."""

    def __init__(self, open_port: PortOpener | None) -> None:
        self._open = open_port
        self._port: Any = None
        self._lock = threading.Lock()
        self._framer = StreamFramer()
        self.enabled = True
        self.bytes_forwarded = 0
        self.write_errors = 0
        self.last_frame_s = -math.inf
        self.last_error = ""

    def forward(self, data: bytes, now: float) -> None:
        if not self.enabled or self._open is None or not data:
            return
        with self._lock:
            try:
                if self._port is None:
                    self._port = self._open()
                self._port.write(data)
            except Exception as exc:  # noqa: BLE001 - missing or unplugged port: count, retry next time
                self.write_errors += 1
                self.last_error = str(exc)
                self._port = None
                return
            self.bytes_forwarded += len(data)
            if any(f.kind == "rtcm" for f in self._framer.feed(data)):
                self.last_frame_s = now

    def age_s(self, now: float) -> float:
        return now - self.last_frame_s if self.last_frame_s > -math.inf else math.nan

    def close(self) -> None:
        with self._lock:
            if self._port is not None:
                try:
                    self._port.close()
                finally:
                    self._port = None


class GnssReceiver:
    """The protocol side of the driver, without threads or a bus: `feed(bytes, now)` -> fixes."""

    def __init__(self, config: GnssSection) -> None:
        self.config = config
        self.framer = StreamFramer()
        self.configured = not config.configure
        self.acks = 0
        self.naks = 0
        self.undecodable = 0
        self.refused = 0  # physically impossible NAV-PVT (`implausible_fix`): dropped, never published
        self.last_refusal = ""
        self.last_pvt: NavPvt | None = None

    def configuration_bytes(self) -> bytes:
        return valset_message(self.config.rate_hz, output=self.config.receiver_output)

    def feed(self, data: bytes, now: float) -> list[GnssFix]:
        fixes = []
        for frame in self.framer.feed(data):
            if frame.kind != "ubx":
                continue  # NMEA left on by a receiver we could not configure; RTCM echoes
            d = frame.data
            if d[2] == 0x01 and d[3] == 0x07:
                pvt = decode_nav_pvt(d, now)
                if pvt is None:
                    self.undecodable += 1
                    continue
                why = implausible_fix(pvt.fix)
                if why is not None:
                    self.refused += 1
                    self.last_refusal = f"iTOW {pvt.itow_s:.3f} s: {why}"
                    continue
                self.last_pvt = pvt
                fixes.append(pvt.fix)
            else:
                ack = ack_of(d)
                if ack is not None and ack[1:] == (0x06, 0x8A):  # CFG-VALSET
                    if ack[0] == "ACK":
                        self.acks += 1
                        self.configured = True
                    else:
                        self.naks += 1
        return fixes


class GnssNode(DriverNode):
    """Publishes `GnssFix` on gps_chatter; forwards RTCM (bus, NTRIP or a radio) to UART2."""

    name = "gnss"
    blocking_poll = True  # thread mode: port.read() blocks up to the port timeout

    def __init__(self, config: GnssSection, open_port: PortOpener, open_rtcm_port: PortOpener | None = None,
                 open_base_port: PortOpener | None = None, threaded: bool = False,
                 ntrip_connect: Callable | None = None) -> None:
        self.period_s = 1.0 / config.poll_hz
        super().__init__(threaded)
        self.config = config
        self.device = f"ZED-F9P {config.port}"
        self.health.device = self.device
        self.health.expected_hz = config.rate_hz
        self._open_port = open_port
        self.port: Any = None
        self.receiver = GnssReceiver(config)
        self.rtcm = RtcmForwarder(open_rtcm_port)
        self._open_base = open_base_port
        self._ntrip_connect = ntrip_connect
        self.ntrip: NtripClient | None = None
        self._base_thread: threading.Thread | None = None
        self._config_sent_s = -math.inf
        self._config_attempts = 0
        self._last_fix: GnssFix | None = None
        self._refused_counted = 0
        self._rtcm_write_errors = 0
        self._corrections_stale = False

    # -- lifecycle ------------------------------------------------------------------------------
    def on_start(self, ctx: NodeContext) -> None:
        ctx.subscribe(Topic.RTCM, self._on_rtcm_message)
        ctx.subscribe(Topic.OPERATOR, self._on_operator)
        src = self.config.rtcm_source
        if src == "ntrip" and self.config.ntrip.enabled:
            self.ntrip = NtripClient(self.config.ntrip, on_rtcm=lambda b: self.rtcm.forward(b, ctx.clock.now()),
                                     position=self._position, connect=self._ntrip_connect,
                                     on_status=lambda text: ctx.executor.call_soon_threadsafe(
                                         lambda: ctx.log("info", text)))
            self.ntrip.start()
        elif src == "serial" and self._open_base is not None:
            self._base_thread = threading.Thread(target=self._base_loop, name="lotsen-rtcm-radio", daemon=True)
            self._base_thread.start()

    def open(self, now: float) -> None:
        self.port = self._open_port()
        self._config_attempts = 0
        self._config_sent_s = -math.inf

    def close(self) -> None:
        if self.ntrip is not None:
            self.ntrip.stop()
        self.rtcm.close()
        if self.port is not None:
            self.port.close()
            self.port = None

    # -- reading --------------------------------------------------------------------------------
    def poll(self, now: float) -> Out:
        out: Out = []
        rx = self.receiver
        if not rx.configured and now - self._config_sent_s > 1.0:
            if self._config_attempts >= 5:
                if self._config_attempts == 5:
                    self.error(out, now, "config_unacknowledged", "receiver did not acknowledge CFG-VALSET")
                    self._config_attempts += 1
            else:
                self._write(rx.configuration_bytes(), out, now)
                self._config_sent_s = now
                self._config_attempts += 1
        data = self.read_serial(out, now)
        if not data:
            return out
        fixes = rx.feed(data, now)
        self.count_dropped(out, now, rx.framer.counters, ("garbage_bytes", "bad_checksums"))
        if rx.refused > self._refused_counted:
            new = rx.refused - self._refused_counted
            self._refused_counted = rx.refused
            self.health.dropped += new
            self.error(out, now, "implausible_fixes",
                       f"{self.device}: refused {new} physically impossible NAV-PVT ({rx.last_refusal})")
        age = self.rtcm.age_s(now)
        self._check_corrections(age, out, now)
        for fix in fixes:
            if math.isfinite(age):
                fix.correction_age_s = age
            self._last_fix = fix
            self.produced(now)
            out.append((Topic.GNSS, fix))
        return out

    def _check_corrections(self, age: float, out: Out, now: float) -> None:
        """Report RTCM write failures and corrections that stopped (RTK will degrade to float/3D)."""
        if self.rtcm.write_errors > self._rtcm_write_errors:
            self._rtcm_write_errors = self.rtcm.write_errors
            self.error(out, now, "rtcm_write_errors", f"RTCM port {self.config.rtcm_port}: {self.rtcm.last_error}")
        stale = age > self.config.correction_timeout_s  # NaN (never had any): not stale
        if stale and not self._corrections_stale:
            self.log(out, now, "warning", f"no RTCM corrections for {age:.0f} s: RTK will degrade",
                     correction_age_s=age)
        elif self._corrections_stale and not stale:
            self.log(out, now, "info", "RTCM corrections flowing again")
        self._corrections_stale = stale

    def _write(self, data: bytes, out: Out, now: float) -> None:
        try:
            self.port.write(data)
        except Exception as exc:  # noqa: BLE001
            self.error(out, now, "write_errors", f"{self.device}: write failed: {exc}")

    # -- corrections ----------------------------------------------------------------------------
    def _on_rtcm_message(self, msg: RtcmData) -> None:
        if self.config.rtcm_source == "bus":
            self.rtcm.forward(msg.data, self.ctx.now())

    def _on_operator(self, msg: OperatorCommand) -> None:
        if msg.action in ("rtk_start", "rtk_stop"):
            self.rtcm.enabled = msg.action == "rtk_start"
            self.ctx.log("info", f"RTK corrections {'on' if self.rtcm.enabled else 'off'}")

    def _position(self) -> tuple[float, float, float] | None:
        f = self._last_fix
        if f is None or f.fix_type < GnssFixType.FIX_3D:
            return None
        return (f.lat_deg, f.lon_deg, f.height_m)

    def _base_loop(self) -> None:
        """A radio modem from a local base station: read its bytes, forward them."""
        port = None
        while not self._stop.is_set():
            try:
                if port is None:
                    port = self._open_base()
                data = port.read(max(1, port.in_waiting))
            except Exception:  # noqa: BLE001 - radio unplugged: retry
                port = None
                self._stop.wait(1.0)
                continue
            if data:
                self.rtcm.forward(bytes(data), self.ctx.clock.now())

    def stop(self) -> None:
        super().stop()
        if self._base_thread is not None:
            self._base_thread.join(timeout=2.0)
