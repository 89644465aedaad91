"""`lotsen` command line. Each command lives in its own module with `register(subparsers)`."""

from __future__ import annotations

import argparse
import importlib
import sys

from lotsen import __version__
from lotsen.errors import LotsenError

# module name in lotsen.cli -> registers one or more sub-commands
COMMAND_MODULES = (
    "model", "sim", "run", "plan", "mission", "identify", "experiment", "calibrate",
    "logs", "gnss", "check", "recover",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lotsen", description="lotsen - model-based autonomy for small surface vessels")
    parser.add_argument("--version", action="version", version=f"lotsen {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(f"lotsen.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"lotsen.cli.{name}":
                continue  # command not part of this build
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    try:
        return int(args.func(args) or 0)
    except LotsenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
