"""The core's CPU (lotsen.stack.roles): two runs on one machine do not put their real-time cores on one
CPU, where the two loops would hold each other up."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from lotsen.stack.config import ProcessOptions
from lotsen.stack.roles import choose_core_cpu, realtime_cpus_taken, resolve_core_cpu


def test_the_core_takes_the_last_cpu_no_other_real_time_core_holds() -> None:
    assert choose_core_cpu([0, 1], set()) == 1
    assert choose_core_cpu([0, 1], {1}) == 0
    assert choose_core_cpu([0, 1, 2, 3], {3, 7}) == 2
    assert choose_core_cpu([0, 1], {0, 1}) == 1  # every CPU held: the last, as before


def test_a_core_cpu_in_the_config_is_kept() -> None:
    assert resolve_core_cpu(ProcessOptions(core_cpu=0)).core_cpu == 0


def test_another_programs_real_time_thread_moves_the_core_to_another_cpu() -> None:
    cpus = sorted(os.sched_getaffinity(0))
    if len(cpus) < 2:
        pytest.skip("one CPU: the core is not pinned")
    last = cpus[-1]
    other = subprocess.Popen(
        [sys.executable, "-c", "import os, sys, time\n"
         f"os.sched_setaffinity(0, {{{last}}})\n"
         "try:\n    os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))\n"
         "except PermissionError:\n    print('no', flush=True); sys.exit(0)\n"
         "print('ok', flush=True)\ntime.sleep(60)\n"], stdout=subprocess.PIPE, text=True)
    try:
        assert other.stdout is not None
        if other.stdout.readline().strip() != "ok":
            pytest.skip("real-time priority not permitted here (root or CAP_SYS_NICE)")
        assert last in realtime_cpus_taken()
        assert resolve_core_cpu(ProcessOptions()).core_cpu == cpus[-2]
    finally:
        other.kill()
        other.wait()
