"""`lotsen pair`: the boat's pilot credential, its QR code to pair a phone, and a new one.

    lotsen pair [CONFIG]          the credential and the QR code of the pairing address (made now if none)
    lotsen pair [CONFIG] --new    a new credential: every paired phone and the page seated with the
                                  old one lose it (a running `lotsen run` takes the new one within a second)

The credential is kept per boat in $LOTSEN_CONFIG_DIR/pairing (default ~/.config/lotsen), readable by
its user only (lotsen.web.pairing); `extra.web.credential_file` names another file.
"""

from __future__ import annotations

import argparse

from lotsen.errors import ConfigError
from lotsen.settings import PORT


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("pair", help="the boat's pilot credential: its QR code to pair a phone, or a new one (--new)")
    p.add_argument("config", nargs="?", help="launch config YAML (default: built-in defaults)")
    p.add_argument("--new", action="store_true",
                   help="replace the credential: every paired phone must scan the new code (revocation)")
    p.add_argument("--hardware", action="store_true", help="the boat's hardware run (not the simulated boat)")
    p.add_argument("--host", help="the web address the phone opens (default from the config)")
    p.add_argument("--port", type=PORT, help="the web port (default from the config)")
    p.add_argument("--tls", action="store_true", help="the page is served over HTTPS (lotsen run --tls)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from lotsen.stack.config import load_stack_config
    from lotsen.stack.web import pilot_credential_file
    from lotsen.web.pairing import PilotCredential, console_lines, page_base_url

    config = load_stack_config(args.config)
    if args.hardware:
        config = replace(config, mode="hardware")
    if config.web.pilot_token:
        raise ConfigError("web.pilot_token is set in this config: the page takes that token; pairing with the "
                          "boat's own credential needs it unset (then `lotsen pair` shows the QR code)")
    path = pilot_credential_file(config)
    cred, created = PilotCredential.load_or_create(path)
    if args.new and not created:
        cred.renew()
        print(f"pilot credential replaced: every paired phone must pair again ({path})")
    base = page_base_url(args.host or config.web.host, args.port if args.port is not None else config.web.port,
                         args.tls)
    for line in console_lines(cred.current(), path, base, created or args.new):
        print(line)
    return 0
