"""No orphans and one run per boat: the processes of `lotsen run` end with their launcher, and a
second run on the same boat is refused before it starts anything."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from dataclasses import replace
from pathlib import Path

import pytest

from lotsen.runtime.config import BoatSection, LaunchConfig
from lotsen.runtime.lifetime import RUNTIME_DIR_ENV, RunLock, RunRefused, read_holder
from lotsen.stack.processes import run_identities

REPO = Path(__file__).resolve().parents[2]
CONFIG = REPO / "config" / "sim.yaml"


# ------------------------------------------------------------------------------------------------
# helpers: the process tree from /proc
# ------------------------------------------------------------------------------------------------
def _ppid(pid: int) -> int | None:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return int(stat.rsplit(")", 1)[1].split()[1])


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"  # a zombie has ended (it waits for its reaper)


def _cmdline(pid: int) -> bytes:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return b""


def descendants(root: int) -> set[int]:
    parents = {int(p): _ppid(int(p)) for p in os.listdir("/proc") if p.isdigit()}
    found, frontier = set(), {root}
    while frontier:
        frontier = {pid for pid, pp in parents.items() if pp in frontier} - found
        found |= frontier
    return found


def _sim_config(tmp_path: Path, name: str = "") -> Path:
    text = CONFIG.read_text().replace("../examples", str(REPO / "examples")).replace("../logs", "logs")
    text = text.replace("port: 8080", "port: 0")
    if name:
        text = text.replace("name: lake boat", f"name: {name}")
    path = tmp_path / "c.yaml"
    path.write_text(text)
    return path


def _start_run(cwd: Path, config: Path, env: dict, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "lotsen", "run", str(config), "--sim", *extra], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL,
                            start_new_session=True)


def _wait_for(proc: subprocess.Popen, prefix: str, timeout_s: float) -> list[str]:
    lines: list[str] = []
    t_end = time.monotonic() + timeout_s
    assert proc.stdout is not None
    while time.monotonic() < t_end:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line.rstrip())
        if line.startswith(prefix):
            return lines
    raise AssertionError(f"no '{prefix}' line:\n" + "\n".join(lines[-30:]))


@pytest.fixture
def run_env(tmp_path):
    env = {**os.environ, RUNTIME_DIR_ENV: str(tmp_path / "rt"), "PYTHONUNBUFFERED": "1",
           "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    return env


# ------------------------------------------------------------------------------------------------
# no orphans
# ------------------------------------------------------------------------------------------------
@pytest.mark.live
def test_sigkill_of_the_launcher_leaves_nothing_of_the_run_and_a_closed_log(tmp_path, run_env):
    from mcap.reader import make_reader

    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    run = _start_run(cwd, _sim_config(tmp_path), run_env)
    tree: set[int] = set()
    try:
        lines = _wait_for(run, "processes:", 120)
        time.sleep(2.0)  # a little recorded
        tree = descendants(run.pid)
        roles = dict(kv.split("=") for kv in lines[-1].split()[1:])
        assert {int(p) for p in roles.values()} <= tree
        assert len(tree) >= 4, tree  # core, recorder, web, planner worker (and the resource tracker)
        trackers = {p for p in tree if b"resource_tracker" in _cmdline(p)}
        run.send_signal(signal.SIGKILL)
        run.wait(5)
        # the run's own processes end with the launcher (parent-death signal) within 3 s; multiprocessing's
        # resource tracker ends by itself once the last of them has closed its pipe, and then cleans up,
        # which took over 3 s once with two live tests side by side (2026-11-29): it gets 15 s
        for pids, grace_s in ((tree - trackers, 3.0), (trackers, 15.0)):
            t_end = time.monotonic() + grace_s
            while time.monotonic() < t_end and any(_alive(p) for p in pids):
                time.sleep(0.05)
            left = {p: _cmdline(p)[:120] for p in pids if _alive(p)}
            assert not left, f"left after {grace_s:.0f} s: {left}"
    finally:
        if run.poll() is None:
            run.kill()
        for pid in tree:
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
    logs = sorted((tmp_path / "logs").glob("*.mcap"))
    assert len(logs) == 1
    with open(logs[0], "rb") as f:
        summary = make_reader(f).get_summary()  # None for a file cut off without its summary
    assert summary is not None and summary.statistics.message_count > 100


_PARENT = textwrap.dedent("""
    import os, subprocess, sys, time
    child = subprocess.Popen([sys.executable, "-c", '''
    import os, sys, time
    sys.path.insert(0, {repo!r})
    from lotsen.runtime.lifetime import die_with_parent
    die_with_parent(int(sys.argv[1]), parent_death_signal={pdeath})
    print("ready", flush=True)
    time.sleep(60)
    ''', str(os.getpid())], stdout=subprocess.PIPE, text=True)
    child.stdout.readline()
    print(child.pid, flush=True)
    time.sleep(60)
