"""`lotsen` command line. Each command lives in its own module with `register(subparsers)`.

Only the module of the command being run is imported: the others appear in `lotsen --help` by
the one-line help of `COMMANDS`, so `lotsen --help` and `lotsen run` do not pay for importing
every library (numpy, scipy, numba, casadi, ...) that some other command uses.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys

from lotsen import __version__
from lotsen.errors import LotsenError

#: sub-command -> (module in lotsen.cli that registers it, its one-line help for `lotsen --help`);
#: a module may register several sub-commands (tests/test_cli.py checks both against the modules)
COMMANDS: dict[str, tuple[str, str]] = {
    "model": ("model", "inspect the vessel model"),
    "sim": ("sim", "run the simulated boat open loop and write the trajectory (CSV)"),
    "run": ("run", "run the full stack (simulated boat by default)"),
    "plan": ("plan", "plan a path through a route's nodes (cubic segments, speed profile)"),
    "mission": ("mission", "plan a route and fly it in closed loop on the simulated boat"),
    "identify": ("identify", "estimate the vessel parameters from experiment data"),
    "experiment": ("experiment", "identification experiments: run, check, design"),
    "calibrate-mag": ("calibrate", "fit the magnetometer's hard/soft iron from one full turn (seed 3.3)"),
    "replay": ("logs", "re-publish a log on the bus (and to Foxglove / Zenoh)"),
    "export": ("logs", "write the topics of a log as tables (CSV), and sysid.csv"),
    "record": ("logs", "record topics received over Zenoh to MCAP (shore side)"),
    "gnss-replay": ("gnss", "print the NAV-PVT fixes of a recorded UBX byte stream as CSV"),
    "check": ("check", "pre-flight check: open each device, measure its rate and health"),
    "recover": ("recover", "make a killed/unclosed MCAP recording readable (index + summary)"),
    "pair": ("pair", "the boat's pilot credential: its QR code to pair a phone, or a new one (--new)"),
    "physics-server": ("physics", "serve the simulated boat as an ArduPilot SITL JSON physics (the reference for --physics)"),
}
COMMAND_MODULES = tuple(dict.fromkeys(module for module, _ in COMMANDS.values()))


def _register(sub: argparse._SubParsersAction, module_name: str) -> bool:
    try:
        module = importlib.import_module(f"lotsen.cli.{module_name}")
    except ModuleNotFoundError as exc:
        if exc.name == f"lotsen.cli.{module_name}":
            return False  # command not part of this build
        raise
    module.register(sub)
    return True


def build_parser(commands: tuple[str, ...] | None = None) -> argparse.ArgumentParser:
    """The parser; with `commands` only those commands' modules are imported (their full
    arguments), the others are listed by name and help only. None: every module."""
    parser = argparse.ArgumentParser(prog="lotsen", description="lotsen - model-based autonomy for small surface vessels")
    parser.add_argument("--version", action="version", version=f"lotsen {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    # the modules of the wanted commands first: a module registers all its commands (logs: export,
    # replay, record, ...), which must not meet a placeholder of the same name
    wanted = COMMAND_MODULES if commands is None else \
        tuple(dict.fromkeys(COMMANDS[c][0] for c in commands if c in COMMANDS))
    for module_name in wanted:
        _register(sub, module_name)
    for name, (_, help_line) in COMMANDS.items():
        if name not in sub.choices:  # listed only; never parsed (its module is not loaded)
            sub.add_parser(name, help=help_line, add_help=False)
    return parser


def command_of(argv: list[str]) -> str | None:
    """The sub-command of a command line (the first word that is not an option)."""
    return next((a for a in argv if not a.startswith("-")), None)


#: commands whose numerics are many small matrix products (identification, experiment design): one BLAS
#: thread. OpenBLAS's worker threads spin on matrices of tens of rows and burn a second core for nothing
#: (a 10-min lake identification: 24 s of CPU with the default threads, 14 s with one; the same answer)
SINGLE_THREADED_BLAS = ("identify", "experiment")


def single_threaded_blas() -> None:
    """One BLAS thread for this process (see SINGLE_THREADED_BLAS); effective only before numpy's import."""
    if "numpy" not in sys.modules:
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")


def main(argv: list[str] | None = None) -> int:
    """The command line `argv` (None: this process's, and the process ends when it returns)."""
    if argv is None:
        try:
            return _main(sys.argv[1:])
        finally:
            # the interpreter's last collections walk every object a numerical command made (a 10-min
            # identification: 0.25-0.3 s between its last word and its exit); the process ends now, so
            # they are left to it (gc.freeze: no object is collected any more, each is still freed)
            gc.freeze()
    return _main(list(argv))


def _main(argv: list[str]) -> int:
    command = command_of(argv)
    if command in SINGLE_THREADED_BLAS:
        single_threaded_blas()
    parser = build_parser((command,) if command in COMMANDS else ())
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    try:
        return int(args.func(args) or 0)
    except LotsenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # the machine's refusal (a name too long, a full disk, no permission): said plainly
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
