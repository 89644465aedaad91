#!/usr/bin/env python3
"""Print the table of every number flag of `lotsen` with its allowed range (docs/inputs.md).

The ranges are the flags' `lotsen.settings.Number`s, read from the argparse parsers, so the table
is what the commands check: `python tools/number_flags.py` after adding or changing a flag.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from lotsen.cli.main import build_parser  # noqa: E402
from lotsen.settings import Number  # noqa: E402


def rows(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, str, str]]:
    out = []
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sub in a.choices.items():
                out += rows(sub, prefix + (name,))
        elif isinstance(a.type, Number):
            default = "" if a.default is None else f"{a.default:g}"
            out.append((" ".join(prefix), a.option_strings[0] if a.option_strings else a.dest,
                        f"{a.type.allowed()}" + (f" (default {default})" if default else "")))
    return out


if __name__ == "__main__":
    print("| command | flag | allowed |\n|---|---|---|")
    for command, flag, allowed in rows(build_parser()):
        print(f"| `lotsen {command}` | `{flag}` | {allowed} |")
