"""The core's watchdog: every timer its loop finishes is a beat; a loop stuck longer than
`stall_s` gets neutral at the actuators (here: a counted stall) from the watchdog's thread."""

import threading
import time
from types import SimpleNamespace

import pytest

from lotsen.runtime import RealtimeExecutor
from lotsen.runtime.executor import Node
from lotsen.stack.roles import CoreWatchdog


def _watched(ex: RealtimeExecutor, nodes: dict, exit_s: float,
             duration_s: float | None = None) -> tuple[CoreWatchdog, list[int]]:
    """Run `ex`'s loop on a thread of its own under a CoreWatchdog (stall_s 0.2) until it ends;
    the watchdog and the exit codes it would have exited with."""
    stack = SimpleNamespace(executor=ex, services={}, nodes=nodes)
    exits: list[int] = []
    dog = CoreWatchdog(stack, stall_s=0.2, exit_s=exit_s, exit_fn=exits.append)

    def loop() -> None:
        dog.start()
        ex.run(duration_s=duration_s)

    th = threading.Thread(target=loop)
    th.start()
    th.join(5.0)
    dog.stop()
    return dog, exits


def _run(block_at_s: float | None, duration_s: float = 1.2) -> CoreWatchdog:
    ex = RealtimeExecutor()
    t0 = time.monotonic()
    blocked = []

    def tick() -> None:  # the loop's 100 Hz work; once it hangs for 0.5 s
        if block_at_s is not None and not blocked and time.monotonic() - t0 > block_at_s:
            blocked.append(True)
            time.sleep(0.5)

    ex.add_timer(0.01, tick)
    dog, exits = _watched(ex, {}, exit_s=5.0, duration_s=duration_s)
    assert not exits
    return dog


@pytest.mark.live
def test_a_running_loop_is_never_silent_with_a_slow_watchdog_timer():
    assert _run(None).stalls == 0


@pytest.mark.live
def test_a_stuck_loop_is_a_stall():
    assert _run(0.4).stalls == 1


class _SlowToClose(Node):
    """A node whose stop takes `close_s` (as the Zenoh bridge's close on an emulated Pi)."""

    name = "slow_to_close"

    def __init__(self, close_s: float) -> None:
        self.close_s = close_s

    def stop(self) -> None:
        time.sleep(self.close_s)


def _shut_down(close_s: float, exit_s: float) -> tuple[CoreWatchdog, list[int], list[str]]:
    """The loop runs 0.3 s, is told to stop (as SIGTERM does) and its node takes close_s to close."""
    ex = RealtimeExecutor()
    neutral: list[str] = []
    guard = SimpleNamespace(accept=lambda cmd, t: neutral.append(cmd.source))
    ex.add_node(_SlowToClose(close_s))
    ex.add_timer(0.01, lambda: None)
    ex.add_timer(0.3, ex.stop)
    dog, exits = _watched(ex, {"sim_boat": SimpleNamespace(guard=guard)}, exit_s)
    return dog, exits, neutral


@pytest.mark.live
def test_a_loop_told_to_stop_is_silent_while_its_nodes_close_and_that_is_no_stall():
    dog, exits, neutral = _shut_down(close_s=0.6, exit_s=5.0)
    assert dog.stalls == 0 and not exits
    assert neutral == ["watchdog"]  # the actuators still get neutral, once


@pytest.mark.live
def test_a_shutdown_that_hangs_still_ends_the_process():
    dog, exits, _ = _shut_down(close_s=1.5, exit_s=0.8)
    assert exits == [70] and dog.stalls == 0
