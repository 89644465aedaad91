"""The processes of `lotsen run`, one main function per role (docs/architecture.md), and what
they share: process options, priority / CPU / locked memory, the core's watchdog.

    core      the boat (simulated, or the drivers), the actuator guard, fusion, the supervisor and
              the controllers, on one clock; a Zenoh router on loopback; its own watchdog
    web       the operator's web server and its planner worker (time and memory budget)
    recorder  the MCAP log of every topic
    foxglove  the live Foxglove server (`--foxglove`)
    ros2      the boat as a ROS 2 node (`extra.ros2`)

A child process starts by importing this module (to find `child_main`), so it imports only what
every role needs; each role's main imports what that role runs. A recorder does not carry the
web server or the controllers, the web server not the estimator or the simulator: on a
Raspberry Pi every library a process imports costs resident memory for the whole run. The
launcher is `lotsen.stack.processes`.

On the boat the core asks for the highest priority, its own CPU and locked memory where the OS
allows it (root or CAP_SYS_NICE / CAP_IPC_LOCK); what it got is printed at start.
"""

from __future__ import annotations

import ctypes
import gc
import math
import os
import signal
import socket
import sys
import threading
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Callable

from lotsen.errors import ConfigError, LotsenError
from lotsen.messages import ThrustCommand, Topic
from lotsen.stack.config import ProcessOptions, StackConfig
from lotsen.runtime.executor import TIMER_GRID_S, RealtimeExecutor
from lotsen.runtime.lifetime import die_with_parent
from lotsen.transport.ros2_bridge import Ros2BridgeConfig
from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge

if TYPE_CHECKING:
    from lotsen.stack.stack import Stack

MCL_CURRENT, MCL_FUTURE, MCL_ONFAULT = 1, 2, 4  # mlockall(2) flags (Linux >= 4.4 for MCL_ONFAULT)
#: what the core accepts from the web process (nothing else from the edge reaches the helm)
OPERATOR_TOPICS = (Topic.OPERATOR, Topic.MANUAL, Topic.LINK, Topic.ROUTE)
#: ... and from the ROS 2 process: operator commands that passed its token gate (CommandGate)
ROS2_TOPICS = (Topic.OPERATOR,)
#: ... and from the recorder its disk's status (the storage check and alert; it moves nothing)
RECORDER_TOPICS = (Topic.RECORDER,)
ROLES = ("core", "recorder", "web", "foxglove", "ros2")
#: how long the core's bridge gathers outgoing messages before it sends them (see core_main)
CORE_SEND_BATCH_S = 0.05


def ros2_config(config: StackConfig) -> Ros2BridgeConfig:
    """`extra.ros2` with the run's pilot token (commands from ROS 2 need it, as on the web page)."""
    if config.extra.ros2 is None:
        raise ConfigError("extra.ros2: no ROS 2 section in the launch config (add `extra: {ros2: {}}`)")
    return replace(config.extra.ros2, pilot_token=config.web.pilot_token)


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# ------------------------------------------------------------------------------------------------
# priority, CPU, memory (best effort, reported)
# ------------------------------------------------------------------------------------------------
def _set_nice(target: int) -> str:
    current = os.nice(0)
    try:
        os.nice(target - current)
        return f"nice {os.nice(0)}"
    except PermissionError:
        if target > current:
            return f"nice {current}"
        return f"nice {current} (wanted {target}: not permitted)"


def _pin(cpus: set[int]) -> str:
    try:
        os.sched_setaffinity(0, cpus)
        return f"CPU {','.join(map(str, sorted(cpus)))}"
    except (AttributeError, OSError, ValueError):
        return "CPU not pinned"


PF_KTHREAD = 0x00200000  # a kernel thread (include/linux/sched.h), in /proc/PID/stat's flags


def realtime_cpus_taken() -> set[int]:
    """The CPUs on which a thread of any program runs alone at a real-time priority (SCHED_FIFO or
    SCHED_RR, pinned to that one CPU): another run's core, as /proc shows it."""
    taken: set[int] = set()
    try:
        pids = [p for p in os.listdir("/proc") if p.isdigit()]
    except OSError:
        return taken
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()  # from field 3 of proc(5)
                policy, flags = int(fields[38]), int(fields[6])
                # SCHED_FIFO or SCHED_RR, not a kernel thread (each CPU has its own: migration/N, irq/N)
                if policy in (1, 2) and not flags & PF_KTHREAD:
                    cpus = os.sched_getaffinity(int(tid))
                    if len(cpus) == 1:
                        taken |= cpus
            except (OSError, ValueError, IndexError):
                continue
    return taken


