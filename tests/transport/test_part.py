import socket

from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.launch import build_stack
from lotsen.stack.zenoh import add_bridge


def test_add_bridge_reads_extra_zenoh_and_is_absent_without_it():
    assert add_bridge(build_stack(LaunchConfig(), realtime=False, parts=())) is None
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cfg = LaunchConfig(extra={"zenoh": {"enabled": True, "vessel": "boat", "listen": [f"tcp/127.0.0.1:{port}"],
                                        "publish": [Topic.STATE], "subscribe": ["shore/**"]}})
    stack = build_stack(cfg, realtime=False, parts=())
    bridge = add_bridge(stack)
    try:
        assert stack.services["zenoh"] is bridge and bridge.config.listen == (f"tcp/127.0.0.1:{port}",)
        assert "multicast scouting off" in stack.services["banner"][-1]
        stack.executor.run_until(0.2)
    finally:
        for close in stack.services["on_shutdown"]:
            close()
