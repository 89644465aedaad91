"""The boat's pilot credential: made once, kept on the boat, paired to a phone by a QR code.

A run used to make a new pilot token each time; after the boat's computer restarted mid-lake the
phone's page came back as "wrong pilot token" and the new one was only on the boat's console
(issue 41). Now the credential belongs to the boat, not to one run:

- `PilotCredential.load_or_create(path)` makes it once (192 random bits, URL-safe) in a file
  readable by its user only (folder 0700, file 0600, written atomically) and reads it at every
  later start; a file someone made weak or readable by others is refused with an error naming it.
- The console prints it with a QR code of the **pairing address** `http://boat:8080/#pair=<credential>`
  (`pairing_url`, `qr_text`); the page served there takes the credential from the address's
  fragment (never sent to the server, removed from the address bar at once), keeps it in the
  browser's storage for this boat's address and takes the controls with it at every (re)connect.
  A pilot page can show the same QR code for a second phone (`qr_svg`).
- `lotsen pair --new` replaces it: a running web server re-reads the file when it changes
  (`current`, a stat at most every `RECHECK_S`), the page seated with the old one loses the seat
  and every paired phone must scan the new code: revocation and a new pairing are one command.
- A configured `web.pilot_token` still wins (a fleet's own secret management); this file is
  used when none is configured.

One place for the credential: the web page's seat and anything else that authenticates the
pilot (ROS 2 commands, a MAVLink endpoint) read it through this module.
"""

from __future__ import annotations

import os
import re
import secrets
import socket
import stat
import tempfile
import threading
import time
from pathlib import Path

from lotsen.errors import ConfigError
from lotsen.web.auth import check_token_strength

#: where lotsen keeps its per-user state (the pairing folder below it); tests point it elsewhere
CONFIG_DIR_ENV = "LOTSEN_CONFIG_DIR"
RECHECK_S = 0.5
CREDENTIAL_BYTES = 24  # 192 bits, 32 URL-safe characters
PAIR_FRAGMENT = "pair"


def config_dir() -> Path:
    """$LOTSEN_CONFIG_DIR, else ~/.config/lotsen."""
    return Path(os.environ.get(CONFIG_DIR_ENV) or Path.home() / ".config" / "lotsen").expanduser()


def credential_path(boat: str) -> Path:
    """The credential file of the boat named `boat` (one per boat a machine runs)."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "-", boat).strip("-.") or "boat"
    return config_dir() / "pairing" / f"{slug[:80]}.credential"


def _write_private(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
    os.chmod(path.parent, 0o700)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".credential-", text=True)
    try:
        os.fchmod(fd, 0o600)
        with os.fdopen(fd, "w", encoding="ascii") as f:
            f.write(text + "\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


class PilotCredential:
    """The credential in `path`; `current()` is the one in force (re-read when the file changed)."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        self._value = ""
        self._stamp: tuple[int, int, int, int] | None = None
        self._checked = -1e9

    @classmethod
    def load_or_create(cls, path: str | os.PathLike) -> tuple["PilotCredential", bool]:
        """The boat's credential, made now if there is none yet; (credential, made now)."""
        cred = cls(path)
        created = False
        if not cred.path.exists():
            try:
                _write_private(cred.path, secrets.token_urlsafe(CREDENTIAL_BYTES))
            except OSError as exc:
                raise ConfigError(f"pilot credential {cred.path}: cannot be created ({exc.strerror or exc}); "
                                  f"set {CONFIG_DIR_ENV} to a writable folder or web.pilot_token") from None
            created = True
        cred.current()
        return cred, created

    def _read(self) -> str:
        try:
            st = self.path.stat()
        except OSError as exc:
            raise ConfigError(f"pilot credential {self.path}: {exc.strerror or exc} "
                              "(`lotsen pair --new` makes a new one)") from None
        if stat.S_IMODE(st.st_mode) & 0o077:
            raise ConfigError(f"pilot credential {self.path}: readable by others (mode "
                              f"{stat.S_IMODE(st.st_mode):o}); it must be 600 (chmod 600, or `lotsen pair --new`)")
        if st.st_size > 1024:
            raise ConfigError(f"pilot credential {self.path}: {st.st_size} bytes, not a credential")
        text = self.path.read_text(encoding="ascii", errors="replace").strip()
        check_token_strength(text, where=f"pilot credential {self.path}")
        self._stamp = (st.st_ino, st.st_mtime_ns, st.st_size, st.st_mode)
        return text

    def current(self) -> str:
        """The credential in force now. The file is looked at again at most every RECHECK_S; a
        file that became unreadable or weak keeps nobody in: "" (no token matches it)."""
        now = time.monotonic()
        with self._lock:
            if now - self._checked < RECHECK_S and self._value:
                return self._value
            self._checked = now
            try:
                st = self.path.stat()
                if (st.st_ino, st.st_mtime_ns, st.st_size, st.st_mode) != self._stamp or not self._value:
                    self._value = self._read()
            except (OSError, ConfigError):
                if not self._value:
                    raise
                self._value = ""
            return self._value

    def renew(self) -> str:
        """A new credential (every paired phone and the seated pilot lose it); the new one."""
        token = secrets.token_urlsafe(CREDENTIAL_BYTES)
        _write_private(self.path, token)
        with self._lock:
            self._checked, self._value, self._stamp = -1e9, "", None
        return self.current()


