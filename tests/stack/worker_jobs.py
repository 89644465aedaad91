"""Jobs for the planner worker's tests (module-level, so they cross the process boundary)."""

import time


def sleep(seconds: float) -> float:
    time.sleep(seconds)
    return seconds


def allocate(megabytes: float) -> int:
    return len(bytearray(int(megabytes * 1024 * 1024)))
