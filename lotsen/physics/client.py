"""`UdpPhysics`: an external physics behind lotsen's `Plant` interface, over ArduPilot SITL's JSON
protocol (`lotsen.physics.protocol`). lotsen plays ArduPilot's side: it sends servo packets and
receives the physics's state, in lock-step, and its own sensor models (`lotsen.sim.Simulator`)
make the sensor messages from that state.

Timing. The physics time drives the clock: lotsen asks for frames of 1 / dt_s (frame_rate 100 at
the default 10 ms) and one lotsen step is as many frames as it takes for the physics's timestamp
to advance by dt_s from where step k should end (t0 + (k + 1) dt_s); a physics that steps finer
is stepped several frames per lotsen step, one that steps coarser is sampled at its own rate
(lotsen's sensors reuse its last state in between). On simulated time the run advances only when
the physics has answered; at wall-clock pace (`lotsen run`) the simulated boat node steps the
physics as the clock advances.

Start. Before its first frame lotsen asks the physics to place the boat at the run's start
(lotsen's `place` extension). A physics that does not know the extension does not answer it: then
lotsen sends frame 0 at neutral and takes the physics's pose as the start, mapping its frame
rigidly onto the requested start pose (position and heading; reported in `status()`).

Failures. A frame that gets no reply within `timeout_s` (on simulated time; `realtime_timeout_s`
at wall-clock pace, where the wait holds up the control loop) is counted (`timeouts`) and sent
again with the same frame count at the next step (a physics answers a repeated count without
stepping twice); at wall-clock pace, until a reply comes, frames wait at most 5 ms. While no fresh state has come,
`step()` returns None: the simulator measures nothing, the sensors go stale and the failsafes act.
After `lost_after_s` without a reply the physics is `lost`: lotsen no longer waits for it (it only
polls, so a lost physics never stalls the loop) and resumes when a reply comes (`recoveries`). A reply that is not a valid state line is counted
(`corrupt`) and dropped; one whose timestamp is not newer than the last is a late duplicate
(`stale`) and dropped; a physics time that runs backwards is a restart of the physics (`resets`).
Without a first state within `connect_timeout_s` the run cannot start: PhysicsError.

Actuators. If the physics reports the achieved actuators (lotsen's `actuators` extension), those
are the boat's; otherwise lotsen's actuator model (servo slew, motor lag, with the channel map's
limits) stands in for them, for the tachometers, the battery and actuators/state.
"""

from __future__ import annotations

import math
import socket
import time
from typing import Any, Callable, Sequence

from lotsen.errors import LotsenError
from lotsen.model.angles import wrap_angle
from lotsen.model.parameters import DEFAULT_LIMITS, ActuatorLimits
from lotsen.physics.config import PhysicsConfig
from lotsen.physics.protocol import (
    MAX_REPLY_BYTES, PhysicsState, ProtocolError, ServoPacket, decode_state, encode_place, encode_servo,
)
from lotsen.sim.actuators import ActuatorDynamics
from lotsen.sim.plant import Plant, PlantError, PlantSample, planar_state
from lotsen.sim.waves import BodyMotion

#: a placed pose counts as honoured within these (m, rad)
PLACE_TOLERANCE = (1e-3, 1e-3)
#: most frames in one lotsen step before lotsen re-anchors its time on the physics's
MAX_FRAMES_PER_STEP = 64


class PhysicsError(LotsenError):
    """The external physics cannot be reached or does not answer as the protocol says."""