# ------------------------------------------------------------------------------------------------
# the pairing address and its QR code
# ------------------------------------------------------------------------------------------------
def lan_address() -> str:
    """This machine's address on its network (the one a phone on the boat's Wi-Fi reaches), found
    without sending anything (a UDP socket's route choice); the host name when there is none."""
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.connect(("10.255.255.255", 1))
            return s.getsockname()[0]
    except OSError:
        return socket.gethostname()


def page_base_url(host: str, port: int, tls: bool = False) -> str | None:
    """The page's address a phone can open: the bind address, or for 0.0.0.0 / :: the LAN one; None
    for port 0 (the web server picks its port at start: no address is known yet)."""
    if port == 0:
        return None
    if host in ("", "0.0.0.0", "::"):
        host = lan_address()
    shown = f"[{host}]" if ":" in host else host
    return f"{'https' if tls else 'http'}://{shown}:{port}/"


def pairing_url(base_url: str, credential: str) -> str:
    """The address that pairs a phone: the page, with the credential in the fragment (a fragment is
    never sent to the server nor kept in its logs; the page removes it from the address bar)."""
    return f"{base_url.rstrip('/')}/#{PAIR_FRAGMENT}={credential}"


def _matrix(data: str) -> list[list[bool]]:
    import qrcode

    q = qrcode.QRCode(error_correction=qrcode.constants.ERROR_CORRECT_M, border=2)
    q.add_data(data)
    q.make(fit=True)
    return q.get_matrix()


def qr_text(data: str, invert: bool = True) -> str:
    """A QR code of `data` for a terminal: two modules per character (half blocks), light on
    dark by default (most consoles; a phone's camera reads either)."""
    m = _matrix(data)
    if len(m) % 2:
        m.append([False] * len(m[0]))
    chars = {(False, False): " ", (True, False): "\u2580", (False, True): "\u2584", (True, True): "\u2588"}
    lines = []
    for top, bottom in zip(m[0::2], m[1::2]):
        row = [(a != invert, b != invert) for a, b in zip(top, bottom)]
        lines.append("".join(chars[c] for c in row))
    return "\n".join(lines)


def qr_svg(data: str) -> str:
    """A QR code of `data` as an SVG element (dark modules on white, one path)."""
    m = _matrix(data)
    n = len(m)
    path = "".join(f"M{x},{y}h1v1h-1z" for y, row in enumerate(m) for x, on in enumerate(row) if on)
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {n} {n}" shape-rendering="crispEdges" '
            f'role="img" aria-label="QR code that pairs a phone with this boat">'
            f'<rect width="{n}" height="{n}" fill="#fff"/><path d="{path}" fill="#000"/></svg>')


def console_lines(credential: str, path: Path, base_url: str | None, created: bool) -> list[str]:
    """What `lotsen run` and `lotsen pair` print: the credential, where it is kept, the pairing
    address and its QR code (without an address, port 0: how to make it from the one printed later)."""
    head = "new pilot credential of this boat" if created else "pilot credential of this boat"
    lines = [f"{head}: {credential} (kept in {path}; `lotsen pair --new` replaces it)"]
    if base_url is None:
        return lines + [f"pair a phone: the web port is chosen at start (web.port 0); open the operator "
                        f"interface's address `lotsen run` prints, with #pair={credential} after it"]
    url = pairing_url(base_url, credential)
    return lines + [f"pair a phone: open {url} or scan:", qr_text(url)]
