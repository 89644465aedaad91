"""Fixtures: a realtime stack (simulated boat + web server on a free loopback port) in a thread."""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass, field
from typing import Any

import pytest

from lotsen.runtime.config import LaunchConfig, LoggingSection, WebSection
from lotsen.stack.launch import build_stack
from lotsen.stack.stack import Stack
from lotsen.stack.web import add_web

TOKEN = "Tq7-vLx2_Rb9KmZ4wNc8Hs"  # 22 URL-safe characters: 132 bits by the strength rule


@dataclass
class RunningStack:
    stack: Stack
    port: int
    thread: threading.Thread
    seen: dict[str, list] = field(default_factory=dict)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws"

    def messages(self, topic: str) -> list:
        return list(self.seen.get(topic, []))


def start_stack(parts: tuple[str, ...] | None = (), extra_web: dict | None = None, tls: bool = False,
                log_dir: str = "", route: str | None = None, extra: dict | None = None, **web: Any) -> RunningStack:
    cfg = LaunchConfig(web=WebSection(port=0, pilot_token=web.pop("pilot_token", TOKEN), **web),
                       logging=LoggingSection(enabled=False, **({"directory": log_dir} if log_dir else {})),
                       route=route, extra={**(extra or {}), **({"web": extra_web} if extra_web else {})})
    stack = build_stack(cfg, realtime=True, parts=parts)
    if "web" not in stack.services:  # not registered as a part (yet): attach it here
        add_web(stack, tls=tls)
    seen: dict[str, list] = {}
    stack.bus.subscribe_all(lambda topic, msg: seen.setdefault(topic, []).append(msg)
                            if topic.startswith("operator/") or topic in ("planning/route",) else None)
    thread = threading.Thread(target=stack.executor.run, name="executor", daemon=True)
    thread.start()
    return RunningStack(stack, stack.services["web"].port, thread, seen)


def stop_stack(rs: RunningStack) -> None:
    rs.stack.executor.stop()
    rs.thread.join(timeout=5)
    for stop in rs.stack.services.get("on_shutdown", []):
        stop()


@pytest.fixture(scope="module")
def running():
    rs = start_stack()
    yield rs
    stop_stack(rs)


def recv_until(ws, pred, timeout: float = 3.0) -> dict:
    """Next message satisfying pred (telemetry and other traffic skipped)."""
    import time

    t_end = time.monotonic() + timeout
    while True:
        left = t_end - time.monotonic()
        if left <= 0:
            raise AssertionError("expected message not received")
        m = json.loads(ws.recv(timeout=left))
        if pred(m):
            return m