class UdpPhysics(Plant):
    """An external physics at `config.address` (udp:HOST:PORT) as a lotsen plant (module docstring)."""

    def __init__(self, config: PhysicsConfig, dt_s: float = 0.01, base_limits: ActuatorLimits = DEFAULT_LIMITS,
                 realtime: bool = False, place_wait_s: float = 0.3, clock: Callable[[], float] = time.monotonic) -> None:
        host, port = config.host_port
        self.config = config
        self.address = f"udp:{host}:{port}"
        self.name = f"external physics at {self.address}"
        self.dt_s = dt_s
        self.servos = config.servos
        self.limits = self.servos.limits(base_limits)
        self.gnss_antenna_m = tuple(config.gnss_antenna_m)  # type: ignore[assignment]
        self.gnss_antenna_height_m = config.gnss_antenna_height_m
        self.actuators = ActuatorDynamics(self.limits, dt_s)  # set-points; stand-in model if not reported
        self.frame_rate_hz = max(1, int(round(1.0 / dt_s)))
        self.connect_timeout_s = config.connect_timeout_s
        # how long a frame waits for its reply: on simulated time as long as a slow physics needs,
        # at wall-clock pace no longer than the control loop can give
        self.wait_s = config.realtime_timeout_s if realtime else config.timeout_s
        # at wall-clock pace, once a frame went unanswered the next ones hardly wait (a dead physics
        # must not hold the loop up frame after frame); on simulated time waiting costs no run time
        self.wait_unanswered_s = min(self.wait_s, 0.005) if realtime else self.wait_s
        self.place_wait_s = place_wait_s
        self._clock = clock
        self._sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.connect((host, port))
        except OSError as exc:
            self._sock.close()
            raise PhysicsError(f"{self.address}: cannot reach it ({exc.strerror or exc})") from None
        self._started = False
        self._k = 0
        self._count = 0  # frame count of the last frame sent
        self._answered = True  # the last frame has its reply (else: send it again, same count)
        self._pwm = self.servos.to_pwm((0.0,) * 5)
        self._state: PhysicsState | None = None
        self._t_phys = -math.inf
        self._t0 = 0.0
        self._x: tuple[float, ...] = (0.0,) * 6
        self._x_dot: tuple[float, ...] = (0.0,) * 6
        self._motion: BodyMotion | None = None  # the physics's attitude, body rates and specific force
        self._step_input: tuple[float, ...] = (0.0,) * 5
        self._fresh = False
        self._silent_since: float | None = None
        self._frame_map: tuple[float, float, float, float, float] | None = None  # dpsi, N0p, E0p, N0, E0
        self.lost = False
        self.lost_at_s: float | None = None  # run time (s) when the physics was declared lost
        self.silent_at_s: float | None = None  # run time of the first frame of the present silence
        self.counters = {"frames": 0, "replies": 0, "timeouts": 0, "corrupt": 0, "stale": 0, "resets": 0,
                         "resyncs": 0, "recoveries": 0}
        self.last_problem = ""
        self.placed = False  # the physics put the boat where lotsen asked

    # -- the Plant interface -------------------------------------------------------------------
    @property
    def fresh(self) -> bool:
        return self._fresh

    def command(self, u: Sequence[float]) -> None:
        self.actuators.set_command(*u)  # clipped to the channels' limits, NaN -> neutral

    def place(self, x: Sequence[float]) -> None:
        """Start the exchange with the boat at x (before the first step only)."""
        if self._started:
            raise PlantError(f"{self.name}: the boat can be placed only before the run starts")
        self._start(tuple(float(v) for v in x))

    def set_faults(self, failed_units: set[int] = frozenset(), stuck_servos: set[int] = frozenset()) -> None:
        self.actuators.set_faults(failed_units, stuck_servos)  # applied to what is sent (_effective_command)

    def close(self) -> None:
        self._sock.close()

    def status(self) -> dict[str, Any]:
        out: dict[str, Any] = {"physics": self.address, **self.counters, "lost": self.lost,
                               "placed": self.placed, "physics_time_s": self._t_phys - self._t0}
        if self.lost_at_s is not None:
            out["lost_at_s"] = round(self.lost_at_s, 3)
        if self.silent_at_s is not None:
            out["silent_since_s"] = round(self.silent_at_s, 3)
        if self._frame_map is not None:
            out["frame_rotated_deg"] = round(math.degrees(self._frame_map[0]), 3)
        if self.last_problem:
            out["last_problem"] = self.last_problem
        return out

    def describe(self, reference: Any = None) -> str:
        return self.name

    def step(self) -> PlantSample | None:
        if not self._started:
            self._start(None)
        sample = PlantSample(self._x, self._x_dot, tuple(self.actuators.state), self._motion) if self._fresh else None
        self._pwm = self.servos.to_pwm(self._effective_command())
        a_before = tuple(self.actuators.state)
        target = self._t0 + (self._k + 1) * self.dt_s
        got_state = timed_out = False
        frames = 0
        while self._t_phys < target - 1e-9:
            state = self._frame()
            if state is None:
                timed_out = True
                break
            self._accept(state)
            got_state = True
            frames += 1
            if frames >= MAX_FRAMES_PER_STEP:  # far behind: take the physics's time from here
                self.counters["resyncs"] += 1
                self._t0 = self._t_phys - (self._k + 1) * self.dt_s
                break
        self._k += 1
        # no frame needed (a physics stepping coarser than dt_s): its last state still stands
        self._fresh = got_state or (not timed_out and self._fresh)
        if self._state is None or self._state.actuators is None:  # lotsen's actuator model stands in
            self.actuators.step()
        a_after = tuple(self.actuators.state)
        mean = self._state.actuators_mean if self._state is not None and self._state.actuators_mean else None
        self._step_input = mean or tuple(0.5 * (p + q) for p, q in zip(a_before, a_after))
        return sample

    # -- the exchange --------------------------------------------------------------------------
    def _effective_command(self) -> tuple[float, ...]:
        """The set-point with the injected faults: a failed unit's propeller stopped, a stuck servo
        held where it is."""
        a = self.actuators
        c = list(a.command)
        f = a.faults
        for i in f.stuck_servos:
            c[i] = a.state[i]
        for i in f.failed_units:
            c[2 + i] = 0.0
        return tuple(c)

    def _send(self, data: bytes) -> None:
        try:
            self._sock.send(data)
        except OSError as exc:  # no route, buffer full: the reply will not come; counted as a timeout
            self.last_problem = f"send: {exc.strerror or exc}"

    def _receive(self, wait_s: float) -> PhysicsState | None:
        """The next valid state newer than the last one, waiting at most `wait_s` (0: poll)."""
        deadline = self._clock() + wait_s
        while True:
            remaining = deadline - self._clock()
            try:
                self._sock.settimeout(max(remaining, 0.0) if wait_s > 0 else 0.0)
                data = self._sock.recv(MAX_REPLY_BYTES + 1)
            except (socket.timeout, BlockingIOError):
                return None
            except OSError as exc:  # ICMP port unreachable (nobody listens), refused: like silence
                self.last_problem = f"receive: {exc.strerror or exc}"
                if remaining <= 0:
                    return None
                time.sleep(min(remaining, 0.005))
                continue
            try:
                state = decode_state(data)
            except ProtocolError as exc:
                self.counters["corrupt"] += 1
                self.last_problem = f"corrupt reply: {exc}"
                continue
            if state.timestamp_s <= self._t_phys:
                if self._state is not None and state.timestamp_s < self._state.timestamp_s - 1.0:
                    return state  # the physics restarted (its time runs from the start again)
                self.counters["stale"] += 1
                continue
            return state

    def _frame(self) -> PhysicsState | None:
        """Send the next frame (or the unanswered one again) and wait for its state."""
        if self._answered:
            self._count = (self._count + 1) & 0xFFFFFFFF
        self.counters["frames"] += 1
        self._send(encode_servo(ServoPacket(self.frame_rate_hz, self._count, self._pwm)))
        # a lost physics is only polled
        state = self._receive(0.0 if self.lost else self.wait_s if self._answered else self.wait_unanswered_s)
        self._answered = state is not None
        now = self._clock()
        if state is None:
            self.counters["timeouts"] += 1
            if self._silent_since is None:
                self._silent_since = now
                self.silent_at_s = self._k * self.dt_s
            if not self.lost and now - self._silent_since >= self.config.lost_after_s:
                self.lost = True
                self.lost_at_s = self._k * self.dt_s
            return None
        self._silent_since = None
        self.silent_at_s = None
        if self.lost:
            self.lost = False
            self.counters["recoveries"] += 1
        return state

    def _accept(self, state: PhysicsState) -> None:
        if self._state is not None and state.timestamp_s < self._state.timestamp_s:
            self.counters["resets"] += 1  # the physics restarted: re-anchor lotsen's time on it
            self._t0 = state.timestamp_s - self._k * self.dt_s
        self.counters["replies"] += 1
        r_prev = self._x[5]
        t_prev = self._t_phys
        self._state = state
        self._t_phys = state.timestamp_s
        n, e, _ = state.position_ned_m
        vn, ve, _ = state.velocity_ned_mps
        psi = state.attitude_rad[2]
        m = self._frame_map
        if m is not None:  # the physics's frame moved rigidly onto the requested start
            dpsi, n0p, e0p, n0, e0 = m
            c, s = math.cos(dpsi), math.sin(dpsi)
            dn, de = n - n0p, e - e0p
            n, e = n0 + c * dn - s * de, e0 + s * dn + c * de
            vn, ve = c * vn - s * ve, s * vn + c * ve
            psi += dpsi
        psi = wrap_angle(psi)
        r = state.gyro_radps[2]
        dt = state.timestamp_s - t_prev
        r_dot = (r - r_prev) / dt if math.isfinite(dt) and dt > 0 else 0.0
        roll, pitch = state.attitude_rad[0], state.attitude_rad[1]
        self._x, self._x_dot = planar_state(n, e, psi, (vn, ve), r, state.accel_body_mps2[:2], roll, pitch, r_dot,
                                            state.gyro_radps[1])
        # what the physics's IMU reports, for lotsen's IMU model: the attitude, the body rates and the
        # specific force with gravity, as an accelerometer on the rolling, pitching hull measures it
        self._motion = BodyMotion(roll, pitch, state.position_ned_m[2], state.gyro_radps[0], state.gyro_radps[1],
                                  tuple(state.accel_body_mps2), r)
        if state.actuators is not None:
            self.actuators.state = tuple(state.actuators)

    def _start(self, x0: tuple[float, ...] | None) -> None:
        """The first state: the boat placed at x0 (the place extension), else the physics's own pose
        after a neutral frame 0, mapped onto x0 when one was asked for."""
        self._started = True
        state = None
        if x0 is not None:
            self._send(encode_place(x0))
            state = self._receive(self.place_wait_s)
            if state is not None and (math.hypot(state.position_ned_m[0] - x0[0], state.position_ned_m[1] - x0[1])
                                      <= PLACE_TOLERANCE[0]
                                      and abs(wrap_angle(state.attitude_rad[2] - x0[2])) <= PLACE_TOLERANCE[1]):
                self.placed = True
            else:
                state = None
        if state is None:
            self._count = 0
            self._answered = False  # frame 0 is sent (and resent) until it is answered
            deadline = self._clock() + self.connect_timeout_s
            while state is None and self._clock() < deadline:
                self._send(encode_servo(ServoPacket(self.frame_rate_hz, self._count, self._pwm)))
                self.counters["frames"] += 1
                state = self._receive(min(self.config.timeout_s * 4, max(deadline - self._clock(), 0.0)))
            if state is None:
                raise PhysicsError(
                    f"{self.address}: no physics answers (waited {self.connect_timeout_s:g} s for a state; "
                    f"{self.counters['corrupt']} corrupt replies"
                    + (f", last: {self.last_problem}" if self.last_problem else "")
                    + "): is the physics server running there?")
            self._answered = True
            if x0 is not None:
                self._frame_map = (wrap_angle(x0[2] - state.attitude_rad[2]), state.position_ned_m[0],
                                   state.position_ned_m[1], x0[0], x0[1])
        self._accept(state)
        self._t0 = self._t_phys
        self._fresh = True
