"""Storage as a failure (issue 41 item 5): the log folder on a real, full file system (a 1 MiB
tmpfs): the recorder stops writing at the first failure and says what it kept (a readable file
up to its last flush), the supervisor raises the storage alert and its pre-arm check names the
disk, and the run goes on (the boat stays as it was)."""

from __future__ import annotations

import time

from lotsen.logs.reader import LogReader
from lotsen.logs.recorder import RecorderConfig
from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig, NodesSection, SimSection
from lotsen.stack.launch import build_stack
from lotsen.stack.logs import add_recorder


def _stack(directory, min_free_mb: float):
    cfg = LaunchConfig(nodes=NodesSection(fusion="truth", controller="los"),
                       sim=SimSection(initial_state=(4.0, 20.0, 0.0, 0.0, 0.0, 0.0), esc_arm_time_s=0.5),
                       extra={"failsafes": {"prearm_skip": ["pilot_link"], "storage_min_free_mb": min_free_mb}})
    stack = build_stack(cfg, realtime=False, parts=("state", "supervisor"))
    said: list[str] = []
    rec = add_recorder(stack, RecorderConfig(directory=str(directory), flush_period_s=0.1, fsync=False),
                       start=True)
    stack.nodes["logging"].console = said.append
    alerts: list = []
    stack.bus.subscribe(Topic.ALERT, alerts.append)
    return stack, rec, said, alerts


def test_a_full_log_disk_stops_the_recording_says_what_it_kept_and_refuses_the_arm(small_filesystem):
    where, fill = small_filesystem
    fill(200_000)
    stack, rec, said, alerts = _stack(where, min_free_mb=0.01)  # only the write failure counts here
    sup = stack.nodes["supervisor"]
    t_end = time.monotonic() + 30.0
    while not said and time.monotonic() < t_end:  # the writer thread flushes at wall-clock pace
        stack.executor.run_for(0.5)
        time.sleep(0.1)
    stack.executor.run_for(1.5)
    assert said and "No space left on device" in said[0] and str(where) in said[0], said
    status = stack.bus.latest[Topic.RECORDER]
    assert status.error and not status.recording and "kB on disk" in status.kept
    storage = [a for a in alerts if a.code == "failsafe:storage" and a.active]
    assert storage and "No space left on device" in storage[-1].text  # (after "0.0 MB free", if that came first)
    why = sup.why_not("arm")
    assert why.startswith("storage: ") and "No space left on device" in why and str(where) in why, why
    assert sup.mode.name == "MANUAL"  # the run goes on as it was
    stats = rec.stats
    path = rec.path
    stack.shutdown()
    # what it kept reads, up to the last flush before the failure
    got = list(LogReader(path).messages())
    assert len(got) > 100 and stats.kept_bytes > 10_000 and 0.0 < stats.kept_until_s < 60.0
    assert f"up to {stats.kept_until_s:.1f} s of the run" in status.kept


def test_too_little_free_space_fails_the_arm_check_before_anything_is_lost(small_filesystem):
    where, fill = small_filesystem
    fill(400_000)
    stack, rec, said, alerts = _stack(where, min_free_mb=50.0)
    stack.executor.run_for(1.5)
    why = stack.nodes["supervisor"].why_not("arm")
    assert why.startswith("storage: the log disk") and "MB free, below the 50 MB" in why and str(where) in why, why
    assert any(a.code == "failsafe:storage" for a in alerts)
    stack.shutdown()