def choose_core_cpu(cpus: list[int], taken: set[int]) -> int:
    """The core's CPU: the last one no other real-time core holds (the last, if all are held). Two
    runs' cores pinned to one CPU at the same real-time priority hold each other up: on a shared
    2-core machine, 150-340 ms control-loop gaps when another run started (bench survey)."""
    free = [c for c in cpus if c not in taken]
    return (free or cpus)[-1]


def _claim_cpu(cpu: int) -> int | None:
    """A machine-wide claim on `cpu` for this process's lifetime (an flock on a file in the temporary
    directory, released by the kernel however the process ends): the open descriptor, or None if held."""
    import fcntl
    import tempfile

    try:
        fd = os.open(os.path.join(tempfile.gettempdir(), f"lotsen-core-cpu{cpu}.lock"), os.O_RDONLY | os.O_CREAT, 0o644)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        return fd
    except OSError:
        os.close(fd)
        return None


def resolve_core_cpu(opts: ProcessOptions) -> tuple[ProcessOptions, int | None]:
    """`opts` with `core_cpu` chosen once for the whole run when the config leaves it open, so the core
    and the edge processes split the CPUs the same way, and the claim to keep open for the run (None
    without one). Chosen as choose_core_cpu says, from the CPUs a real-time thread holds (/proc) and
    those another launcher has claimed: two runs started together see no pinned core yet (a core
    pins itself once warm)."""
    cpus = _cpus_to_split()
    if opts.core_cpu is not None or not cpus:
        return opts, None
    taken = realtime_cpus_taken()
    while True:
        cpu = choose_core_cpu(cpus, taken)
        if cpu in taken:  # every CPU held: the last, unclaimed
            return replace(opts, core_cpu=cpu), None
        fd = _claim_cpu(cpu)
        if fd is not None:
            return replace(opts, core_cpu=cpu), fd
        taken.add(cpu)


def _cpus_to_split() -> list[int]:
    """The CPUs this process may run on, when there are two or more to split between the core and
    the edge processes (else none)."""
    try:
        cpus = sorted(os.sched_getaffinity(0))
    except AttributeError:
        return []
    return cpus if len(cpus) >= 2 else []


def _cpu_split(opts: ProcessOptions) -> tuple[set[int] | None, set[int] | None]:
    cpus = _cpus_to_split()
    if not cpus:
        return None, None
    core = opts.core_cpu if opts.core_cpu is not None and opts.core_cpu in cpus else cpus[-1]
    return {core}, set(cpus) - {core}


def _other_threads() -> list[int]:
    """The ids of this process's threads but the calling one (Linux sets priority and CPUs per thread)."""
    me = threading.get_native_id()
    try:
        return [int(t) for t in os.listdir("/proc/self/task") if int(t) != me]
    except OSError:
        return []


def apply_core_priority(opts: ProcessOptions) -> list[str]:
    """Priority, CPU and locked memory for the core, called from the control loop's thread when
    every other thread of the process (Zenoh's, the bridge's) exists.

    All threads of the core get the core CPU and SCHED_RR at `realtime_priority`, the loop one
    level above (SCHED_FIFO): no program outside the core can delay any thread that may hold
    the interpreter lock the loop needs (a lock holder preempted by an ordinary busy process
    stalled the loop for 0.2 s), and no core thread can delay the loop. With the kernel's
    autogroups, nice values alone count only within one terminal session."""
    done = [_set_nice(opts.core_nice)]
    core_cpus, _ = _cpu_split(opts)
    others = _other_threads()
    if core_cpus:
        for tid in others:
            try:
                os.sched_setaffinity(tid, core_cpus)
            except OSError:
                pass
        done.append(_pin(core_cpus))  # this thread, and what it got
    if opts.realtime_priority > 0:
        try:
            for tid in others:
                try:
                    os.sched_setscheduler(tid, os.SCHED_RR, os.sched_param(opts.realtime_priority))
                except ProcessLookupError:  # a thread that ended meanwhile: not a refusal
                    pass
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(opts.realtime_priority + 1))
            done.append(f"real-time priority {opts.realtime_priority + 1} (SCHED_FIFO; other threads SCHED_RR)")
        except (AttributeError, PermissionError, OSError):
            done.append("real-time priority not permitted")
    if opts.lock_memory:
        # after the warm-up (every kernel compiled) and on fault only: the pages in use now and
        # those the loop touches later stay in RAM; untouched pages of every mapped library
        # (LLVM alone maps 150 MB) are not read in and pinned, as plain MCL_CURRENT would
        try:
            libc = ctypes.CDLL("libc.so.6", use_errno=True)
            ok = libc.mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0
            done.append("memory locked on fault" if ok else "memory not locked (not permitted)")
        except OSError:
            done.append("memory not locked (no libc)")
    return done


