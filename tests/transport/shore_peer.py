"""Helper process for the Zenoh tests (the "shore"): connects to the test process over loopback,
records everything received from vessel "boat" (as boat/<topic>) to an MCAP file, and answers each `ping`
(a ThrustCommand) with a `pong` carrying the same stamp. Ends when stdin closes."""

import sys
import threading
import time

from lotsen.logs.recorder import McapRecorder, RecorderConfig
from lotsen.messages import ThrustCommand
from lotsen.runtime import Node, RealtimeExecutor
from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge


class Pong(Node):
    name = "pong"

    def start(self, ctx):
        self.ctx = ctx
        ctx.subscribe("boat/ping", lambda m: ctx.publish("pong", ThrustCommand(stamp_s=m.stamp_s, n1_rps=m.n1_rps, source="shore")))


def _until_told(ex: RealtimeExecutor, rec: McapRecorder) -> None:
    """Stops the shore when stdin closes; a line `expect N` first waits (at most 15 s) until N messages
    from the boat other than pings are recorded: the pong to the last ping can overtake the boat's other
    topics (their own subscribers), and a shore stopped on it lost the last 28 of 160 on a busy machine."""
    for line in sys.stdin:
        if line.startswith("expect "):
            n, deadline = int(line.split()[1]), time.monotonic() + 15.0
            while time.monotonic() < deadline and sum(
                    v for t, v in dict(rec.stats.per_topic).items() if t.startswith("boat/") and t != "boat/ping") < n:
                time.sleep(0.02)
    ex.stop()


def main(endpoint: str, out_mcap: str) -> None:
    ex = RealtimeExecutor()
    bridge = ZenohBridge(BridgeConfig(vessel="shore", connect=(endpoint,), subscribe=("boat/**",), publish=("pong",),
                                       local_prefix="boat/"))
    ex.add_node(bridge)
    ex.add_node(Pong())
    rec = McapRecorder(RecorderConfig(fsync=False), clock=ex.clock.now).attach(ex.bus)
    rec.start(out_mcap)
    threading.Thread(target=_until_told, args=(ex, rec), daemon=True).start()
    print("ready", flush=True)
    ex.run()
    bridge.close()
    rec.close()
    print("done", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
