"""Callbacks that raise are counted and logged once per distinct error, repeats rate-limited."""

from lotsen.messages import LogEvent
from lotsen.runtime import Bus, SimExecutor
from lotsen.runtime.callback_errors import CallbackErrors


def test_a_distinct_error_is_logged_once_then_repeats_are_counted_and_summarised():
    now = [0.0]
    errors = CallbackErrors(period_s=10.0, clock=lambda: now[0])
    assert "ValueError" in errors.record("subscriber f", "a", ValueError("x=1"))
    for i in range(49):  # 50 Hz for a second: counted, not logged
        now[0] += 0.02
        assert errors.record("subscriber f", "a", ValueError(f"x={i}")) is None
    assert errors.record("subscriber g", "a", ValueError("y")) is not None  # another callback: distinct
    assert errors.record("subscriber f", "a", KeyError("k")) is not None  # another exception type: distinct
    now[0] = 10.5
    again = errors.record("subscriber f", "a", ValueError("x=99"))
    assert again is not None and "50 times since the last report" in again and "51 in all" in again
    assert errors.total == 53 and errors.distinct == 3
    assert errors.summary().startswith("callback errors: 53 (3 distinct")


def test_a_failing_subscriber_at_50_hz_is_counted_and_logged_once_per_period():
    ex = SimExecutor()
    logs: list[LogEvent] = []
    ex.bus.subscribe("log", logs.append)
    ex.bus.subscribe("a", lambda m: 1 / 0)
    ex.add_timer(0.02, lambda: ex.bus.publish("a", 1), "source")
    ex.run_for(25.0)
    assert ex.health()["callback_errors"] == ex.bus.stats.callback_errors >= 1249
    texts = [e.text for e in logs if e.source == "bus"]
    assert 3 <= len(texts) <= 4 and "ZeroDivisionError" in texts[0]  # at 0, ~10 and ~20 s


def test_failing_timers_and_external_calls_count_where_health_is_reported():
    ex = SimExecutor()
    logs: list[LogEvent] = []
    ex.bus.subscribe("log", logs.append)
    ex.add_timer(0.1, lambda: {}["missing"], "broken")
    ex.call_soon_threadsafe(lambda: None)
    ex.run_for(1.0)
    health = ex.health()
    assert health["timer_errors"] == health["callback_errors"] == 11
    assert len([e for e in logs if e.source == "broken"]) == 1
    assert logs[0].data["callback_errors"] == 1


def test_a_bare_bus_still_isolates_and_counts():
    bus = Bus()
    got = []
    bus.subscribe("a", lambda m: 1 / 0)
    bus.subscribe("a", got.append)
    for i in range(3):
        bus.publish("a", i)
    assert got == [0, 1, 2] and bus.stats.callback_errors == 3
    assert "ZeroDivisionError" in bus.stats.last_error
