"""Run `lotsen` command lines in-process, each in a forked child with a time limit (issue 42).

A server process (started once, single-threaded, so forking is safe) imports lotsen and the heavy
libraries the commands use, then forks a child per case: the child runs `lotsen.cli.main.main(argv)`
in the case's folder with its output in files, and reports its exit code; a child still running at
the case's time limit is killed with its whole process group (planner workers, a run's processes)
and counted as a hang. A case costs a fork (~10-30 ms) plus the command's own work, instead of a
Python start-up and imports (~1-2 s) per case.

    with CaseRunner() as runner:
        outcome = runner.run(["plan", "r.yaml"], cwd=folder, timeout_s=20)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

#: imported by the server before it forks: what the commands import lazily (numpy, scipy, shapely,
#: matplotlib, the planner, sysid, logs, ...), so a case pays none of it
PRELOAD = (
    "numpy", "scipy.linalg", "scipy.optimize", "shapely", "yaml", "matplotlib", "matplotlib.pyplot",
    "lotsen.cli.main", "lotsen.cli.plan", "lotsen.cli.mission", "lotsen.cli.model", "lotsen.cli.sim",
    "lotsen.cli.experiment", "lotsen.cli.identify", "lotsen.cli.calibrate", "lotsen.cli.logs", "lotsen.cli.gnss",
    "lotsen.cli.recover", "lotsen.cli.check", "lotsen.cli.run", "lotsen.planning", "lotsen.planning.io",
    "lotsen.sysid.experiment", "lotsen.sysid.data", "lotsen.sysid.identify", "lotsen.logs.reader",
    "lotsen.logs.recover", "lotsen.logs.export", "lotsen.drivers.ubx", "lotsen.stack.stack", "lotsen.stack.launch",
    "lotsen.harness.mission", "lotsen.fusion.magcal", "mcap.writer", "mcap.reader",
)

#: how a child marks an exception that escaped `main` (its stderr holds the traceback)
ESCAPED = 70
#: command lines the server runs once before serving (no threads, no processes left behind)
WARM_UP = (["model", "check"], ["sim", "--duration", "0.2", "--out", "t.csv"],
           ["experiment", "check", str(REPO / "examples" / "experiments" / "designed_12s.yaml")])

_SERVER = r"""
import importlib, json, os, resource, signal, sys, time, traceback
os.environ.setdefault("MPLBACKEND", "Agg")
for name in PRELOAD:
    try:
        importlib.import_module(name)
    except Exception:
        pass
from lotsen.cli.main import main

def warm_up():
    # compile (or load from numba's cache) the kernels here once, not in every child
    import contextlib, io, tempfile
    with tempfile.TemporaryDirectory() as d:
        cwd = os.getcwd()
        os.chdir(d)
        try:
            for argv in WARM_UP:
                with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
                    try:
                        main(argv)
                    except BaseException:
                        pass
        finally:
            os.chdir(cwd)

warm_up()