def freeze_heap() -> None:
    """Move every object made during start-up out of the garbage collector's reach: a full
    collection of the ~200 000 objects a core holds (numpy, scipy, OSQP, Zenoh) takes 0.3 s on
    this machine, a stall of three control periods whenever Python decides to run one."""
    gc.collect()
    gc.freeze()


def apply_edge_priority(opts: ProcessOptions, nice: int) -> list[str]:
    """Nice and the edge CPUs for every thread of this process (Linux sets both per thread: the
    web process calls this once its server threads run)."""
    done = [_set_nice(nice)]
    _, edge_cpus = _cpu_split(opts)
    for tid in _other_threads():
        try:
            os.setpriority(os.PRIO_PROCESS, tid, os.nice(0))
            if edge_cpus:
                os.sched_setaffinity(tid, edge_cpus)
        except OSError:  # a thread that ended meanwhile, or a lower nice not permitted
            pass
    if edge_cpus:
        done.append(_pin(edge_cpus))
    return done


# ------------------------------------------------------------------------------------------------
# the core's watchdog
# ------------------------------------------------------------------------------------------------
class CoreWatchdog:
    """A thread that watches the core's control loop: when the executor has not run for
    `stall_s`, the actuators are sent to neutral directly (not through the stalled loop); after
    `exit_s` the process exits, so the launcher (or systemd) sees it and the ESCs' own signal
    loss failsafe takes over. Once the executor is told to stop, the loop is meant to go silent
    while its nodes close (the Zenoh bridge's close took 0.3 s and more on an emulated Pi): still
    neutral, and still the exit if the closing hangs, but no stall counted or reported."""

    def __init__(self, stack: Stack, stall_s: float, exit_s: float,
                 exit_fn: Callable[[int], None] = os._exit) -> None:
        self.stack = stack
        self.stall_s = stall_s
        self.exit_s = exit_s
        self.exit_fn = exit_fn
        self.clock = stack.executor.clock
        self.beat = self.clock.now()
        self.stalls = 0
        self.loop_thread = threading.current_thread()  # start() is called from the thread that runs the loop
        self._stop = threading.Event()
        # every timer the loop finishes is a beat (RealtimeExecutor.beat_s: the 100 Hz simulated
        # boat or drivers, 20 Hz fusion, 10 Hz supervisor); this timer only makes sure there is
        # one at least every stall_s / 4 (a 50 Hz timer of its own woke the loop 50 times a
        # second more than its work does)
        # (its period on the real-time loop's 10 ms grid: it runs in a wake-up the boat's timer has anyway)
        period_s = max(TIMER_GRID_S, math.floor(stall_s / 4 / TIMER_GRID_S + 1e-9) * TIMER_GRID_S)
        stack.executor.add_timer(period_s, self._beat, "watchdog")
        self._thread = threading.Thread(target=self._watch, name="core-watchdog", daemon=True)

    def start(self) -> None:
        self.loop_thread = threading.current_thread()
        self.beat = self.clock.now()
        self._thread.start()

    def silent_s(self) -> float:
        """How long the control loop has not finished a timer."""
        return self.clock.now() - max(self.beat, getattr(self.stack.executor, "beat_s", -math.inf))

    def where(self) -> str:
        """Where the control loop is now, and the other Python threads (one may hold the GIL):
        the cause of a stall, for the log."""
        frames = sys._current_frames()
        names = {t.ident: t.name for t in threading.enumerate()}

        def spots(frame: Any, depth: int) -> str:
            out = []
            while frame is not None and len(out) < depth:
                out.append(f"{os.path.basename(frame.f_code.co_filename)}:{frame.f_lineno} {frame.f_code.co_name}")
                frame = frame.f_back
            return " < ".join(out)

        loop = spots(frames.get(self.loop_thread.ident or -1), 4) or "unknown"
        others = [f"{names.get(ident, ident)}: {spots(f, 2)}" for ident, f in frames.items()
                  if ident not in (self.loop_thread.ident, threading.get_ident())]
        return loop + ("; other threads: " + " | ".join(others) if others else "")

    def _beat(self) -> None:
        self.beat = self.clock.now()

    def _watch(self) -> None:
        try:  # above the loop it watches, so it runs even if the loop spins at real-time priority
            if os.sched_getscheduler(0) == os.SCHED_FIFO:
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(os.sched_getparam(0).sched_priority + 1))
        except (AttributeError, OSError):
            pass
        stalled = False
        while not self._stop.wait(self.stall_s / 4):
            silent = self.silent_s()
            stopping = bool(getattr(self.stack.executor, "stopping", False))
            if silent > self.stall_s and not stalled:
                stalled = True
                emergency_neutral(self.stack)
                if not stopping:
                    self.stalls += 1
                    print(f"lotsen core: t={self.stack.executor.clock.now():.1f} s: control loop silent for {silent:.2f} s: "
                          "actuators to neutral "
                          f"(loop at {self.where()})", file=sys.stderr, flush=True)
            elif silent <= self.stall_s:
                stalled = False
            if silent > self.exit_s:
                print(f"lotsen core: control loop silent for {silent:.1f} s{' while shutting down' if stopping else ''}: "
                      f"exiting (loop at {self.where()})", file=sys.stderr, flush=True)
                self.exit_fn(70)
                return

    def stop(self) -> None:
        self._stop.set()


