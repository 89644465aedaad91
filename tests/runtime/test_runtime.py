import math

import pytest

from lotsen.errors import ConfigError
from lotsen.messages import LogEvent, ThrustCommand, Topic
from lotsen.runtime import Bus, Node, SimExecutor
from lotsen.runtime.config import LaunchConfig, load_config
from lotsen.stack.launch import build_stack
from lotsen.runtime.guard import ActuatorGuard
from lotsen.stack.schedule import ScheduleNode, load_schedule


def test_bus_isolates_a_failing_subscriber():
    bus = Bus()
    got, logs = [], []
    bus.subscribe("a", lambda m: 1 / 0)
    bus.subscribe("a", got.append)
    bus.subscribe("log", logs.append)
    bus.publish("a", 5)
    assert got == [5]
    assert bus.stats.callback_errors == 1
    assert isinstance(logs[0], LogEvent) and "ZeroDivisionError" in logs[0].text


def test_bounded_queue_drops_oldest():
    bus = Bus()
    q = bus.queue(["t"], maxlen=3)
    for i in range(5):
        bus.publish("t", i)
    bus.publish("other", 99)
    assert [m for _, m in q.get_all()] == [2, 3, 4]
    assert q.dropped == 2


def test_sim_executor_runs_timers_in_time_order():
    ex = SimExecutor()
    order = []
    ex.add_timer(0.3, lambda: order.append(("a", round(ex.clock.now(), 6))))
    ex.add_timer(0.2, lambda: order.append(("b", round(ex.clock.now(), 6))))
    ex.run_until(0.6)
    assert order == [("a", 0.0), ("b", 0.0), ("b", 0.2), ("a", 0.3), ("b", 0.4), ("a", 0.6), ("b", 0.6)]


def test_failing_timer_is_reported_not_fatal():
    ex = SimExecutor()
    logs, ticks = [], []
    ex.bus.subscribe("log", logs.append)
    ex.add_timer(0.1, lambda: 1 / 0, "bad")
    ex.add_timer(0.1, lambda: ticks.append(1), "good")
    ex.run_until(0.25)
    assert len(ticks) == 3 and ex.timer_errors == 3 and logs[0].source == "bad"


def test_actuator_guard_stale_and_non_finite():
    g = ActuatorGuard(deadline_s=0.5)
    assert g.output(0.0) == (0, 0, 0, 0, 0)  # nothing received yet: neutral
    g.accept(ThrustCommand(stamp_s=0, n1_rps=50, n2_rps=50), 0.0)
    assert g.output(0.4)[2] == 50
    assert g.output(0.6) == (0, 0, 0, 0, 0) and g.counters.stale_events == 1
    g.accept(ThrustCommand(stamp_s=1, n1_rps=50, alpha1_rad=float("nan")), 1.0)
    assert g.output(1.0) == (0, 0, 0, 0, 0) and g.counters.non_finite == 1
    g.accept(ThrustCommand(stamp_s=2, n1_rps=500), 2.0)
    assert g.output(2.0)[2] == 100.0  # clipped to the limit


def test_sim_stack_stops_the_boat_when_commands_stop():
    stack = build_stack(LaunchConfig(), realtime=False, parts=())

    class Burst(Node):
        name = "burst"

        def start(self, ctx):
            self.ctx = ctx
            ctx.add_timer(0.1, self.tick)

        def tick(self):
            if self.ctx.now() < 3.0:
                self.ctx.publish(Topic.SHIP_COMMAND, ThrustCommand(stamp_s=self.ctx.now(), n1_rps=60, n2_rps=60))

    stack.add(Burst())
    logs = []
    stack.bus.subscribe(Topic.LOG, logs.append)
    stack.executor.run_until(3.4)
    assert stack.simulator.actuators.state[2] > 50
    stack.executor.run_until(5.0)
    assert abs(stack.simulator.actuators.state[2]) < 0.5
    assert any("stale thrust command" in e.text for e in logs)
    assert stack.bus.stats.published[Topic.IMU_RAW] == 501


