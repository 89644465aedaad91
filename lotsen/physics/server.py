"""The reference physics server: a plant (lotsen's own simulated boat, by default) served over
ArduPilot SITL's JSON protocol, the physics's side of `lotsen.physics.protocol`.

`lotsen physics-server` runs it; `lotsen mission ROUTE --physics udp:HOST:PORT` against it
reproduces the built-in `lotsen mission ROUTE --sim` (same route and seed: the same events, the
cross-track error within 2 %, tests/physics/test_seam.py) because the server steps the very plant the
built-in run steps and lotsen's sensors stay on lotsen's side, on the same seed.

Per datagram:
- a servo packet with a new frame count: the set-points decoded from the PWM (the channel map),
  the plant stepped 1 / frame_rate (in steps of its own dt), the state sent back;
- the same frame count again (a retransmission): the last state again, no step;
- a smaller frame count (the flight controller restarted): the plant is rebuilt, then stepped;
- frame_rate 0 or anything that is not a servo packet or a place request: ignored;
- lotsen's place request: the plant placed there (pose and velocities), its state sent back.
The reply carries lotsen's `actuators` extension (the achieved actuator values and their mean over
the last step), so lotsen's tachometers and logs see the plant's own actuators.
"""

from __future__ import annotations

import math
import socket
import threading
from typing import Any, Callable

from lotsen.model.environment import GRAVITY_MPS2
from lotsen.physics.config import ChannelMap
from lotsen.physics.protocol import (
    PhysicsState, ProtocolError, decode_place, decode_servo, encode_state,
)
from lotsen.sim.plant import Plant


def plant_state(plant: Plant, t_s: float) -> PhysicsState:
    """The state line of a plant: its planar state; the accelerometer's specific force from the
    plant's rate now (`rate_now` where the plant has it, else its last x_dot). A level boat in flat
    water (heave 0); in waves the attitude, heave, body rates and specific force of its motion out of
    the plane (`motion_now`)."""
    n, e, psi, u, v, r = plant.x
    rate = getattr(plant, "rate_now", None)
    xd = rate() if rate is not None else plant.x_dot
    c, s = math.cos(psi), math.sin(psi)
    accel_xy = (xd[3] - v * r, xd[4] + u * r)
    motion_now = getattr(plant, "motion_now", None)
    m = motion_now(accel_xy) if motion_now is not None else None
    if m is None:
        p = q = roll = pitch = heave = 0.0
        f = (accel_xy[0], accel_xy[1], -GRAVITY_MPS2)
    else:
        p, q, roll, pitch, heave, f = m.p_radps, m.q_radps, m.roll_rad, m.pitch_rad, m.heave_m, m.specific_force_mps2
        r = m.r_radps
    return PhysicsState(
        timestamp_s=t_s, gyro_radps=(p, q, r), accel_body_mps2=tuple(f),
        position_ned_m=(n, e, heave), velocity_ned_mps=(c * u - s * v, s * u + c * v, 0.0),
        attitude_rad=(roll, pitch, psi), actuators=tuple(plant.actuators.state), actuators_mean=tuple(plant.step_input))


class PhysicsServer:
    """Serves the plant `make_plant()` builds at udp://host:port (module docstring)."""

    def __init__(self, make_plant: Callable[[], Plant], servos: ChannelMap = ChannelMap(), host: str = "127.0.0.1",
                 port: int = 9002) -> None:
        self.make_plant = make_plant
        self.servos = servos
        self.plant = make_plant()
        # compiled kernels now, not while the first client waits for its first state
        self.plant.warm_up()
        plant_state(self.plant, 0.0)
        self.t_s = 0.0
        self._last_count: int | None = None
        self._reply: bytes | None = None
        self.sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.address = self.sock.getsockname()[:2]
        self.counters = {"frames": 0, "repeats": 0, "restarts": 0, "places": 0, "ignored": 0}

    def handle(self, data: bytes) -> bytes | None:
        """The reply to one datagram (None: no reply)."""
        place = decode_place(data)
        if place is not None:
            self.plant.place(place)
            self._last_count = None
            self.counters["places"] += 1
            self._reply = encode_state(plant_state(self.plant, self.t_s))
            return self._reply
        try:
            pkt = decode_servo(data)
        except ProtocolError:
            self.counters["ignored"] += 1
            return None
        if pkt.frame_rate_hz == 0:
            self.counters["ignored"] += 1
            return None
        if self._last_count is not None and pkt.frame_count == self._last_count and self._reply is not None:
            self.counters["repeats"] += 1
            return self._reply
        if self._last_count is not None and pkt.frame_count < self._last_count:
            self.counters["restarts"] += 1
            self.plant = self.make_plant()
            self.t_s = 0.0
        self._last_count = pkt.frame_count
        self.counters["frames"] += 1
        self.plant.command(self.servos.from_pwm(pkt.pwm_us))
        steps = max(1, int(round(1.0 / (pkt.frame_rate_hz * self.plant.dt_s))))
        for _ in range(steps):
            self.plant.step()
        self.t_s += steps * self.plant.dt_s
        self._reply = encode_state(plant_state(self.plant, self.t_s))
        return self._reply

    def serve(self, stop: threading.Event | None = None, poll_s: float = 0.2) -> None:
        """Answer datagrams until `stop` is set (or forever)."""
        self.sock.settimeout(poll_s)
        while stop is None or not stop.is_set():
            try:
                data, peer = self.sock.recvfrom(4096)
            except socket.timeout:
                continue
            except OSError:
                if stop is not None and stop.is_set():
                    return
                raise
            reply = self.handle(data)
            if reply is not None:
                try:
                    self.sock.sendto(reply, peer)
                except OSError:
                    pass  # the client went away; it sends again or not

    def serve_in_thread(self) -> tuple[threading.Thread, threading.Event]:
        stop = threading.Event()
        thread = threading.Thread(target=self.serve, args=(stop,), name="physics-server", daemon=True)
        thread.start()
        return thread, stop

    def close(self) -> None:
        self.sock.close()

    def status(self) -> dict[str, Any]:
        return {"address": f"udp:{self.address[0]}:{self.address[1]}", "t_s": round(self.t_s, 3), **self.counters}
