import dataclasses
import math
import os
import tempfile

import pytest

# the boat's pilot credential (lotsen.web.pairing) of every run a test starts goes here, never
# into the user's ~/.config/lotsen (inherited by the `lotsen run` processes the tests start)
os.environ.setdefault("LOTSEN_CONFIG_DIR", tempfile.mkdtemp(prefix="lotsen-test-config-"))


@pytest.fixture(autouse=True)
def _own_run_locks(tmp_path_factory, monkeypatch):
    """Every test's `lotsen run` takes its one-run-per-boat lock (lotsen.runtime.lifetime) in a
    directory of its own: the live tests run two at a time, and an operator's run of the same boat
    on this machine must neither refuse a test's run nor be refused by it."""
    monkeypatch.setenv("LOTSEN_RUNTIME_DIR", str(tmp_path_factory.mktemp("run-locks")))


def _same(a, b) -> bool:
    if dataclasses.is_dataclass(a):
        if type(a) is not type(b):
            return False
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, float) or isinstance(b, float):  # (the simulator publishes numpy floats)
        return (math.isnan(a) and math.isnan(b)) or a == b
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b


@pytest.fixture
def same():
    """Message equality where NaN equals NaN (messages carry NaN for 'not available')."""
    return _same


@pytest.fixture
def small_filesystem(tmp_path):
    """A real, small file system (tmpfs, 1 MiB) to fill up: `fill(leave_bytes)` writes a file that
    leaves about that much free. Needs root (CI runs as root on a fresh machine); skipped with the
    reason where mounting is impossible."""
    import os
    import subprocess

    if os.geteuid() != 0:
        pytest.skip("a full file system needs a small tmpfs, and mounting one needs root")
    where = tmp_path / "small-disk"
    where.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m,mode=0755", "tmpfs", str(where)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {done.stderr.strip() or done.returncode}")

    def fill(leave_bytes: int) -> None:
        st = os.statvfs(where)
        size = max(0, st.f_bavail * st.f_frsize - leave_bytes)
        with open(where / "ballast.bin", "ab") as f:
            f.write(b"\0" * size)

    try:
        yield where, fill
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)