def emergency_neutral(stack: Stack) -> None:
    """Neutral at the actuators from any thread: the hardware drivers write neutral pulses now;
    the simulated boat's guard gets a neutral command."""
    hw = stack.services.get("hardware")
    if hw is not None and "actuators" in getattr(hw, "drivers", {}):
        try:
            hw.drivers["actuators"].neutral()
        except Exception as exc:  # noqa: BLE001 - a dead pigpiod: the ESC signal-loss failsafe remains
            print(f"lotsen core: neutral failed: {exc!r}", file=sys.stderr, flush=True)
    boat = stack.nodes.get("sim_boat")
    if boat is not None:
        boat.guard.accept(ThrustCommand.neutral(stack.executor.clock.now(), source="watchdog"),
                          stack.executor.clock.now())


# ------------------------------------------------------------------------------------------------
# the roles (each the main function of one process)
# ------------------------------------------------------------------------------------------------
def _bridge(stack: Stack, **kw: Any) -> ZenohBridge:
    bridge = ZenohBridge(BridgeConfig(**kw))
    stack.add(bridge)
    stack.on_shutdown(bridge.close)
    return bridge


def _edge_stack(config: StackConfig) -> Stack:
    from lotsen.stack.stack import Stack, resolve_origin, vessel_model

    return Stack(config=config, executor=RealtimeExecutor(), model=vessel_model(config), origin=resolve_origin(config))


def _run_until_stopped(stack: Stack, ready: Any, info: dict, on_stop: Callable[[], None] | None = None) -> None:
    """Serve until SIGTERM (the launcher's stop, or its death: `die_with_parent`); `on_stop` runs
    first thing in the signal handler (the core: neutral at the actuators)."""

    def stop(*_: Any) -> None:
        if on_stop is not None:
            on_stop()
        stack.executor.stop()

    freeze_heap()  # no 0.3 s collector pauses in the web server's or the recorder's loop either
    signal.signal(signal.SIGTERM, stop)
    ready.send(("ready", info))
    ready.close()
    try:
        stack.executor.run()
    finally:
        stack.executor.stop()
        stack.shutdown()


