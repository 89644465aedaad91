"""`lotsen check [CONFIG.yaml] [--emulated]`: pre-flight check of the boat's devices.

Opens every device of the hardware config through the real drivers, lets them settle for
SETTLE_S (opening, the GNSS configuration, what queued meanwhile), then reads for `--duration`
seconds (default 2) at wall-clock pace with the thrusters held at neutral (no ship_command is
sent: the ESCs only see their arming pulse), and prints one row per device: whether it opened,
the message rate measured after the settling against the expected one, errors and dropped
input. Exit code 0 when every enabled device is healthy, 1 otherwise. `--emulated` runs against
the emulated twins.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from lotsen.settings import Number

#: Seconds left out of the rate: the devices open, the GNSS receiver is configured, and what
#: queued meanwhile arrives in bursts (in a 2-s check those bursts were most of the intervals:
#: the GNSS read 24 Hz for 8, the RC receiver 218 Hz for 111).
SETTLE_S = 1.0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("check", help="pre-flight check: open each device, measure its rate and health")
    p.add_argument("config", nargs="?", help="launch config YAML with an extra.hardware section (default: built-in)")
    p.add_argument("--emulated", action="store_true", help="check against the emulated devices")
    p.add_argument("--duration", type=Number(0.1, 600.0, "s"), default=2.0, help="seconds to read (default 2)")
    p.set_defaults(func=run)


def format_table(rows: list, extra: dict[str, str]) -> str:
    head = ("device", "status", "rate Hz", "expected", "msgs", "errors", "dropped", "detail")
    table = [head]
    for h in rows:
        status = "OK" if h.ok else ("MISSING" if not h.opened else "DEGRADED")
        detail = h.detail or ", ".join(f"{k}={v}" for k, v in sorted(h.counters.items()))
        if h.name in extra:
            detail = "; ".join(x for x in (detail, extra[h.name]) if x)
        table.append((f"{h.name}: {h.device}", status, f"{h.rate_hz:.1f}", f"{h.expected_hz:.1f}", str(h.messages),
                      str(h.errors), str(h.dropped), detail))
    widths = [max(len(r[i]) for r in table) for i in range(len(head) - 1)]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r[:-1], widths)) + "  " + r[-1] for r in table)


def run(args: argparse.Namespace) -> int:
    from lotsen.stack.hardware import add_hardware_boat
    from lotsen.stack.config import load_stack_config
    from lotsen.runtime.executor import RealtimeExecutor
    from lotsen.stack.stack import Stack, vessel_model

    config = replace(load_stack_config(args.config), mode="hardware")
    hw = config.extra.hardware
    stack = Stack(config=config, executor=RealtimeExecutor(), model=vessel_model(config))
    boat = add_hardware_boat(stack, emulated=args.emulated, config=hw)
    print(f"lotsen check: reading {'emulated ' if args.emulated else ''}devices for {SETTLE_S:g} s + "
          f"{args.duration:.1f} s (thrusters held at neutral)...", flush=True)
    measure_from_s = stack.executor.clock.now() + SETTLE_S
    try:
        stack.executor.run(SETTLE_S + args.duration)
    finally:
        stack.executor.stop()
    extra: dict[str, str] = {}
    act = boat.drivers.get("actuators")
    if act is not None and act.health.opened:
        edges = ", ".join(f"GPIO {m.tacho_pin}: {m.tacho.total_edges}" for m in act.motors)
        extra["actuators"] = f"tachometer edges {edges} (0 expected at neutral)"
    gnss = boat.drivers.get("gnss")
    if gnss is not None and gnss.health.opened:
        r = gnss.receiver
        fix = stack.bus.latest.get("gps_chatter")
        extra["gnss"] = (f"configured={'yes' if r.configured else 'NO'}"
                         + (f", fix {fix.fix_type.name}, h_acc {fix.h_acc_m:.3f} m, {fix.num_sv} SV" if fix else ""))
    rc = boat.drivers.get("rc")
    if rc is not None and rc.health.opened:
        extra["rc"] = rc.detail()
    sounder = boat.drivers.get("echosounder")
    if sounder is not None and sounder.health.opened:
        extra["echosounder"] = sounder.detail()
    rows = boat.health(since_s=measure_from_s)
    print(format_table(rows, extra))
    bad = [h.name for h in rows if not h.ok]
    print("all devices OK" if not bad else f"NOT OK: {', '.join(bad)}")
    return 0 if not bad else 1