def child(case):
    os.setpgid(0, 0)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    limit = int(case.get("memory_mb", 3000)) * 1024 * 1024
    try:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    except (ValueError, OSError):
        pass
    os.chdir(case["cwd"])
    for fd, path, mode in ((0, "/dev/null", os.O_RDONLY), (1, case["stdout"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                           (2, case["stderr"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
        f = os.open(path, mode, 0o600)
        os.dup2(f, fd)
        os.close(f)
    sys.stdout = os.fdopen(1, "w", buffering=1)
    sys.stderr = os.fdopen(2, "w", buffering=1)
    sys.argv = ["lotsen", *case["argv"]]
    try:
        code = main(case["argv"])
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:
        traceback.print_exc()
        code = ESCAPED
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    finally:
        os._exit(int(code) & 0xFF)

print("ready", flush=True)
for line in sys.stdin:
    case = json.loads(line)
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:
        child(case)
    code, hang = None, False
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() - t0 > case["timeout_s"]:
            hang = True
            try:
                os.killpg(pid, signal.SIGKILL)
            except OSError:
                pass
            os.waitpid(pid, 0)
            break
        time.sleep(0.005)
    took = time.monotonic() - t0
    try:  # the case's other processes (a planner worker that outlived it)
        os.killpg(pid, signal.SIGKILL)
    except OSError:
        pass
    print(json.dumps({"code": code, "hang": hang, "seconds": took}), flush=True)
"""


@dataclass
class Outcome:
    argv: list[str]
    code: int | None  # None: killed at the time limit
    hang: bool
    seconds: float
    stdout: str
    stderr: str
    changed_inputs: list[str] = field(default_factory=list)  # filled by the caller

    @property
    def traceback(self) -> bool:
        """An exception escaped (in this process or one it started)."""
        return self.code == ESCAPED or "Traceback (most recent call last)" in self.stderr

    def describe(self) -> str:
        tail = (self.stderr.strip().splitlines() or [""])[-1][:300]
        return (f"lotsen {' '.join(self.argv)[:300]} -> "
                + ("HANG" if self.hang else f"exit {self.code}") + f" in {self.seconds:.1f} s: {tail}")


class CaseRunner:
    """The fork server (a context manager); `run` one case at a time."""

    def __init__(self, env: dict[str, str] | None = None, memory_mb: int = 3000) -> None:
        self.env = env
        self.memory_mb = memory_mb
        self.proc: subprocess.Popen | None = None

    def __enter__(self) -> "CaseRunner":
        env = dict(os.environ)
        env.update(self.env or {})
        env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        env.setdefault("MPLBACKEND", "Agg")
        code = f"PRELOAD = {PRELOAD!r}\nESCAPED = {ESCAPED}\nWARM_UP = {WARM_UP!r}\n" + _SERVER
        self.proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True, env=env, cwd=str(REPO))
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if line.strip() != "ready":
            raise RuntimeError(f"the fuzz case server did not start: {line!r}")
        return self

    def __exit__(self, *exc: object) -> None:
        if self.proc is not None:
            assert self.proc.stdin is not None
            self.proc.stdin.close()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            self.proc = None

    def run(self, argv: list[str], cwd: str | Path, timeout_s: float) -> Outcome:
        assert self.proc is not None and self.proc.stdin is not None and self.proc.stdout is not None
        cwd = Path(cwd)
        out, err = cwd.parent / f".{cwd.name}.stdout", cwd.parent / f".{cwd.name}.stderr"
        case = {"argv": list(argv), "cwd": str(cwd), "timeout_s": timeout_s, "stdout": str(out),
                "stderr": str(err), "memory_mb": self.memory_mb}
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        reply = self.proc.stdout.readline()
        if not reply:
            raise RuntimeError("the fuzz case server died")
        r = json.loads(reply)
        stdout = out.read_text(errors="replace")[-20000:] if out.exists() else ""
        stderr = err.read_text(errors="replace")[-20000:] if err.exists() else ""
        for f in (out, err):
            f.unlink(missing_ok=True)
        return Outcome(list(argv), r["code"], r["hang"], r["seconds"], stdout, stderr)


def file_digests(folder: Path) -> dict[str, tuple[int, int, bytes]]:
    """(size, mtime_ns, head) of each file in `folder`, to tell whether a case changed an input."""
    import hashlib

    out = {}
    for p in sorted(folder.iterdir()):
        if p.is_file() and not p.is_symlink():
            out[p.name] = (p.stat().st_size, p.stat().st_mtime_ns, hashlib.sha1(p.read_bytes()).digest())
    return out


def measure(runner: CaseRunner, argv: list[str], cwd: Path, timeout_s: float, inputs: list[str]) -> Outcome:
    """Run a case and note which of `inputs` (file names in `cwd`) it changed or removed."""
    before = {k: v for k, v in file_digests(cwd).items() if k in inputs}
    t0 = time.monotonic()
    outcome = runner.run(argv, cwd, timeout_s)
    outcome.seconds = min(outcome.seconds, time.monotonic() - t0)
    after = file_digests(cwd)
    outcome.changed_inputs = [k for k, v in before.items() if after.get(k, (None, None, None))[2] != v[2]]
    return outcome