# Each main imports what its role runs (see the module's docstring).
def core_main(config: StackConfig, endpoint: str, ready: Any) -> None:
    from lotsen.stack.launch import build_stack, summary

    opts = config.extra.processes
    # ahead of the edge processes, which start at the same time, while the kernels load (the
    # real-time priority and the CPU come with apply_core_priority, once the loop is ready)
    _set_nice(opts.core_nice)
    # the loop and its watchdog start only once build_stack has every compiled kernel ready;
    # how far that is goes to the console at once (not with the banner, sent when ready)
    stack = build_stack(config, realtime=True, parts=("state", "supervisor"),
                        progress=lambda line: print(f"lotsen core: {line}", flush=True))
    sources = [f"web/{t}" for t in OPERATOR_TOPICS] + [f"ros2/{t}" for t in ROS2_TOPICS] + \
        [f"recorder/{t}" for t in RECORDER_TOPICS]
    # every topic out in batches of up to 50 ms, each closed by the 20 Hz estimate: Zenoh then
    # packs a batch into few frames (the core's sending thread and the edge's receiving threads
    # wake 20 times a second, not 100 and more), and the page's pose leaves as it is made; the
    # edge sees the other telemetry up to 50 ms later, its stamps are the core's. JSON for every
    # type, not ROS 2 CDR where one fits: the router listens on loopback only (ROS 2 tools get CDR
    # from the ros2 process), JSON costs the core less to encode and the edge less to decode, the
    # recorder writes the received JSON as it is (no decode and re-encode), and what is recorded
    # is exactly what was published (CDR rounds stamps to nanoseconds and the field to tesla)
    _bridge(stack, vessel="core", mode="router", listen=(endpoint,), publish=("*",), subscribe=tuple(sources),
            send_batch_s=CORE_SEND_BATCH_S, flush_on=(Topic.STATE,), encoding="json")
    watchdog = CoreWatchdog(stack, opts.watchdog_s, opts.watchdog_exit_s)
    stack.on_shutdown(watchdog.stop)
    stack.executor.add_timer(5.0, lambda: print(summary(stack), flush=True), "console")
    done = apply_core_priority(opts)  # this thread runs the loop
    watchdog.start()
    info = {"banner": [f"core: {config.mode} boat with {', '.join(stack.nodes)}; {', '.join(done)}",
                       *stack.services.get("banner", [])]}
    # neutral first when told to stop (by the launcher, or by its death), and again on the way out
    _run_until_stopped(stack, ready, info, on_stop=lambda: emergency_neutral(stack))
    emergency_neutral(stack)


def recorder_main(config: StackConfig, endpoint: str, ready: Any) -> None:
    from lotsen.stack.logs import add_recorder

    opts = config.extra.processes
    done = apply_edge_priority(opts, opts.recorder_nice)
    stack = _edge_stack(config)
    # the core's whole stream (300+ messages a second): taken in batches, not one thread switch
    # each; every 0.1 s (the writer writes every 0.2 s, and logging on / off may wait that long)
    bridge = _bridge(stack, vessel="recorder", mode="client", connect=(endpoint,), publish=(Topic.LOG, *RECORDER_TOPICS),
                     subscribe=("*/**",), wait_for_router=True, receive="poll", drain_period_s=0.1)
    recorder = add_recorder(stack)
    # ... and recorded as it came (the JSON on the wire is the log's JSON): decoded only for the
    # Foxglove views and for what this process acts on (logging on / off)
    bridge.forward_encoded(recorder.on_envelopes, decoded=stack.bus.subscribed_topics())
    _run_until_stopped(stack, ready, {"banner": [*stack.services.get("banner", []), f"recorder: {', '.join(done)}"]})


