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
    assert resolve_core_cpu(ProcessOptions(core_cpu=0)) == (ProcessOptions(core_cpu=0), None)


def test_two_runs_started_together_claim_different_cpus() -> None:
    """Neither core has pinned itself yet (a core pins once warm): the launchers' claims keep them apart,
    and a claim ends with its holder."""
    free = sorted(os.sched_getaffinity(0) - realtime_cpus_taken())
    if len(free) < 2:
        pytest.skip(f"fewer than two CPUs without another program's real-time core: {free}")
    first, claim1 = resolve_core_cpu(ProcessOptions())
    second, claim2 = resolve_core_cpu(ProcessOptions())
    try:
        assert claim1 is not None and claim2 is not None
        assert first.core_cpu != second.core_cpu
    finally:
        for fd in (claim1, claim2):
            if fd is not None:
                os.close(fd)
    again, claim3 = resolve_core_cpu(ProcessOptions())
    os.close(claim3)
    assert again.core_cpu == first.core_cpu


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
        options, claim = resolve_core_cpu(ProcessOptions())
        if claim is not None:
            os.close(claim)
        assert options.core_cpu == cpus[-2]
    finally:
        other.kill()
        other.wait()
