"""Helper process for the Zenoh tests (the "shore"): connects to the test process over loopback,
records everything received from vessel "boat" (as boat/<topic>) to an MCAP file, and answers each `ping`
(a ThrustCommand) with a `pong` carrying the same stamp. Ends when stdin closes."""

import sys
import threading

from lotsen.logs.recorder import McapRecorder, RecorderConfig
from lotsen.messages import ThrustCommand
from lotsen.runtime import Node, RealtimeExecutor
from lotsen.transport.zenoh_bridge import BridgeConfig, ZenohBridge


class Pong(Node):
    name = "pong"

    def start(self, ctx):
        self.ctx = ctx
        ctx.subscribe("boat/ping", lambda m: ctx.publish("pong", ThrustCommand(stamp_s=m.stamp_s, n1_rps=m.n1_rps, source="shore")))


def main(endpoint: str, out_mcap: str) -> None:
    ex = RealtimeExecutor()
    bridge = ZenohBridge(BridgeConfig(vessel="shore", connect=(endpoint,), subscribe=("boat/**",), publish=("pong",),
                                       local_prefix="boat/"))
    ex.add_node(bridge)
    ex.add_node(Pong())
    rec = McapRecorder(RecorderConfig(fsync=False), clock=ex.clock.now).attach(ex.bus)
    rec.start(out_mcap)
    threading.Thread(target=lambda: (sys.stdin.read(), ex.stop()), daemon=True).start()
    print("ready", flush=True)
    ex.run()
    bridge.close()
    rec.close()
    print("done", flush=True)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
