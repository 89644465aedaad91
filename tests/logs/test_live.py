import asyncio
import json
import time

import pytest

from lotsen.stack.logs import add_foxglove_server
from lotsen.messages import Topic
from lotsen.runtime.config import LaunchConfig
from lotsen.stack.launch import build_stack

websockets = pytest.importorskip("websockets")


def test_foxglove_server_advertises_and_streams_the_stack_channels():
    stack = build_stack(LaunchConfig(), realtime=False, parts=())
    live = add_foxglove_server(stack, "127.0.0.1", 0)
    try:
        assert live.port > 0 and any("foxglove" in line for line in stack.services["banner"])
        stack.executor.run_until(1.0)  # sensors, truth, gnss -> channels are created as topics appear
        deadline = time.monotonic() + 5
        while live.sent < 10 and time.monotonic() < deadline:
            time.sleep(0.02)

        async def session():
            async with websockets.connect(f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.sdk.v1"],
                                          close_timeout=0.5) as ws:  # the server does not answer a close quickly
                assert ws.subprotocol == "foxglove.sdk.v1"
                channels, binary = {}, 0
                end = time.monotonic() + 5
                while time.monotonic() < end and not (channels and binary):
                    try:
                        frame = await asyncio.wait_for(ws.recv(), 0.2)
                    except asyncio.TimeoutError:
                        stack.executor.run_for(0.2)  # keep the boat publishing
                        continue
                    if isinstance(frame, str):
                        msg = json.loads(frame)
                        if msg["op"] == "advertise":
                            channels.update({c["id"]: c for c in msg["channels"]})
                            await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                                {"id": i, "channelId": cid} for i, cid in enumerate(channels)]}))
                    elif frame[0] == 1:  # message data
                        binary += 1
                return channels, binary

        channels, binary = asyncio.run(session())
    finally:
        for close in stack.services["on_shutdown"]:
            close()
    by_topic = {c["topic"]: c for c in channels.values()}
    assert by_topic[Topic.GNSS]["schemaName"] == "lotsen.GnssFix" and by_topic[Topic.GNSS]["encoding"] == "json"
    assert by_topic["foxglove/gnss"]["schemaName"] == "foxglove.LocationFix"
    assert by_topic["foxglove/tf"]["schemaName"] == "foxglove.FrameTransform"
    assert by_topic["foxglove/gnss_rtk"]["schemaName"] == "lotsen.RtkStatus"
    assert binary > 0
