"""Optional TLS for the boat's Wi-Fi: a self-signed certificate made once with the `openssl`
command (Debian and Raspberry Pi OS ship it; no Python package needed) and its SHA-256
fingerprint, which the operator compares with the browser's certificate viewer on first
connection (then the browser's exception pins it)."""

from __future__ import annotations

import hashlib
import ipaddress
import os
import shutil
import ssl
import subprocess
from dataclasses import dataclass
from pathlib import Path

from lotsen.errors import ConfigError


@dataclass(frozen=True)
class Certificate:
    certfile: str
    keyfile: str
    fingerprint_sha256: str  # "AB:CD:..." as browsers show it


def fingerprint(certfile: str | os.PathLike) -> str:
    der = ssl.PEM_cert_to_DER_cert(Path(certfile).read_text(encoding="ascii"))
    digest = hashlib.sha256(der).hexdigest().upper()
    return ":".join(digest[i:i + 2] for i in range(0, len(digest), 2))


def ensure_certificate(directory: str | os.PathLike, hosts: tuple[str, ...] = ("localhost", "127.0.0.1"),
                       days: int = 825) -> Certificate:
    """`<directory>/lotsen-cert.pem` and `lotsen-key.pem` (ECDSA P-256), created when missing;
    `hosts` go into the subjectAltName (names and IP addresses of the boat)."""
    d = Path(directory).expanduser()
    cert, key = d / "lotsen-cert.pem", d / "lotsen-key.pem"
    if not (cert.is_file() and key.is_file()):
        openssl = shutil.which("openssl")
        if openssl is None:
            raise ConfigError("--tls: the 'openssl' command is needed to create a certificate "
                              "(apt-get install openssl), or set extra.web.tls_certfile/tls_keyfile")
        d.mkdir(parents=True, exist_ok=True)
        san = []
        for h in hosts:
            try:
                ipaddress.ip_address(h)
                san.append(f"IP:{h}")
            except ValueError:
                san.append(f"DNS:{h}")
        cmd = [openssl, "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
               "-keyout", str(key), "-out", str(cert), "-days", str(days), "-subj", "/CN=lotsen boat",
               "-addext", "subjectAltName=" + ",".join(san)]
        old = os.umask(0o077)  # the key is readable by its owner only
        try:
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=60, check=False)
        finally:
            os.umask(old)
        if res.returncode != 0:
            raise ConfigError(f"--tls: openssl failed: {res.stderr.strip()[:300]}")
    return Certificate(str(cert), str(key), fingerprint(cert))