def web_main(config: StackConfig, endpoint: str, ready: Any, tls: bool = False) -> None:
    from lotsen.stack.planner_worker import PlannerWorker
    from lotsen.stack.web import add_web
    from lotsen.web.telemetry import LIVE_ONLY, TOPICS as PAGE_TOPICS

    opts = config.extra.processes
    # the launcher's priority until the page answers, web_nice after: at nice 5 from the start, the
    # page waited behind any ordinary busy program on a loaded machine (6-9 s with one core busy)
    stack = _edge_stack(config)
    worker = PlannerWorker(config.extra.planning)
    stack.on_shutdown(worker.close)
    # the page first: it answers while the core is still starting (what the page publishes waits
    # in the executor's queue until the loop below runs)
    add_web(stack, run_blocking=worker.run, tls=tls)
    done = apply_edge_priority(opts, opts.web_nice)
    # the page's topics only: the core's 100-200 Hz sensor streams (imu/*) are two thirds of
    # its messages, and the page shows none of them; decoding them was most of this process's CPU
    bridge = _bridge(stack, vessel="web", mode="client", connect=(endpoint,), publish=OPERATOR_TOPICS,
                     bulk=(Topic.ROUTE,),
                     subscribe=(*(f"core/{topic}" for topic in PAGE_TOPICS), "recorder/log",
                                f"recorder/{Topic.RECORDER}", "launcher/log"),
                     wait_for_router=True, receive="poll", drain_period_s=0.1, wake_on=(f"core/{Topic.STATE}",))
    server = stack.services.get("web")
    if server is not None and not config.extra.mavlink.endpoints:
        # the live view's ~90 messages a second decoded only while a page is connected (a MAVLink
        # ground station reads them too: then always)
        hub = server.hub
        bridge.hold_latest(LIVE_ONLY, lambda: bool(hub.clients))
    # the worker once the core is up (it would compete with the core's start for the CPU); after
    # the server: a web process that cannot serve ends with its one error
    threading.Thread(target=worker.warm, name="planner-warm-up", daemon=True).start()
    _run_until_stopped(stack, ready, {"banner": [*stack.services.get("banner", []), f"web: {', '.join(done)}"]})


def ros2_main(config: StackConfig, endpoint: str, ready: Any) -> None:
    """The boat as a ROS 2 node (rmw_zenoh wire format, docs/runtime.md): the core's topics out,
    authorised operator commands in (they reach the core as ros2/operator/command)."""
    from lotsen.transport.ros2_bridge import Ros2Bridge

    opts = config.extra.processes
    done = apply_edge_priority(opts, opts.web_nice)
    stack = _edge_stack(config)
    _bridge(stack, vessel="ros2", mode="client", connect=(endpoint,), publish=(*ROS2_TOPICS, Topic.LOG),
            subscribe=("core/**",), wait_for_router=True)
    bridge = Ros2Bridge(ros2_config(config))
    stack.add(bridge)
    stack.on_shutdown(bridge.close)
    _run_until_stopped(stack, ready, {"banner": [f"ros2: namespace {bridge.namespace}, {len(bridge.config.publish)} "
                                                 f"topics out, commands with the pilot token in; {', '.join(done)}"]})


def foxglove_main(config: StackConfig, endpoint: str, ready: Any, port: int = 8765) -> None:
    from lotsen.stack.logs import add_foxglove_server

    opts = config.extra.processes
    apply_edge_priority(opts, opts.web_nice)
    stack = _edge_stack(config)
    _bridge(stack, vessel="foxglove", mode="client", connect=(endpoint,), publish=(), subscribe=("*/**",),
            wait_for_router=True, receive="poll", drain_period_s=0.05)
    add_foxglove_server(stack, config.web.host, port)
    _run_until_stopped(stack, ready, {"banner": stack.services.get("banner", [])})


_MAINS: dict[str, Callable[..., None]] = {"core": core_main, "recorder": recorder_main, "web": web_main,
                                         "foxglove": foxglove_main, "ros2": ros2_main}


def child_main(role: str, config: StackConfig, endpoint: str, ready: Any, kwargs: dict, launcher_pid: int) -> None:
    # no orphans: whatever ends the launcher (SIGKILL included) ends this process, through its
    # own orderly SIGTERM path (the core's neutral, the recorder's closed file)
    die_with_parent(launcher_pid)
    # Ctrl-C reaches every process of the terminal's group: only the launcher acts on it, so the
    # shutdown order stays core first, then the edge
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        _MAINS[role](config, endpoint, ready, **kwargs)
    except LotsenError as exc:
        print(f"lotsen {role}: error: {exc}", file=sys.stderr, flush=True)
        try:
            ready.send(("error", str(exc)))
        except OSError:
            pass
        sys.exit(2)