""")


@pytest.mark.live
@pytest.mark.parametrize("pdeath", [True, False], ids=["parent-death-signal", "watcher-only"])
def test_a_child_that_dies_with_its_parent_ends_when_the_parent_is_killed(pdeath):
    parent = subprocess.Popen([sys.executable, "-c", _PARENT.format(repo=str(REPO), pdeath=pdeath)],
                              stdout=subprocess.PIPE, text=True)
    assert parent.stdout is not None
    child = int(parent.stdout.readline())
    assert _alive(child)
    parent.kill()
    parent.wait(5)
    t_end = time.monotonic() + 2.0
    while time.monotonic() < t_end and _alive(child):
        time.sleep(0.02)
    alive = _alive(child)
    if alive:
        os.kill(child, signal.SIGKILL)
    assert not alive


# ------------------------------------------------------------------------------------------------
# one run per boat
# ------------------------------------------------------------------------------------------------
def test_a_second_lock_on_the_same_boat_is_refused_naming_the_holder(tmp_path):
    first = RunLock(["sim boat lake boat"], tmp_path)
    first.acquire("http://127.0.0.1:8080/")
    t0 = time.perf_counter()
    with pytest.raises(RunRefused, match=rf"pid {os.getpid()}, operator interface http://127.0.0.1:8080/"):
        RunLock(["sim boat lake boat"], tmp_path).acquire("http://127.0.0.1:9999/")
    assert time.perf_counter() - t0 < 0.1
    assert first.held and read_holder(first.path("sim boat lake boat")).web == "http://127.0.0.1:8080/"
    RunLock(["sim boat other boat"], tmp_path).acquire("x")  # another boat: no conflict
    first.release()
    again = RunLock(["sim boat lake boat"], tmp_path)
    again.acquire("http://127.0.0.1:9999/")
    assert read_holder(again.path("sim boat lake boat")).web == "http://127.0.0.1:9999/"
    again.release()


def test_a_lock_left_by_a_killed_run_is_taken_over(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        sys.path.insert(0, {str(REPO)!r})
        from lotsen.runtime.lifetime import RunLock
        RunLock(["sim boat lake boat"], {str(tmp_path)!r}).acquire("http://somewhere/")
        print("held", flush=True)
        time.sleep(60)
        """)], stdout=subprocess.PIPE, text=True)
    assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
    with pytest.raises(RunRefused, match=rf"pid {holder.pid}"):
        RunLock(["sim boat lake boat"], tmp_path).acquire("")
    holder.kill()
    holder.wait(5)
    lock = RunLock(["sim boat lake boat"], tmp_path)
    assert read_holder(lock.path("sim boat lake boat")).pid == holder.pid  # the stale file is still there
    lock.acquire("http://here/")
    assert read_holder(lock.path("sim boat lake boat")).pid == os.getpid()
    lock.release()


def test_runs_are_the_same_boat_by_vessel_name_or_by_hardware_device():
    sim = LaunchConfig()
    assert run_identities(sim) == run_identities(replace(sim, seed=3))
    renamed = replace(sim, sim=replace(sim.sim, boat=BoatSection(name="harbour tug")))
    assert run_identities(renamed) != run_identities(sim)
    hw = replace(sim, mode="hardware", extra={"hardware": {"gnss": {"port": "/dev/ttyUSB0"}}})
    same_port = replace(hw, extra={"hardware": {"gnss": {"port": "/dev/ttyUSB0"}, "imu": {"bus": 3}}})
    assert set(run_identities(hw)) & set(run_identities(same_port))  # the same GNSS port
    assert "hardware serial /dev/ttyUSB0" in run_identities(hw)


@pytest.mark.live
def test_a_second_run_on_the_same_boat_is_refused_at_once_and_the_first_keeps_running(tmp_path, run_env):
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    config = _sim_config(tmp_path)
    first = _start_run(cwd, config, run_env)
    try:
        lines = _wait_for(first, "processes:", 120)
        url = next(x.split(": ", 1)[1] for x in lines if x.startswith("operator interface: "))
        t0 = time.monotonic()
        second = subprocess.run([sys.executable, "-m", "lotsen", "run", str(config), "--sim", "--port", "0"],
                                cwd=cwd, env=run_env, capture_output=True, text=True, timeout=60)
        took_s = time.monotonic() - t0
        assert second.returncode == 2, second.stdout + second.stderr
        assert f"pid {first.pid}, operator interface {url}" in second.stderr, second.stderr
        assert "Traceback" not in second.stderr
        assert "processes:" not in second.stdout and "pilot token" not in second.stdout  # nothing started
        assert took_s < 10.0  # the interpreter's imports (1-2 s), then the lock: no process was started
        time.sleep(1.0)
        assert first.poll() is None  # the first keeps running
    finally:
        first.send_signal(signal.SIGINT)
        try:
            first.wait(30)
        except subprocess.TimeoutExpired:
            first.kill()
    assert first.returncode == 0


@pytest.mark.live
def test_a_second_run_is_refused_within_a_second_before_the_stack_is_imported(tmp_path, run_env):
    """The lock is checked before the control stack's libraries are loaded: a refusal costs the
    interpreter's start and the launcher's light imports only (0.3-0.7 s on a loaded machine)."""
    config = _sim_config(tmp_path)
    holder = RunLock(run_identities(LaunchConfig()), directory=Path(run_env[RUNTIME_DIR_ENV]))
    holder.acquire("http://127.0.0.1:8080/")
    try:
        probe = ("import sys, runpy; sys.argv = ['lotsen', 'run', sys.argv[1], '--sim', '--port', '0']\n"
                 "try:\n    runpy.run_module('lotsen', run_name='__main__')\n"
                 "finally:\n    print('loaded:', *(m for m in ('numba', 'scipy', 'fastapi', 'osqp') if m in sys.modules),"
                 " file=sys.stderr)")
        t0 = time.monotonic()
        refused = subprocess.run([sys.executable, "-c", probe, str(config)], cwd=tmp_path, env=run_env,
                                 capture_output=True, text=True, timeout=30)
        took_s = time.monotonic() - t0
    finally:
        holder.release()
    assert refused.returncode == 2, refused.stderr
    first, loaded = refused.stderr.strip().splitlines()[0], refused.stderr.strip().splitlines()[-1]
    assert first.startswith("error: another lotsen run is already running on this boat") and "http://127.0.0.1:8080/" in first
    assert loaded == "loaded:"  # none of the heavy libraries was imported for the refusal
    assert took_s < 1.0, f"refused after {took_s:.2f} s"
