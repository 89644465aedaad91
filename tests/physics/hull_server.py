"""The independent 6-DOF hulls as an ArduPilot SITL JSON physics server: hull6dof.py (the monohull,
default) or, with `--hull b`, hull_b.py (the catamaran, issue 47).

Written from the protocol as ArduPilot documents it (libraries/SITL/examples/JSON/readme.md and
SIM_JSON.cpp: a binary servo packet in, one JSON state line out), not from lotsen's client: it
imports nothing of lotsen. Any flight controller that speaks the protocol can fly it, lotsen's
`--physics udp:HOST:PORT` among them:

    python tests/physics/hull_server.py --port 9002 [--hull 6dof|b] [--wind 4,250 --gusts 0.2 --wander 15]
        [--current 0.08,30] [--waves 0.03,0.8,250 --wave-spreading 2] [--seed 0]

Hull B models no waves and a constant current: `--hull b` with `--waves` or `--current-variation` is
refused, not dropped.

Servo channels (lotsen's default channel map, docs/physics.md): SERVO1 azimuth 1 (starboard) angle,
SERVO2 azimuth 2 angle, SERVO3 / SERVO4 their propellers, SERVO5 the bow thruster; 1000-1500-2000
microseconds for -full .. 0 .. +full with +-45 deg, +-100 rev/s, +-80 rev/s; 0 (a channel nobody
drives) is neutral. One frame steps the hull 1 / frame_rate seconds (in its own 5 ms steps).

The reply has the 6-DOF state (roll, pitch, heave included; the accelerometer's specific force
with gravity) and lotsen's optional extensions: the achieved actuators and their mean over the
frame ("lotsen": {"actuators", "actuators_mean"}); it honours lotsen's place request
({"lotsen": {"place": [N, E, psi, u, v, r]}}): the hull is put there, level, and its state sent.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import socket
import struct
import sys
import threading
from dataclasses import fields
from pathlib import Path
from typing import Any, NamedTuple

sys.path.insert(0, str(Path(__file__).parent))

from hull6dof import (Hull6DOF, HullEnvironment, HullParameters, add_environment_arguments,  # noqa: E402
                     environment_arguments)
from hull_b import CatamaranEnvironment, CatamaranHull, CatamaranParameters  # noqa: E402


class HullKind(NamedTuple):
    """A hull the server can serve: its class, parameters and environment types, its name."""

    hull: type
    parameters: type
    environment: type
    name: str


HULLS = {"6dof": HullKind(Hull6DOF, HullParameters, HullEnvironment, "6-DOF hull"),
         "b": HullKind(CatamaranHull, CatamaranParameters, CatamaranEnvironment, "hull B (catamaran)")}


def environment_for(hull: str, values: dict[str, Any]) -> Any:
    """The water and air flags (`environment_arguments`) as `hull`'s environment. A flag the hull does
    not model (hull B: waves, a varying current) is refused with a ValueError rather than dropped: a
    run would otherwise be calmer than asked."""
    kind = HULLS[hull]
    known = {f.name for f in fields(kind.environment)}
    unset = HullEnvironment()
    dropped = sorted(k for k, v in values.items() if k not in known and v != getattr(unset, k))
    if dropped:
        raise ValueError(f"{kind.name} does not model {', '.join(dropped)}")
    return kind.environment(**{k: v for k, v in values.items() if k in known})

PACKET_16 = struct.Struct("<HHI16H")
PACKET_32 = struct.Struct("<HHI32H")
MAGIC_16, MAGIC_32 = 18458, 29569
PWM_MIN, PWM_NEUTRAL, PWM_MAX = 1000, 1500, 2000
FULL_SCALE = (math.radians(45.0), math.radians(45.0), 100.0, 100.0, 80.0)  # SERVO1..5


def pwm_to_setpoints(pwm: tuple[int, ...]) -> tuple[float, ...]:
    out = []
    for ch, full in enumerate(FULL_SCALE):
        p = pwm[ch]
        if p <= 0:
            out.append(0.0)
            continue
        p = min(max(p, PWM_MIN), PWM_MAX)
        f = (p - PWM_NEUTRAL) / ((PWM_MAX - PWM_NEUTRAL) if p >= PWM_NEUTRAL else (PWM_NEUTRAL - PWM_MIN))
        out.append(f * full)
    return tuple(out)


class HullServer:
    """`hull` (a key of HULLS) on a UDP socket; `params` and `environment` of that hull's types (default:
    its defaults, calm)."""

    def __init__(self, params: Any = None, environment: Any = None, host: str = "127.0.0.1", port: int = 9002,
                 pose: tuple[float, float, float] = (0.0, 0.0, 0.0), hull: str = "6dof") -> None:
        self.kind = HULLS[hull]
        self.params = self.kind.parameters() if params is None else params
        self.environment = self.kind.environment() if environment is None else environment
        self.pose = pose
        self.hull = self.kind.hull(self.params, self.environment, pose=pose)
        self.mean = self.hull.actuators
        self.last_frame: int | None = None
        self.reply: bytes | None = None
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((host, port))
        self.address = self.sock.getsockname()
        self.frames = 0

    def state_line(self) -> bytes:
        h = self.hull
        x, y, z, phi, theta, psi = h.eta
        _, _, _, p, q, r = h.nu
        vel, f = h.measure()
        state: dict[str, Any] = {
            "timestamp": h.t,
            "imu": {"gyro": [p, q, r], "accel_body": list(f)},
            "position": [x, y, z], "velocity": list(vel), "attitude": [phi, theta, psi],
            "lotsen": {"actuators": list(h.actuators), "actuators_mean": list(self.mean)},
        }
        return ("\n" + json.dumps(state) + "\n").encode()

    def handle(self, data: bytes) -> bytes | None:
        if data.lstrip()[:1] == b"{":  # lotsen's place request
            try:
                pose = json.loads(data)["lotsen"]["place"]
                n, e, psi, u, v, r = (float(a) for a in pose)
            except (ValueError, KeyError, TypeError):
                return None
            self.pose = (n, e, psi)
            self.hull.reset((n, e, psi), t_s=self.hull.t)
            self.hull.set_velocity(u, v, r)
            self.mean = self.hull.actuators
            self.last_frame = None
            self.reply = self.state_line()
            return self.reply
        if len(data) == PACKET_16.size:
            fields = PACKET_16.unpack(data)
            if fields[0] != MAGIC_16:
                return None
        elif len(data) == PACKET_32.size:
            fields = PACKET_32.unpack(data)
            if fields[0] != MAGIC_32:
                return None
        else:
            return None
        frame_rate, frame_count, pwm = fields[1], fields[2], fields[3:]
        if frame_rate == 0:
            return None
        if self.last_frame is not None and frame_count < self.last_frame:  # the controller restarted
            self.hull = self.kind.hull(self.params, self.environment, pose=self.pose)
            self.last_frame = None
        if frame_count != self.last_frame or self.reply is None:  # a repeated count: answer again, no step
            self.hull.command(*pwm_to_setpoints(pwm))
            self.mean = self.hull.advance(1.0 / frame_rate)
            self.reply = self.state_line()
            self.last_frame = frame_count
            self.frames += 1
        return self.reply

    def serve(self, stop: threading.Event | None = None) -> None:
        self.sock.settimeout(0.2)
        while stop is None or not stop.is_set():
            try:
                data, peer = self.sock.recvfrom(2048)
            except socket.timeout:
                continue
            except OSError:
                return
            reply = self.handle(data)
            if reply is not None:
                self.sock.sendto(reply, peer)

    def serve_in_thread(self) -> tuple[threading.Thread, threading.Event]:
        stop = threading.Event()
        thread = threading.Thread(target=self.serve, args=(stop,), name="hull-server", daemon=True)
        thread.start()
        return thread, stop

    def close(self) -> None:
        self.sock.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="an independent 6-DOF hull as an ArduPilot SITL JSON physics")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=9002)
    ap.add_argument("--hull", choices=sorted(HULLS), default="6dof",
                    help="6dof: hull6dof.py, the monohull (default); b: hull_b.py, the catamaran")
    ap.add_argument("--realtime", action="store_true",
                    help="run at real-time priority (SCHED_RR 10, just below lotsen's core loop) where permitted: "
                         "a physics at wall-clock pace must get the CPU when the core waits for it (at nice 0 on "
                         "a loaded two-core machine it went silent for up to 0.34 s)")
    add_environment_arguments(ap)
    a = ap.parse_args(argv)
    if a.realtime:
        try:
            os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(10))
        except (AttributeError, PermissionError, OSError):
            pass  # not permitted here: the server runs at normal priority
    try:  # the hull refuses what it does not model (hull B: waves)
        server = HullServer(environment=environment_for(a.hull, environment_arguments(a)), host=a.host, port=a.port,
                            hull=a.hull)
    except ValueError as e:
        ap.error(str(e))
    print(f"{server.kind.name} listening on udp:{server.address[0]}:{server.address[1]}", flush=True)
    try:
        server.serve()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
