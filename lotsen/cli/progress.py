"""Progress lines of the long commands (`lotsen identify`, `lotsen experiment design`)."""

from __future__ import annotations

import sys
import time
from typing import Callable


def progress_printer(title: str) -> Callable[[str | None], None]:
    """Progress of a long command on stderr, on a terminal or not: a line per stage and every few
    seconds otherwise (a log or CI never waits in silence); called with None at the end."""
    t0 = time.monotonic()
    last = [t0 - 10.0]
    tty = sys.stderr.isatty()

    def progress(msg: str | None) -> None:
        now = time.monotonic()
        if msg is None:
            if tty:
                print(file=sys.stderr)
            return
        stage = not msg.startswith("iteration")
        if stage or now - last[0] >= (0.5 if tty else 5.0):
            last[0] = now
            line = f"{title}: {now - t0:5.1f} s  {msg}"
            if tty and not stage:
                print("\r" + line[:100].ljust(100), end="", file=sys.stderr, flush=True)
            else:
                print(("\r" if tty else "") + line, file=sys.stderr, flush=True)

    return progress
