"""ESCs, steering servos and tachometers through pigpio (or its emulated twin).

Published with every rpm sample: `ActuatorState` with the measured propeller speeds, the servo
angles as commanded to the servos (after the guard's and the pulse limits; hobby servos have no
feedback wire) and `escs_armed` (False during the arming time of neutral pulses after opening).

Chain per thruster: ship_command -> ActuatorGuard (finite, limited, neutral when stale) ->
arming gate -> propeller-speed loop (PI on the tachometer + calibration feedforward) ->
pulse-width calibration -> set_servo_pulsewidth. Servos get angle -> pulse directly (hobby
servos have their own position loop and no feedback wire).

Tachometer: rising edges counted in a pigpio callback (its own thread; a lock guards the
counts). Speed = edges / (time between the last edge of the previous window and the last edge
of this one) / pulses_per_rev: the resolution of the edge timestamps (1 us), not of the window.
No edge for `tacho_timeout_s` -> 0 rev/s. A tachometer sees no direction: the sign is that of
the commanded ESC direction (kept through neutral, while the propeller spins down).

The pigpio interface used (pigpio.pi, or EmulatedPigpio): set_mode, set_pull_up_down,
set_servo_pulsewidth, get_servo_pulsewidth, callback(gpio, edge, func(gpio, level, tick)),
get_current_tick, stop, connected.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any, Callable

from lotsen.drivers.base import DriverNode, Out
from lotsen.drivers.config import ActuatorSection, EscCalibration, ServoCalibration, SpeedLoopGains
from lotsen.messages import ActuatorState, RpmSample, ThrustCommand, Topic
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.runtime.executor import NodeContext
from lotsen.runtime.guard import ActuatorGuard

# pigpio constants (same values as the pigpio module, so the emulation needs no import)
PI_OUTPUT = 1
PI_INPUT = 0
PI_PUD_UP = 2
PI_PUD_OFF = 0
RISING_EDGE = 0
TICK_WRAP = 1 << 32


# -- calibrations -----------------------------------------------------------------------------

def servo_us(cal: ServoCalibration, angle_rad: float) -> float:
    """Steering angle (rad, + turns thrust to starboard) -> pulse width (us)."""
    return min(cal.max_us, max(cal.min_us, cal.center_us + cal.sign * angle_rad * cal.us_per_rad))


def servo_angle(cal: ServoCalibration, us: float) -> float:
    """Inverse of servo_us (within the pulse limits)."""
    return (min(cal.max_us, max(cal.min_us, us)) - cal.center_us) / (cal.sign * cal.us_per_rad)


def esc_us(cal: EscCalibration, n_rps: float) -> float:
    """Propeller speed set-point (rev/s, signed) -> pulse width (us): neutral at 0, the deadband
    skipped, linear to max_us (min_us) at n_max_rps (n_max_reverse_rps)."""
    n = cal.sign * n_rps
    if n == 0.0 or not math.isfinite(n):
        return cal.neutral_us
    if n > 0:
        span = cal.max_us - cal.neutral_us - cal.deadband_us
        return cal.neutral_us + cal.deadband_us + span * min(1.0, n / cal.n_max_rps)
    span = cal.neutral_us - cal.deadband_us - cal.min_us
    return cal.neutral_us - cal.deadband_us - span * min(1.0, -n / cal.n_max_reverse_rps)


def esc_rps(cal: EscCalibration, us: float) -> float:
    """Inverse of esc_us: what an ESC with this calibration makes of a pulse (0 in the deadband
    and for 'no pulses' (0 us))."""
    if us <= 0:
        return 0.0
    d = us - cal.neutral_us
    if abs(d) <= cal.deadband_us:
        return 0.0
    if d > 0:
        frac = min(1.0, (d - cal.deadband_us) / (cal.max_us - cal.neutral_us - cal.deadband_us))
        return cal.sign * frac * cal.n_max_rps
    frac = min(1.0, (-d - cal.deadband_us) / (cal.neutral_us - cal.deadband_us - cal.min_us))
    return -cal.sign * frac * cal.n_max_reverse_rps


# -- tachometer -------------------------------------------------------------------------------

class Tachometer:
    """Edge counter for one propeller; `on_edge` runs on pigpio's callback thread."""

    def __init__(self, pulses_per_rev: int, timeout_s: float) -> None:
        self.ppr = pulses_per_rev
        self.timeout_us = int(timeout_s * 1e6)
        self._lock = threading.Lock()
        self._edges = 0  # since the last measure()
        self._last_tick: int | None = None
        self._ref_tick: int | None = None  # last edge of the previous window
        self.total_edges = 0
        self._speed = 0.0

    def on_edge(self, gpio: int, level: int, tick: int) -> None:
        with self._lock:
            self._edges += 1
            self.total_edges += 1
            self._last_tick = tick

    def measure(self, now_tick: int) -> float:
        """Unsigned rev/s since the previous call."""
        with self._lock:
            edges, last, ref = self._edges, self._last_tick, self._ref_tick
            self._edges = 0
            if last is not None:
                self._ref_tick = last
        if last is None or (now_tick - last) % TICK_WRAP > self.timeout_us:
            self._speed = 0.0
            return 0.0
        if edges == 0:
            # no edge in this window: the speed is at most one pulse per elapsed time
            bound = 1e6 / (self.ppr * max(1, (now_tick - last) % TICK_WRAP))
            self._speed = min(self._speed, bound)
            return self._speed
        if ref is None:
            return self._speed  # first edges: no interval yet
        dt_us = (last - ref) % TICK_WRAP
        if dt_us == 0:
            return self._speed
        self._speed = edges * 1e6 / (dt_us * self.ppr)
        return self._speed


