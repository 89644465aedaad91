"""The web process serves its page at the launcher's priority and lowers itself (web_nice, the
edge CPUs) only once the server runs: every thread it has then, the server's included, gets them
(Linux sets nice and affinity per thread). At nice 5 from the start the page waited behind any
ordinary busy program (6-9 s on a 2-core machine with one core busy)."""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = r"""
import json, os, threading
from lotsen.stack.processes import ProcessOptions
from lotsen.stack.roles import apply_edge_priority

ready, stop = threading.Event(), threading.Event()
tid = []
def server():  # a thread started before the priority is applied, as uvicorn's is
    tid.append(threading.get_native_id()); ready.set(); stop.wait()
t = threading.Thread(target=server); t.start(); ready.wait()
base = os.nice(0)
done = apply_edge_priority(ProcessOptions(), base + 3)
server_nice = os.getpriority(os.PRIO_PROCESS, tid[0])
stop.set(); t.join()
print(json.dumps({"base": base, "done": done, "server_nice": server_nice, "main_nice": os.nice(0)}))
"""


def test_the_edge_priority_reaches_threads_started_before_it():
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["main_nice"] == r["base"] + 3
    assert r["server_nice"] == r["base"] + 3  # the server's thread too, not only the caller's

