"""The core locks its memory on fault: the pages it uses stay in RAM, the untouched pages of
every library it maps are neither read in nor pinned (plain MCL_CURRENT pinned ~1.7 GB)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

PROBE = r"""
import json
from pathlib import Path
import numba, scipy.linalg  # large mappings, mostly untouched
from lotsen.stack.processes import ProcessOptions, apply_core_priority

def kb(path, key):
    for line in Path(path).read_text().splitlines():
        if line.startswith(key + ":"):
            return float(line.split()[1])
    return float("nan")

done = apply_core_priority(ProcessOptions(realtime_priority=0, core_nice=0, lock_memory=True))
print(json.dumps({"done": done, "locked_kb": kb("/proc/self/smaps_rollup", "Locked"),
                  "rss_kb": kb("/proc/self/status", "VmRSS"), "vmlck_kb": kb("/proc/self/status", "VmLck")}))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mlockall and /proc are Linux")
def test_core_locks_on_fault_not_every_mapping() -> None:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    r = json.loads(out.stdout.strip().splitlines()[-1])
    if "memory locked on fault" not in r["done"]:
        pytest.skip(f"mlockall not permitted here: {r['done']}")
    assert r["vmlck_kb"] > 0
    # pinned = what is resident, far less than the address space under the lock
    assert r["locked_kb"] <= r["rss_kb"] + 1024
    assert r["locked_kb"] < 0.5 * r["vmlck_kb"], r
