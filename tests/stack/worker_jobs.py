"""Jobs for the planner worker's tests (module-level, so they cross the process boundary)."""

import time


def sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def allocate(megabytes: float) -> int:
    return len(bytearray(int(megabytes * 1024 * 1024)))


def spin(cpu_seconds: float) -> float:
    """Burn CPU time (what a hard planning problem does)."""
    t_end = time.process_time() + cpu_seconds
    while time.process_time() < t_end:
        pass
    return cpu_seconds
