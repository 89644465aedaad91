"""The core's watchdog: every timer its loop finishes is a beat; a loop stuck longer than
`stall_s` gets neutral at the actuators (here: a counted stall) from the watchdog's thread."""

import threading
import time
from types import SimpleNamespace

import pytest

from lotsen.runtime import RealtimeExecutor
from lotsen.stack.roles import CoreWatchdog


def _run(block_at_s: float | None, duration_s: float = 1.2) -> CoreWatchdog:
    ex = RealtimeExecutor()
    stack = SimpleNamespace(executor=ex, services={}, nodes={})
    exits: list[int] = []
    dog = CoreWatchdog(stack, stall_s=0.2, exit_s=5.0, exit_fn=exits.append)
    t0 = time.monotonic()
    blocked = []

    def tick() -> None:  # the loop's 100 Hz work; once it hangs for 0.5 s
        if block_at_s is not None and not blocked and time.monotonic() - t0 > block_at_s:
            blocked.append(True)
            time.sleep(0.5)

    ex.add_timer(0.01, tick)

    def loop() -> None:
        dog.start()
        ex.run(duration_s=duration_s)

    th = threading.Thread(target=loop)
    th.start()
    th.join(5.0)
    dog.stop()
    assert not exits
    return dog


@pytest.mark.live
def test_a_running_loop_is_never_silent_with_a_slow_watchdog_timer():
    assert _run(None).stalls == 0


@pytest.mark.live
def test_a_stuck_loop_is_a_stall():
    assert _run(0.4).stalls == 1