# -- speed loop -------------------------------------------------------------------------------

class PropellerSpeedLoop:
    """n_out = n_ref + kp e + I, I += ki e dt, e = n_ref - n_meas (rev/s).

    The feedforward n_ref goes through the ESC calibration, so with a perfect calibration the
    loop has nothing to do; the PI removes calibration error, battery sag and load changes.
    Anti-windup: the integral is clamped to +-integral_limit_rps and frozen while the output
    saturates in the direction of the error (conditional integration). Below min_speed_rps the
    output is neutral and the integral reset (no hunting around the ESC's deadband).
    """

    def __init__(self, gains: SpeedLoopGains, n_max_rps: float, n_max_reverse_rps: float) -> None:
        self.g = gains
        self.n_max = n_max_rps
        self.n_min = -n_max_reverse_rps
        self.integral = 0.0
        self.saturated = False

    def reset(self) -> None:
        self.integral = 0.0

    def update(self, n_ref: float, n_meas: float, dt_s: float, feedback: bool = True) -> float:
        g = self.g
        if abs(n_ref) < g.min_speed_rps:
            self.integral = 0.0
            self.saturated = False
            return 0.0
        if not (g.enabled and feedback):
            self.integral = 0.0
            return min(self.n_max, max(self.n_min, n_ref))
        if n_ref * self.integral < 0 and abs(n_meas) < g.min_speed_rps:
            self.integral = 0.0  # direction reversal: the old integral pushes the wrong way
        e = n_ref - n_meas
        unsat = n_ref + g.kp * e + self.integral
        out = min(self.n_max, max(self.n_min, unsat))
        self.saturated = out != unsat
        if not (self.saturated and e * (unsat - out) > 0):
            self.integral += g.ki_per_s * e * dt_s
            lim = g.integral_limit_rps
            self.integral = min(lim, max(-lim, self.integral))
        return out


# -- pigpio -----------------------------------------------------------------------------------

def pigpio_opener(host: str, port: int) -> Callable[[], Any]:
    def open_pi() -> Any:
        import contextlib
        import io

        import pigpio

        with contextlib.redirect_stdout(io.StringIO()):  # pigpio prints a banner when pigpiod is absent
            pi = pigpio.pi(host, port)
        if not pi.connected:
            raise OSError(f"pigpiod not reachable at {host}:{port} (sudo systemctl start pigpiod)")
        return pi

    return open_pi


@dataclass
class MotorChannel:
    esc_pin: int
    tacho_pin: int
    cal: EscCalibration
    tacho: Tachometer
    loop: PropellerSpeedLoop
    direction: float = 1.0  # sign of the last non-neutral ESC command
    n_meas: float = 0.0
    us: float = 1500.0
    no_pulse_s: float = 0.0
    tacho_fault: bool = False


