"""`lotsen run` as processes: the launcher (the roles' mains are `lotsen.stack.roles`).

The processes talk only through Zenoh (lotsen.transport): the core publishes every topic and
accepts from the edge only the operator's topics coming from the web process. An edge process
may crash, hang or be flooded; the core notices only through its link monitors and keeps its
10 Hz and its failsafe table. The launcher starts every process at once (the edge connects to
the core's router when it is up), restarts a dead edge process (logged), stops everything when the core ends (neutral pulses from the launcher
on the hardware), and stops the core first on the way out so the recorder keeps its last words.
Every child ends with the launcher however it ends (`die_with_parent`: SIGTERM, so the core's
neutral and the recorder's closed file). All processes stamp on one clock (LOTSEN_CLOCK_T0).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import threading
import time
from dataclasses import dataclass, replace
from typing import Any, Callable

from lotsen.drivers.actuators import pigpio_opener
from lotsen.errors import ConfigError, LotsenError
from lotsen.messages import LogEvent
from lotsen.runtime.clock import CLOCK_ENV
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.config import ProcessOptions, StackConfig, stack_config  # noqa: F401 - ProcessOptions: of `lotsen run`
from lotsen.runtime.lifetime import RunLock
from lotsen.stack.identity import run_identities  # noqa: F401 - part of the launcher's interface
from lotsen.stack.logs import recorder_config
from lotsen.stack.roles import (  # noqa: F401 - apply_core_priority ... free_port: of `lotsen run`
    ROLES, apply_core_priority, child_main, free_port, freeze_heap, resolve_core_cpu,
)
from lotsen.stack.stack import load_parameters, resolve_origin, simulated_boat
from lotsen.stack.web import check_web_host, tls_certificate
from lotsen.transport import codec
from lotsen.transport.zenoh_bridge import BridgeConfig, zenoh_config
from lotsen.web.options import WebOptions


def launcher_neutral(config: StackConfig) -> str:
    """Neutral pulses from outside the core, when the core ended without saying goodbye (killed,
    or its watchdog's hard exit): pigpiod keeps sending the last pulse widths it was given, so
    without this an ESC would keep its last thrust. Nothing to do for the simulated boat or the
    emulated devices (they lived in the core). Returns what was done, for the log."""
    if config.mode != "hardware" or config.extra.emulated:
        return "no actuators outside the core"
    act = config.extra.hardware.actuators
    if not act.enabled:
        return "actuators disabled"
    try:
        pi = pigpio_opener(act.pigpio_host, act.pigpio_port)()
        for pin, cal in zip(act.esc_pins, act.esc):
            pi.set_servo_pulsewidth(pin, int(cal.neutral_us))
        for pin, servo in zip(act.servo_pins, act.servo):
            pi.set_servo_pulsewidth(pin, int(servo.center_us))
        pi.stop()
        return "ESCs at neutral, servos centred by the launcher"
    except Exception as exc:  # noqa: BLE001 - pigpiod gone too: nothing drives the pulses
        return f"neutral from the launcher failed ({exc!r})"


# ------------------------------------------------------------------------------------------------
# the launcher
# ------------------------------------------------------------------------------------------------
@dataclass
class Child:
    role: str
    kwargs: dict
    proc: Any = None
    started_s: float = 0.0
    restarts: int = 0
    next_start_s: float = 0.0


class Launcher:
    """Starts, watches and stops the processes of one run (`lotsen run`)."""

    def __init__(self, config: LaunchConfig, roles: tuple[str, ...] = ("core", "recorder", "web"),
                 role_kwargs: dict[str, dict] | None = None, out: Callable[[str], None] = print,
                 lock: RunLock | None = None) -> None:
        unknown = set(roles) - set(ROLES)
        if unknown or "core" not in roles:
            raise ConfigError(f"processes: roles must include 'core' and be among {ROLES}, got {roles}")
        config = stack_config(config)
        # the core's CPU chosen once, here: every process of the run splits the CPUs the same way
        processes, self._core_cpu_claim = resolve_core_cpu(config.extra.processes)
        self.config = replace(config, extra=replace(config.extra, processes=processes))
        self.opts = self.config.extra.processes
        self.port = self.opts.zenoh_port or free_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.out = out
        self.children = {r: Child(r, (role_kwargs or {}).get(r, {})) for r in ROLES if r in roles}
        self._ctx = mp.get_context("spawn")
        self._stop = threading.Event()
        self.events: list[str] = []
        self._session: Any = None
        self._log_pub: Any = None
        os.environ.setdefault(CLOCK_ENV, repr(time.monotonic()))  # one clock for every process of the run
        self.clock_t0 = float(os.environ[CLOCK_ENV])
        self.exit_code = 0
        self.lock = lock  # held by the caller for the whole run; here only its web address is kept current
        self.web_url = ""

    # -- starting ----------------------------------------------------------------------------
    def _spawn(self, child: Child) -> list[str]:
        return self._wait_ready(child, self._launch(child))

    def _launch(self, child: Child) -> Any:
        parent, conn = self._ctx.Pipe(duplex=False)
        proc = self._ctx.Process(target=child_main, name=f"lotsen-{child.role}",
                                 args=(child.role, self.config, self.endpoint, conn, child.kwargs, os.getpid()))
        proc.start()
        conn.close()
        child.proc, child.started_s = proc, time.monotonic()
        return parent

    def _note(self, lines: list[str]) -> list[str]:
        """The web address from the web process's banner, into the run lock (for a refused second run)."""
        for line in lines:
            if line.startswith("operator interface: "):
                self.web_url = line.split(": ", 1)[1]
                if self.lock is not None and self.lock.held:
                    self.lock.update(self.web_url)
        return lines

    def _wait_ready(self, child: Child, parent: Any) -> list[str]:
        proc = child.proc
        if not parent.poll(self.opts.ready_timeout_s):
            proc.kill()
            raise LotsenError(f"the {child.role} process did not start within {self.opts.ready_timeout_s:g} s")
        try:
            kind, info = parent.recv()
        except EOFError:
            proc.join(1.0)
            raise LotsenError(f"the {child.role} process ended while starting (exit code {proc.exitcode})") from None
        if kind != "ready":
            proc.join(2.0)
            raise LotsenError(f"{child.role}: {info}")
        return self._note(list(info.get("banner", [])))

    def start(self) -> None:
        """Every process at once: the edge processes connect to the core's Zenoh router when it
        is up (the web page answers while the core still prepares its kernels). The core's
        banner first, then the edge's; a core that fails to start stops the run (`stop`)."""
        conns = {role: self._launch(child) for role, child in self.children.items()}
        for line in self._wait_ready(self.children["core"], conns["core"]):
            self.out(line)
        for role, child in self.children.items():
            if role != "core":
                for line in self._wait_ready(child, conns[role]):
                    self.out(line)
        self._open_log()

    def _open_log(self) -> None:
        try:
            import zenoh

            self._session = zenoh.open(zenoh_config(BridgeConfig(vessel="launcher", mode="client",
                                                                 connect=(self.endpoint,))))
            self._log_pub = self._session.declare_publisher("lotsen/launcher/log")
        except Exception as exc:  # noqa: BLE001 - the launcher's own log line is a nicety
            self.out(f"launcher: no log channel ({exc!r})")

    def log(self, level: str, text: str) -> None:
        self.events.append(text)
        self.out(f"launcher: {text}")
        if self._log_pub is not None:
            msg = LogEvent(stamp_s=time.monotonic() - self.clock_t0, level=level, source="launcher", text=text)
            try:
                self._log_pub.put(codec.encode(msg, "json", origin="launcher"))
            except Exception:  # noqa: BLE001
                pass

    # -- watching ----------------------------------------------------------------------------
    def supervise(self, duration_s: float | None = None) -> int:
        """Watch until stopped, the core ends, or `duration_s` from now (every process is up)."""
        end = None if duration_s is None else time.monotonic() + duration_s
        while not self._stop.wait(0.1):
            if end is not None and time.monotonic() >= end:
                break
            core = self.children["core"]
            if not core.proc.is_alive():
                self.log("error", f"the core process ended (exit code {core.proc.exitcode}): stopping the run; "
                                  f"{launcher_neutral(self.config)}")
                self.exit_code = 1
                break
            for child in self.children.values():
                if child.role == "core" or child.proc is None:
                    continue
                if not child.proc.is_alive() and time.monotonic() >= child.next_start_s:
                    code = child.proc.exitcode
                    child.restarts += 1
                    self.log("warning", f"the {child.role} process ended (exit code {code}); restarting it "
                                        f"(restart {child.restarts})")
                    child.next_start_s = time.monotonic() + self.opts.restart_backoff_s * min(child.restarts, 10)
                    try:
                        for line in self._spawn(child):
                            self.out(line)
                    except LotsenError as exc:
                        self.log("error", f"restarting {child.role} failed: {exc}")
        self.stop()
        return self.exit_code

    def request_stop(self) -> None:
        self._stop.set()

    # -- stopping ----------------------------------------------------------------------------
    def stop(self, timeout_s: float = 5.0) -> None:
        order = ["core"] + [r for r in ("web", "ros2", "foxglove", "recorder") if r in self.children]
        for i, role in enumerate(order):
            p = self.children[role].proc
            if p is not None and p.is_alive():
                p.terminate()
                p.join(timeout_s)
                if p.is_alive():
                    p.kill()
                    p.join(1.0)
                    if role == "core":
                        self.log("error", f"the core did not stop within {timeout_s:g} s and was killed; "
                                          f"{launcher_neutral(self.config)}")
            if role == "core":
                time.sleep(0.3)  # the recorder takes the core's last messages
        if self._session is not None:
            try:
                self._session.close()
            except Exception:  # noqa: BLE001
                pass
            self._session = None

    def pids(self) -> dict[str, int]:
        return {r: c.proc.pid for r, c in self.children.items() if c.proc is not None}


def validate(config: LaunchConfig, tls: bool = False) -> StackConfig:
    """Every section a run uses, checked once before any process starts: a bad value is an error
    naming the key, at once, not a traceback in a child process (restarted again and again). The
    sections' values are typed when the config is loaded (`lotsen.stack.config`); here what needs
    more than the values: the parameter files, the simulated boat, the web host, the pilot token,
    the certificate (with `tls` made here, once, before the web process needs it). Returns the
    typed config."""
    config = stack_config(config)
    load_parameters(config.vessel.parameters_file)
    if config.mode == "sim":
        simulated_boat(config)  # sim.boat and its parameter file
    recorder_config(config, resolve_origin(config))
    web = WebOptions.from_config(config, config.extra.web, config.extra.failsafes.link_timeout_s)
    if config.web.enabled:
        check_web_host(config.web.host)
        tls_certificate(web, tls)
    return config
