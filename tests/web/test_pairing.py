"""The boat's pilot credential (issue 41 item 1): made once and kept private, the same at every
start, replaced by one command (and the replacement reaches a running server), printed with the
QR code of the pairing address."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from lotsen.errors import ConfigError
from lotsen.web import pairing
from lotsen.web.pairing import PilotCredential, credential_path, pairing_url, qr_svg, qr_text

CONFIG = Path(__file__).resolve().parents[2] / "config" / "sim.yaml"


def test_made_once_private_and_the_same_at_every_start(tmp_path, monkeypatch):
    monkeypatch.setenv(pairing.CONFIG_DIR_ENV, str(tmp_path / "cfg"))
    path = credential_path("sim boat lake boat")
    assert path.parent == tmp_path / "cfg" / "pairing" and path.name == "sim-boat-lake-boat.credential"
    cred, created = PilotCredential.load_or_create(path)
    assert created and len(cred.current()) == 32
    assert stat.S_IMODE(path.stat().st_mode) == 0o600 and stat.S_IMODE(path.parent.stat().st_mode) == 0o700
    again, created2 = PilotCredential.load_or_create(path)
    assert not created2 and again.current() == cred.current()


def test_a_replaced_credential_reaches_the_running_server_and_bad_files_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(pairing, "RECHECK_S", 0.0)
    path = tmp_path / "boat.credential"
    cred, _ = PilotCredential.load_or_create(path)
    old = cred.current()
    running = PilotCredential(path)  # the web process's copy
    assert running.current() == old
    new = cred.renew()
    assert new != old and running.current() == new
    os.chmod(path, 0o644)
    with pytest.raises(ConfigError, match="readable by others"):
        PilotCredential(path).current()
    assert running.current() == ""  # a file gone bad lets nobody in, rather than the old credential
    os.chmod(path, 0o600)
    path.write_text("password\n")
    with pytest.raises(ConfigError, match=f"pilot credential {path}: too weak"):
        PilotCredential(path).current()


def test_the_pairing_address_carries_the_credential_in_its_fragment_and_its_qr_code():
    url = pairing_url("http://192.168.4.1:8080/", "Tq7-vLx2_Rb9KmZ4wNc8HsTq7-vLx2_Rb")
    assert url == "http://192.168.4.1:8080/#pair=Tq7-vLx2_Rb9KmZ4wNc8HsTq7-vLx2_Rb"
    text = qr_text(url, invert=False)
    m = pairing._matrix(url)
    # the terminal rendering is the code's matrix, two modules per character
    top = {"\u2580", "\u2588"}
    assert [c in top for c in text.splitlines()[0]] == m[0]
    assert 'viewBox="0 0 %d %d"' % (len(m), len(m)) in qr_svg(url)


def test_with_the_port_chosen_at_start_no_address_with_port_0_is_printed(tmp_path):
    """web.port 0: the server picks its port at start, so `lotsen run` cannot know the pairing address
    when it prints the credential; it said http://HOST:0/#pair=... (an address that opens nothing)."""
    assert pairing.page_base_url("127.0.0.1", 0) is None
    assert pairing.page_base_url("127.0.0.1", 8080) == "http://127.0.0.1:8080/"
    lines = pairing.console_lines("Tq7-vLx2", tmp_path / "c", None, created=False)
    assert len(lines) == 2 and ":0/" not in "".join(lines) and "#pair=Tq7-vLx2" in lines[1], lines


def _pair(tmp_path, *args):
    env = {**os.environ, pairing.CONFIG_DIR_ENV: str(tmp_path / "cfg")}
    return subprocess.run([sys.executable, "-m", "lotsen", "pair", str(CONFIG), *args], capture_output=True,
                          text=True, env=env, timeout=60)


def test_lotsen_pair_shows_the_same_credential_until_new_replaces_it(tmp_path):
    first, second = _pair(tmp_path), _pair(tmp_path)
    assert first.returncode == 0 and second.returncode == 0, first.stderr
    cred = first.stdout.split("pilot credential of this boat: ")[1].split()[0]
    assert f"#pair={cred}" in second.stdout and "pair a phone: open http://127.0.0.1:8080/#pair=" in second.stdout
    renewed = _pair(tmp_path, "--new")
    assert renewed.returncode == 0 and "every paired phone must pair again" in renewed.stdout
    assert cred not in renewed.stdout
    cfg = tmp_path / "token.yaml"
    cfg.write_text(CONFIG.read_text().replace("  port: 8080", "  port: 8080\n  pilot_token: Tq7-vLx2_Rb9KmZ4wNc8HsX"))
    refused = subprocess.run([sys.executable, "-m", "lotsen", "pair", str(cfg)], capture_output=True, text=True,
                             env={**os.environ, pairing.CONFIG_DIR_ENV: str(tmp_path / "cfg")}, timeout=60)
    assert refused.returncode != 0 and "web.pilot_token is set in this config" in refused.stderr
    assert "Traceback" not in refused.stderr