def test_schedule_node_and_loader(tmp_path):
    f = tmp_path / "s.yaml"
    f.write_text("segments:\n  - {duration_s: 1.0, n1_rps: 40, n2_rps: 40}\n  - {duration_s: 1.0, alpha1_deg: 10}\n")
    sched = load_schedule(f)
    assert sched.duration_s == 2.0
    ex = SimExecutor()
    cmds = []
    ex.bus.subscribe(Topic.SHIP_COMMAND, cmds.append)
    ex.add_node(ScheduleNode(sched, rate_hz=10))
    ex.run_until(2.5)
    assert cmds[0].n1_rps == 40 and cmds[12].alpha1_rad == pytest.approx(math.radians(10))
    assert cmds[-1].source == "schedule:end"
    f.write_text("segments:\n  - {duration_s: 1.0, n1: 40}\n")
    with pytest.raises(ConfigError, match=r"segments\[0\]\.n1: unknown key \(did you mean 'n1_rps'\?\)"):
        load_schedule(f)


@pytest.mark.parametrize("text, message", [
    ("sim: {dt_s: fast}", "sim.dt_s: expected a number, got 'fast'"),
    ("nodes: {controler: mpc}", "nodes.controler: unknown key (did you mean 'controller'?)"),
    ("nodes: {controller: pid}", "nodes.controller: 'pid' is not one of"),
    ("web: {port: 99999}", "web.port: 99999 outside the allowed range"),
    ("sim: {initial_state: [1, 2]}", "sim.initial_state: expected 6 values, got 2"),
    ("sim: {environment: {current_speed_mps: .nan}}", "is not finite"),
    ("web: [1, 2]", "web: expected a mapping"),
    ("sim: {dt_s: 1", "not valid YAML at line"),
])
def test_config_errors_name_key_and_value(tmp_path, text, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_config(f)
    assert message in str(exc.value) and str(f) in str(exc.value)


def test_config_defaults_and_missing_file(tmp_path):
    f = tmp_path / "ok.yaml"
    f.write_text("seed: 4\nsim: {environment: {current_speed_mps: 0.1}}\n")
    cfg = load_config(f)
    assert cfg.seed == 4 and cfg.sim.environment.current_speed_mps == 0.1 and cfg.web.host == "127.0.0.1"
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")


def test_rtk_on_and_off_in_simulation():
    from lotsen.messages import GnssFixType, OperatorCommand

    stack = build_stack(LaunchConfig(), realtime=False, parts=())
    fixes = []
    stack.bus.subscribe(Topic.GNSS, fixes.append)
    stack.executor.run_until(1.0)
    assert fixes[-1].fix_type == GnssFixType.RTK_FIXED
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=1.0, action="rtk_stop"))
    stack.executor.run_until(2.0)
    assert fixes[-1].fix_type == GnssFixType.FIX_3D
    stack.bus.publish(Topic.OPERATOR, OperatorCommand(stamp_s=2.0, action="rtk_start"))
    stack.executor.run_until(5.0)
    assert fixes[-1].fix_type == GnssFixType.RTK_FLOAT
    stack.executor.run_until(11.0)
    assert fixes[-1].fix_type == GnssFixType.RTK_FIXED


def test_a_queue_takes_a_batch_with_drop_oldest_and_a_bus_names_its_subscribed_topics():
    from lotsen.runtime.bus import BoundedQueue

    q = BoundedQueue(maxlen=4)
    q.put("a", 0)
    q.put_many([("b", i) for i in range(1, 6)])
    assert q.get_all() == [("b", 2), ("b", 3), ("b", 4), ("b", 5)] and q.dropped == 2
    q.put_many([])
    assert q.get(timeout=0.0) is None and q.dropped == 2

    bus = Bus()
    bus.subscribe("x", lambda m: None)
    bus.subscribe_all(lambda t, m: None)
    bus.queue(["y"])
    bus.queue(None)
    assert bus.subscribed_topics() == {"x", "y"}


