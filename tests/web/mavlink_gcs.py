"""A ground station for the tests: pymavlink as QGroundControl or MAVProxy use MAVLink, with a
reader thread that keeps every message (so a test can wait for one that already came), and
`lotsen run --mavlink ...` started from another directory at wall-clock pace.

Nothing here imports the endpoint under test: the ground station knows MAVLink, the token and the
boat's ports, as an operator's tablet does."""

from __future__ import annotations

import hashlib
import os
import secrets
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Callable

import yaml

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

from lotsen.runtime.clock import CLOCK_ENV  # noqa: E402
from lotsen.runtime.lifetime import RUNTIME_DIR_ENV  # noqa: E402
from lotsen.stack.processes import free_port  # noqa: E402
from lotsen.stack.soak import derive_run_config  # noqa: E402

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def free_udp_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Boat:
    """`python -m lotsen run CONFIG --sim --mavlink udpout:127.0.0.1:P ...` (one endpoint per ground
    station, each sending to its port as ArduPilot SITL sends to 14550)."""

    def __init__(self, work: Path, gcs_ports: list[int], esc_arm_time_s: float = 8.0) -> None:
        (work / "elsewhere").mkdir(parents=True, exist_ok=True)
        self.token = secrets.token_urlsafe(24)
        self.web_port = free_port()
        path = derive_run_config(CONFIG, work, self.web_port, self.token)
        data = yaml.safe_load(path.read_text())
        data["sim"]["esc_arm_time_s"] = esc_arm_time_s  # a window in which arming is refused: "PreArm"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        args = [sys.executable, "-m", "lotsen", "run", str(path), "--sim"]
        for port in gcs_ports:
            args += ["--mavlink", f"udpout:127.0.0.1:{port}"]
        env = {**os.environ, CLOCK_ENV: repr(time.monotonic()), "PYTHONUNBUFFERED": "1",
               RUNTIME_DIR_ENV: str(work / "run-locks")}
        self.proc = subprocess.Popen(args, cwd=work / "elsewhere", env=env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL)
        self.output: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line.rstrip())

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        return self.proc.returncode


class GroundStation:
    """pymavlink listening where the boat sends (udpin), system 255 like MAVProxy and QGroundControl."""

    def __init__(self, port: int, system: int = 255, component: int = 190) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=system,
                                               source_component=component, dialect="ardupilotmega")
        self.log: list[tuple[float, Any]] = []
        self._cv = threading.Condition()
        self._stop = threading.Event()
        self.heartbeats = True
        self._send_lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=self._beat, daemon=True).start()

    def _read(self) -> None:
        while not self._stop.is_set():
            try:
                m = self.conn.recv_match(blocking=True, timeout=0.2)
            except OSError:  # closed
                return
            if m is None or m.get_type() == "BAD_DATA":
                continue
            with self._cv:
                self.log.append((time.monotonic(), m))
                self._cv.notify_all()

    def _beat(self) -> None:
        """1 Hz HEARTBEAT as a GCS (type 6), once the boat is known (udpin replies to the sender)."""
        while not self._stop.wait(1.0):
            if self.heartbeats and self.conn.target_system:
                self.send(lambda mav: mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS,
                                                         mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0))

    def send(self, fn: Callable[[Any], None]) -> None:
        with self._send_lock:
            fn(self.conn.mav)

    def sign(self, token: str) -> None:
        self.conn.setup_signing(hashlib.sha256(token.encode()).digest(), sign_outgoing=True)

    def wait(self, pred: Callable[[Any], bool], timeout_s: float, since: float = 0.0) -> Any:
        """The first message (arrived after `since`) for which `pred` holds, else None at the timeout."""
        end = time.monotonic() + timeout_s
        with self._cv:
            k = 0
            while True:
                for t, m in self.log[k:]:
                    if t >= since and pred(m):
                        return m
                k = len(self.log)
                left = end - time.monotonic()
                if left <= 0:
                    return None
                self._cv.wait(left)

    def texts(self, since: float = 0.0) -> list[str]:
        """STATUSTEXT since `since`, chunks (id, chunk_seq) joined."""
        out: dict[Any, str] = {}
        with self._cv:
            for t, m in self.log:
                if t >= since and m.get_type() == "STATUSTEXT":
                    key = m.id or object()
                    out[key] = out.get(key, "") + m.text
        return list(out.values())

    def command(self, command: int, *params: float, timeout_s: float = 10.0) -> tuple[Any, list[str]]:
        """COMMAND_LONG to the boat; (its COMMAND_ACK or None, the STATUSTEXTs that came with it)."""
        t0 = time.monotonic()
        p = list(params) + [0.0] * (7 - len(params))
        self.send(lambda mav: mav.command_long_send(1, 1, command, 0, *p))
        ack = self.wait(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command, timeout_s, since=t0)
        time.sleep(0.05)
        return ack, self.texts(since=t0)

    def upload(self, items: list[tuple], mission_type: int = 0, timeout_s: float = 30.0) -> Any:
        """The mission protocol's upload: MISSION_COUNT, then each requested item as MISSION_ITEM_INT
        (items: (command, frame, p1, p2, p3, p4, lat, lon, alt)); returns the MISSION_ACK."""
        t0 = time.monotonic()
        self.send(lambda mav: mav.mission_count_send(1, 1, len(items), mission_type))
        sent = set()
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            m = self.wait(lambda m: (m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST")
                                     and getattr(m, "mission_type", 0) == mission_type and m.seq not in sent)
                          or (m.get_type() == "MISSION_ACK" and m.mission_type == mission_type), 5.0, since=t0)
            if m is None:
                return None
            if m.get_type() == "MISSION_ACK":
                return m
            cmd, frame, p1, p2, p3, p4, lat, lon, alt = items[m.seq]
            self.send(lambda mav: mav.mission_item_int_send(1, 1, m.seq, frame, cmd, int(m.seq == 0), 1, p1, p2, p3, p4,
                                                            int(round(lat * 1e7)), int(round(lon * 1e7)), alt,
                                                            mission_type))
            sent.add(m.seq)
        return None

    def download(self, mission_type: int = 0, timeout_s: float = 10.0) -> list[Any] | None:
        t0 = time.monotonic()
        self.send(lambda mav: mav.mission_request_list_send(1, 1, mission_type))
        count = self.wait(lambda m: m.get_type() == "MISSION_COUNT" and m.mission_type == mission_type, timeout_s,
                          since=t0)
        if count is None:
            return None
        out = []
        for seq in range(count.count):
            t1 = time.monotonic()
            self.send(lambda mav: mav.mission_request_int_send(1, 1, seq, mission_type))
            item = self.wait(lambda m: m.get_type() == "MISSION_ITEM_INT" and m.seq == seq
                             and m.mission_type == mission_type, timeout_s, since=t1)
            if item is None:
                return None
            out.append(item)
        self.send(lambda mav: mav.mission_ack_send(1, 1, 0, mission_type))
        return out

    def close(self) -> None:
        self._stop.set()
        self.conn.close()
