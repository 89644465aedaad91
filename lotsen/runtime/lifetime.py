"""How long the processes of a run live, and how many runs a boat has.

`die_with_parent`: a child process of `lotsen run` ends when its launcher ends, however the
launcher ended (SIGKILL included). Two mechanisms, because either alone has a gap: Linux's
parent-death signal (prctl PR_SET_PDEATHSIG) arrives at once but is bound to the *thread* that
started the child and exists on Linux only; a watcher thread that sees the parent id change
(the orphan is adopted by init or a subreaper) works everywhere within `poll_s`. Either delivers
`signum` (SIGTERM: the process's own orderly shutdown, e.g. the core's neutral command and the
recorder's closed file); if that has not ended the process after `grace_s`, it exits hard.

`RunLock`: one run per boat. The launcher holds an flock'ed lock file per vessel identity (the
simulated boat's name, or each hardware device) in the user's runtime directory; the file holds
the pid and the web address of the run holding it. The kernel releases an flock when its holder
dies, so a lock left by a killed run is free and simply taken over.
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import json
import os
import re
import signal
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from lotsen.errors import LotsenError

PR_SET_PDEATHSIG = 1
#: overrides the directory of the run locks (tests; several independent boats on one computer)
RUNTIME_DIR_ENV = "LOTSEN_RUNTIME_DIR"


def die_with_parent(parent_pid: int, signum: int = signal.SIGTERM, *, parent_death_signal: bool = True,
                    poll_s: float = 0.2, grace_s: float = 5.0) -> str:
    """Make this process end when `parent_pid` (its parent) ends; returns how, for the banner.

    `parent_death_signal=False` where the parent may have started this process from a thread
    that ends before it does (the signal would come when that thread ends)."""
    how = []
    if parent_death_signal:
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(PR_SET_PDEATHSIG, int(signum), 0, 0, 0) == 0:
                how.append("parent-death signal")
        except (OSError, AttributeError):  # not Linux: the watcher below remains
            pass

    def orphaned() -> None:
        os.kill(os.getpid(), signum)
        time.sleep(grace_s)
        os._exit(70)

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        orphaned()

    if os.getppid() != parent_pid:  # the parent ended before the signal was set up
        threading.Thread(target=orphaned, name="orphaned", daemon=True).start()
    else:
        threading.Thread(target=watch, name="parent-watch", daemon=True).start()
    how.append(f"parent watched every {poll_s:g} s")
    return "ends with its launcher (" + ", ".join(how) + ")"


def process_cpu_seconds(pid: int) -> float | None:
    """A process's user + system CPU time so far, from /proc/PID/stat (Linux, the Pi's OS); None
    where the process is gone or /proc cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            fields = f.read().rsplit(b")", 1)[1].split()  # from field 3 of proc(5): the name may hold ")"
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime (fields 14, 15)
    except (OSError, ValueError, IndexError):
        return None


# ------------------------------------------------------------------------------------------------
# one run per boat
# ------------------------------------------------------------------------------------------------
class RunRefused(LotsenError):
    """Another run holds this boat."""


def runtime_dir() -> Path:
    """$LOTSEN_RUNTIME_DIR, else $XDG_RUNTIME_DIR/lotsen, else <tmp>/lotsen-<uid> (private)."""
    if os.environ.get(RUNTIME_DIR_ENV):
        return Path(os.environ[RUNTIME_DIR_ENV])
    if os.environ.get("XDG_RUNTIME_DIR"):
        return Path(os.environ["XDG_RUNTIME_DIR"]) / "lotsen"
    return Path(tempfile.gettempdir()) / f"lotsen-{os.getuid()}"


def _file_name(identity: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", identity).strip("_")[:120] + ".lock"


@dataclass(frozen=True)
class RunHolder:
    pid: int
    web: str
    identity: str

    def describe(self) -> str:
        return f"pid {self.pid}, operator interface {self.web or 'none'}"


def read_holder(path: Path) -> RunHolder | None:
    try:
        with open(path, "rb") as f:
            data = json.loads(f.read(64 * 1024))  # a lock file holds ~100 bytes; never read a huge one whole
        return RunHolder(int(data["pid"]), str(data.get("web", ""))[:300], str(data.get("identity", ""))[:300])
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return None


class RunLock:
    """Locks for the identities of one boat (`identities`: e.g. "sim boat: lake boat" or
    "serial /dev/ttyAMA1"), all or none; `RunRefused` names the run holding one of them."""

    def __init__(self, identities: list[str], directory: Path | None = None) -> None:
        self.identities = list(dict.fromkeys(identities))
        self.directory = Path(directory) if directory is not None else runtime_dir()
        self._files: dict[str, int] = {}
        self.web = ""

    def path(self, identity: str) -> Path:
        return self.directory / _file_name(identity)

    def acquire(self, web: str = "") -> None:
        try:
            self.directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        except OSError as exc:
            raise LotsenError(f"{self.directory}: cannot create the directory of run locks: "
                              f"{exc.strerror or exc} (set {RUNTIME_DIR_ENV})") from None
        try:
            for identity in self.identities:
                path = self.path(identity)
                try:
                    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
                except OSError as exc:
                    raise LotsenError(f"{path}: cannot open the run lock: {exc.strerror or exc}") from None
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except OSError as exc:
                    os.close(fd)
                    if exc.errno not in (errno.EWOULDBLOCK, errno.EACCES, errno.EAGAIN):
                        raise LotsenError(f"{path}: cannot lock: {exc.strerror or exc}") from None
                    holder = read_holder(path)
                    who = holder.describe() if holder else "its pid not yet written"
                    raise RunRefused(f"another lotsen run is already running on this boat ({identity}): {who}. "
                                     "Stop it first (Ctrl-C in its terminal, or kill that pid); "
                                     f"lock file {path}") from None
                self._files[identity] = fd
            self.update(web)
        except BaseException:
            self.release()
            raise

    def update(self, web: str) -> None:
        """Write this run's pid and web address into every held lock file."""
        self.web = web
        for identity, fd in self._files.items():
            data = json.dumps({"pid": os.getpid(), "web": web, "identity": identity}).encode()
            os.ftruncate(fd, 0)
            os.pwrite(fd, data, 0)

    def release(self) -> None:
        for fd in self._files.values():
            try:
                os.ftruncate(fd, 0)
            except OSError:
                pass
            os.close(fd)  # closing the descriptor releases the flock
        self._files.clear()

    @property
    def held(self) -> bool:
        return bool(self._files)