@pytest.mark.live
def test_the_realtime_loop_sleeps_until_its_next_timer_and_wakes_for_a_call_at_once():
    import threading
    import time

    from lotsen.runtime import RealtimeExecutor

    ex = RealtimeExecutor()
    ticks: list[float] = []
    ex.add_timer(0.25, lambda: ticks.append(time.monotonic()))
    calls: list[float] = []
    threading.Timer(0.1, lambda: ex.call_soon_threadsafe(lambda: calls.append(time.monotonic()))).start()
    t0, cpu0 = time.monotonic(), time.process_time()
    ex.run(duration_s=1.0)
    wall, cpu = time.monotonic() - t0, time.process_time() - cpu0
    assert 0.95 <= wall < 1.3 and len(ticks) in (4, 5)  # at 0, 0.25, ... s
    assert calls and calls[0] - t0 < 0.2  # the call ran when it came, not at the next timer
    assert cpu < 0.05  # ~6 wake-ups, no polling between them (a 20 Hz poll alone took ~1.5 ms / s)


def test_background_work_runs_off_the_loop_and_its_result_comes_back_on_the_loops_thread():
    """`run_in_background`: on a real-time executor the work runs on another thread while the loop keeps
    its timers, and `done` runs on the loop's thread with the result or the error; on simulated time it
    runs at once, inline (deterministic, no simulated time taken)."""
    import threading
    import time

    from lotsen.runtime import RealtimeExecutor

    ex = RealtimeExecutor()
    loop = threading.get_ident()
    ticks: list[float] = []
    ex.add_timer(0.02, lambda: ticks.append(time.monotonic()))
    seen: list = []

    def slow() -> int:
        time.sleep(0.3)  # a long job (no interpreter lock held): the loop's timers go on
        return threading.get_ident()

    def fail() -> None:
        raise ValueError("bad route")

    ex.call_soon_threadsafe(lambda: ex.run_in_background(slow, lambda r, e: seen.append((r, e, threading.get_ident()))))
    ex.call_soon_threadsafe(lambda: ex.run_in_background(fail, lambda r, e: seen.append((r, e, threading.get_ident()))))
    ex.run(duration_s=0.6)
    (worker, err, where), (none, error, where2) = seen
    assert worker != loop and err is None and where == where2 == loop
    assert none is None and isinstance(error, ValueError) and str(error) == "bad route"
    assert max(b - a for a, b in zip(ticks, ticks[1:])) < 0.1  # the loop kept its period meanwhile
    ex.stop()  # ... and the worker thread ends with the executor
    ex._background._thread.join(2.0)
    assert not ex._background._thread.is_alive()

    sim = SimExecutor()
    out: list = []
    sim.run_in_background(lambda: 7, lambda r, e: out.append((r, e)))
    assert out == [(7, None)] and sim.clock.now() == 0.0


def test_the_realtime_loop_puts_its_timers_on_one_grid_so_they_fall_due_together():
    """A timer's first run is the next 10 ms grid point: the core's 100 Hz boat, 20 Hz fusion and
    10 Hz supervisor then run in one wake-up of the loop, not each in its own (fewer wake-ups of
    an idle run); the simulated-time executor keeps the times it was given."""
    from lotsen.runtime.clock import SimClock
    from lotsen.runtime.executor import TIMER_GRID_S, RealtimeExecutor, SimExecutor, on_grid

    assert on_grid(0.0, 0.01) == 0.0 and on_grid(0.013, 0.01) == pytest.approx(0.02)
    assert on_grid(0.02 + 1e-13, 0.01) == pytest.approx(0.02)  # a hair of rounding is on the point

    class Fixed(SimClock):
        pass

    clock = Fixed()
    clock.set(12.3456)
    ex = RealtimeExecutor(clock=clock)  # type: ignore[arg-type]
    a = ex.add_timer(0.01, lambda: None)
    clock.set(12.3501)
    b = ex.add_timer(0.05, lambda: None, phase_s=0.003)
    for t in (a, b):
        k = t.next_t / TIMER_GRID_S
        assert abs(k - round(k)) < 1e-6
    assert a.next_t == pytest.approx(12.35) and b.next_t == pytest.approx(12.36)
    sim = SimExecutor()
    sim.sim_clock.set(1.2345)
    assert sim.add_timer(0.01, lambda: None).next_t == 1.2345