class ActuatorNode(DriverNode):
    """ship_command -> ESC and servo pulses; tachometers -> rpm_chatter and sim/actuators."""

    name = "actuators"

    def __init__(self, cfg: ActuatorSection, open_pi: Callable[[], Any], limits: ActuatorLimits = DEFAULT_LIMITS,
                 command_deadline_s: float = 0.5) -> None:
        self.period_s = 1.0 / cfg.rate_hz
        super().__init__(threaded=False)  # pulse writes are short socket calls to pigpiod
        self.cfg = cfg
        self.device = f"pigpio {cfg.pigpio_host}:{cfg.pigpio_port}"
        self.health.device = self.device
        self._open_pi = open_pi
        self.pi: Any = None
        self.guard = ActuatorGuard(limits, command_deadline_s)
        self.motors = [
            MotorChannel(cfg.esc_pins[i], cfg.tacho_pins[i], cfg.esc[i],
                         Tachometer(cfg.pulses_per_rev, cfg.tacho_timeout_s),
                         PropellerSpeedLoop(cfg.speed_loop, cfg.esc[i].n_max_rps, cfg.esc[i].n_max_reverse_rps))
            for i in range(3)]
        self._callbacks: list[Any] = []
        self._armed_at_s = math.inf
        self.armed = False
        self.servo_us = [cfg.servo[0].center_us, cfg.servo[1].center_us]
        self._rpm_every = max(1, round(cfg.rate_hz / cfg.rpm_publish_hz))
        self.health.expected_hz = cfg.rate_hz / self._rpm_every
        self._k = 0
        self._last_poll_s: float | None = None

    def on_start(self, ctx: NodeContext) -> None:
        ctx.subscribe(Topic.SHIP_COMMAND, lambda cmd: self.guard.accept(cmd, ctx.now()))

    def open(self, now: float) -> None:
        pi = self._open_pi()
        cfg = self.cfg
        for m in self.motors:
            pi.set_mode(m.esc_pin, PI_OUTPUT)
            pi.set_servo_pulsewidth(m.esc_pin, m.cal.neutral_us)  # ESC arming: neutral first
            pi.set_mode(m.tacho_pin, PI_INPUT)
            pi.set_pull_up_down(m.tacho_pin, PI_PUD_UP if cfg.tacho_pull_up else PI_PUD_OFF)
            self._callbacks.append(pi.callback(m.tacho_pin, RISING_EDGE, m.tacho.on_edge))
        for pin, cal in zip(cfg.servo_pins, cfg.servo):
            pi.set_mode(pin, PI_OUTPUT)
            pi.set_servo_pulsewidth(pin, cal.center_us)
        self.pi = pi
        self._armed_at_s = now + cfg.arm_time_s
        self.armed = False

    def poll(self, now: float) -> Out:
        out: Out = []
        pi, cfg = self.pi, self.cfg
        dt = self.period_s if self._last_poll_s is None else max(1e-4, now - self._last_poll_s)
        self._last_poll_s = now
        was_stale = self.guard.stale
        a1, a2, n1, n2, nt = self.guard.output(now)
        if self.guard.stale and not was_stale:
            self.log(out, now, "warning", "stale thrust command: ESCs to neutral",
                     deadline_s=self.guard.deadline_s)
        if not self.armed and now >= self._armed_at_s:
            self.armed = True
            self.log(out, now, "info", f"ESCs armed after {cfg.arm_time_s:.1f} s of neutral")
        try:
            tick = pi.get_current_tick()
            for m, n_ref in zip(self.motors, (n1, n2, nt)):
                speed = m.tacho.measure(tick)
                m.n_meas = m.direction * speed
                self._check_tacho(m, n_ref, dt, out, now)
                if not self.armed:
                    n_out = 0.0
                    m.loop.reset()
                else:
                    n_out = m.loop.update(n_ref, m.n_meas, dt, feedback=not m.tacho_fault)
                m.us = esc_us(m.cal, n_out)
                if abs(m.us - m.cal.neutral_us) > m.cal.deadband_us:
                    m.direction = 1.0 if n_out > 0 else -1.0
                pi.set_servo_pulsewidth(m.esc_pin, int(round(m.us)))
            for i, (pin, cal, alpha) in enumerate(zip(cfg.servo_pins, cfg.servo, (a1, a2))):
                self.servo_us[i] = servo_us(cal, alpha)
                pi.set_servo_pulsewidth(pin, int(round(self.servo_us[i])))
        except OSError as exc:  # pigpiod gone: reconnect (outputs keep their last pulse in the daemon)
            self.error(out, now, "pigpio_errors", f"{self.device}: {exc}")
            self.health.opened = False
            # not armed until reopened and neutral again for arm_time_s (`open`): we cannot know
            # what the ESCs see (a restarted pigpiod sends no pulses), and AUTO needs armed ESCs;
            # said at once, so the supervisor does not go on with the last "armed" it heard
            was_armed, self.armed, self._armed_at_s = self.armed, False, math.inf
            if was_armed:
                self.log(out, now, "warning", f"{self.device} lost: ESCs reported not armed until re-armed")
            out.append((Topic.ACTUATORS, self._state(now)))
            return out
        self._k += 1
        if self._k % self._rpm_every == 0:
            n = [m.n_meas for m in self.motors]
            self.produced(now)
            out.append((Topic.RPM, RpmSample(stamp_s=now, n1_rps=n[0], n2_rps=n[1], nt_rps=n[2])))
            out.append((Topic.ACTUATORS, self._state(now)))
        return out

    def _state(self, now: float) -> ActuatorState:
        """Measured propeller speeds, the servo angles as commanded to the servos (the guard's
        limits, then the pulse limits and the 1 us resolution of the pulse actually written; no
        servo feedback) and whether the ESCs finished arming."""
        n = [m.n_meas for m in self.motors]
        alpha = [servo_angle(cal, round(us)) for cal, us in zip(self.cfg.servo, self.servo_us)]
        return ActuatorState(stamp_s=now, alpha1_rad=alpha[0], alpha2_rad=alpha[1], n1_rps=n[0], n2_rps=n[1],
                             nt_rps=n[2], escs_armed=self.armed)

    def _check_tacho(self, m: MotorChannel, n_ref: float, dt: float, out: Out, now: float) -> None:
        """No pulses while clearly driving the motor: the tachometer (or motor) has failed; run
        on feedforward alone and say so. Pulses again: feedback resumes."""
        driving = self.armed and abs(n_ref) >= max(5.0, 2 * m.loop.g.min_speed_rps)
        if driving and m.n_meas == 0.0:
            m.no_pulse_s += dt
            if m.no_pulse_s > 2 * self.cfg.tacho_timeout_s and not m.tacho_fault:
                m.tacho_fault = True
                self.error(out, now, "tacho_no_pulses",
                           f"tachometer GPIO {m.tacho_pin}: no pulses at {n_ref:.0f} rev/s commanded;"
                           " speed loop on feedforward only")
        elif m.n_meas != 0.0:
            if m.tacho_fault:
                self.log(out, now, "info", f"tachometer GPIO {m.tacho_pin}: pulses again")
            m.no_pulse_s = 0.0
            m.tacho_fault = False

    def neutral(self) -> None:
        """All ESCs to neutral, servos centred (shutdown, errors)."""
        if self.pi is None:
            return
        for m in self.motors:
            self.pi.set_servo_pulsewidth(m.esc_pin, int(m.cal.neutral_us))
        for pin, cal in zip(self.cfg.servo_pins, self.cfg.servo):
            self.pi.set_servo_pulsewidth(pin, int(cal.center_us))

    def close(self) -> None:
        if self.pi is None:
            return
        try:
            self.neutral()
            for cb in self._callbacks:
                cb.cancel()
            for m in self.motors:  # pulses off: the ESC's signal-loss failsafe keeps it stopped
                self.pi.set_servo_pulsewidth(m.esc_pin, 0)
            for pin in self.cfg.servo_pins:
                self.pi.set_servo_pulsewidth(pin, 0)
            self.pi.stop()
        finally:
            self.pi = None
            self._callbacks = []

    def command_neutral(self, now: float) -> None:
        self.guard.accept(ThrustCommand.neutral(now, source="actuators"), now)
