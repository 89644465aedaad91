#!/usr/bin/env python3
"""Does every pinned on-board dependency install on the boat's computer?

For each Python version the project claims (requires-python in pyproject.toml, up to the newest
one named in SUPPORTED), `pip download --only-binary=:all:` resolves the pinned dependencies for
Linux aarch64 (Raspberry Pi 4, 64-bit OS) into a temporary folder: a pin without an aarch64 wheel
for that Python, or one whose own requirement excludes it, fails here as it would on the Pi.

Usage: python tools/check_wheels.py [--python 3.11 ...] [--extra sysid]
Exit code 0 when every version resolves. Needs the network (PyPI); takes a minute or two.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: the Python of each OS image we name as working on the boat (README, docs/drivers.md)
OS_IMAGES = {
    "3.11": "Raspberry Pi OS bookworm / Debian 12",
    "3.12": "Ubuntu 24.04 LTS",
    "3.13": "Debian 13 trixie / Raspberry Pi OS trixie",
}
#: too old: the pins do not install there (numpy 2.4, scipy 1.17 need 3.11)
UNSUPPORTED = {"3.10": "Ubuntu 22.04 LTS"}
PLATFORMS = ("manylinux2014_aarch64", "manylinux_2_17_aarch64", "manylinux_2_28_aarch64")


def project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def minimum_python() -> str:
    """The version in requires-python (the project states exactly one lower bound)."""
    spec = project()["requires-python"]
    m = re.fullmatch(r"\s*>=\s*(\d+\.\d+)\s*", spec)
    if not m:
        raise SystemExit(f"pyproject.toml: requires-python {spec!r} is not of the form '>=3.N'")
    return m.group(1)


def requirements(extras: tuple[str, ...] = ()) -> list[str]:
    p = project()
    reqs = list(p["dependencies"])
    for e in extras:
        reqs += p["optional-dependencies"][e]
    return reqs


def resolve(python: str, reqs: list[str]) -> tuple[bool, str]:
    with tempfile.TemporaryDirectory(prefix="lotsen-wheels-") as tmp:
        req_file = Path(tmp) / "requirements.txt"
        req_file.write_text("\n".join(reqs) + "\n")
        cmd = [sys.executable, "-m", "pip", "--disable-pip-version-check", "download", "-q",
               "--only-binary=:all:", "--python-version", python, "--implementation", "cp",
               "-d", str(Path(tmp) / "wheels"), "-r", str(req_file)]
        for plat in PLATFORMS:
            cmd += ["--platform", plat]
        proc = subprocess.run(cmd, capture_output=True, text=True)
        if proc.returncode != 0:
            lines = [ln for ln in (proc.stderr or proc.stdout).splitlines() if ln.strip()]
            return False, " / ".join(lines[-3:])
        wheels = sorted(p.name for p in (Path(tmp) / "wheels").iterdir())
        return True, f"{len(wheels)} wheels"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--python", action="append", help="Python version(s) to check (default: every one claimed)")
    ap.add_argument("--extra", action="append", default=[], help="also an optional-dependency group")
    args = ap.parse_args()
    lowest = minimum_python()
    versions = args.python or [v for v in OS_IMAGES if tuple(map(int, v.split("."))) >= tuple(map(int, lowest.split(".")))]
    reqs = requirements(tuple(args.extra))
    print(f"requires-python >={lowest}; {len(reqs)} pinned dependencies; linux aarch64")
    failed = 0
    for v in versions:
        t0 = time.monotonic()
        ok, what = resolve(v, reqs)
        failed += not ok
        print(f"  Python {v} ({OS_IMAGES.get(v) or UNSUPPORTED.get(v, '')}): "
              f"{'ok' if ok else 'FAILS'}, {what} ({time.monotonic() - t0:.0f} s)", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
