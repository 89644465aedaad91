"""What the project claims to install on, against what tools/check_wheels.py checks."""

from __future__ import annotations

import importlib.util
import re
import socket
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _check_wheels():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("check_wheels", ROOT / "tools" / "check_wheels.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_requires_python_is_the_oldest_named_os_image() -> None:
    cw = _check_wheels()
    lowest = cw.minimum_python()
    assert lowest == "3.11"  # numpy 2.4 / scipy 1.17 pins: 3.10 cannot install them
    named = sorted(cw.OS_IMAGES, key=lambda v: tuple(map(int, v.split("."))))
    assert named[0] == lowest, "the oldest OS image named as working must be the requires-python minimum"
    for v in cw.UNSUPPORTED:
        assert tuple(map(int, v.split("."))) < tuple(map(int, lowest.split(".")))


def test_readme_states_the_same_minimum() -> None:
    lowest = _check_wheels().minimum_python()
    readme = (ROOT / "README.md").read_text()
    claimed = set(re.findall(r"Python >= (\d+\.\d+)", readme))
    assert claimed == {lowest}, f"README claims Python >= {sorted(claimed)}, pyproject.toml >= {lowest}"


def test_every_dependency_is_pinned() -> None:
    # check_wheels resolves exactly these: a range would check one version and install another
    for req in _check_wheels().requirements(("sysid",)):
        assert re.fullmatch(r"[A-Za-z0-9_.\-]+(\[[a-z,]+\])?==[0-9][0-9A-Za-z.]*", req), req


def _pypi_reachable() -> bool:
    try:
        socket.create_connection(("pypi.org", 443), timeout=3).close()
        return True
    except OSError:
        return False


@pytest.mark.slow
def test_pins_resolve_as_aarch64_wheels_for_the_minimum_and_not_below() -> None:
    if not _pypi_reachable():
        pytest.skip("PyPI not reachable")
    cw = _check_wheels()
    reqs = cw.requirements()
    ok, what = cw.resolve(cw.minimum_python(), reqs)
    assert ok, what
    ok_below, _ = cw.resolve("3.10", reqs)
    assert not ok_below, "Python 3.10 resolves the pins: requires-python could be lowered"
