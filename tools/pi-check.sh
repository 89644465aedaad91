#!/usr/bin/env bash
# make pi-check: install and run lotsen in an emulated Raspberry Pi OS base (Debian bookworm arm64)
#
# Builds once (cached in $PI_ROOTFS, default ~/.cache/lotsen/pi-rootfs) an arm64 Debian bookworm
# root file system with debootstrap; arm64 programs run through qemu-user-static and the kernel's
# binfmt_misc. Then, in a chroot: a fresh venv, `pip install -e .` of this checkout as the README
# does (`make venv`), `lotsen check --emulated`, a short `lotsen run --sim` (no browser), and the
# unit tests that need no browser. Writes the result to bench/results/pi-check.md.
# Needs root (debootstrap, chroot, binfmt_misc) and the network (Debian mirror, PyPI).
# Emulation is 5-20x slower than the host: the first run takes ~20 min, later runs less.
set -euo pipefail

SRC="$(cd "$(dirname "$0")/.." && pwd)"
ROOTFS="${PI_ROOTFS:-$HOME/.cache/lotsen/pi-rootfs}"
MIRROR="${PI_MIRROR:-http://deb.debian.org/debian}"
RUN_S="${PI_RUN_S:-30}"
TESTS="${PI_TESTS:-tests/model tests/sim tests/control tests/architecture tests/test_packaging.py}"
RESULT="$SRC/bench/results/pi-check.md"
LOG="$(mktemp -t lotsen-pi-check.XXXXXX.log)"

say() { echo "pi-check: $*"; }
die() { say "FAILED: $*"; write_result fail "$*"; exit 1; }

declare -a STEPS=()
write_result() {  # pass|fail, note
    mkdir -p "$(dirname "$RESULT")"
    {
        echo "# pi-check"
        echo
        echo "\`make pi-check\` (tools/pi-check.sh): lotsen installed and run in an emulated arm64"
        echo "Debian bookworm (the Raspberry Pi OS base; qemu-user-static on $(uname -m), so times are"
        echo "emulation times, not a Pi's)."
        echo
        echo "Run $(date '+%Y-%m-%d %H:%M'); result: **$1**${2:+ ($2)}."
        echo
        echo "| step | result | time (s) |"
        echo "|---|---|---|"
        for s in "${STEPS[@]}"; do echo "$s"; done
    } > "$RESULT"
    say "result in ${RESULT#$SRC/} (log: $LOG)"
}

step() {  # name, command... : runs, times, records
    local name="$1"; shift
    local t0=$SECONDS
    say "$name ..."
    if "$@" >>"$LOG" 2>&1; then
        STEPS+=("| $name | pass | $((SECONDS - t0)) |")
    else
        STEPS+=("| $name | FAIL | $((SECONDS - t0)) |")
        tail -n 30 "$LOG" | sed 's/^/    /'
        die "$name"
    fi
}

[ "$(id -u)" = 0 ] || { command -v sudo >/dev/null && exec sudo -E PI_ROOTFS="$ROOTFS" bash "$0" "$@"; \
    say "needs root (debootstrap, chroot, binfmt_misc) and there is no sudo"; exit 1; }

# -- the tools on the host ------------------------------------------------------------------------
if ! command -v debootstrap >/dev/null || [ ! -e /usr/bin/qemu-aarch64-static ] || ! command -v update-binfmts >/dev/null; then
    step "host tools (apt-get)" bash -c "apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y debootstrap qemu-user-static binfmt-support"
fi

# -- arm64 programs through qemu (binfmt_misc) ---------------------------------------------------
binfmt() {
    [ -e /proc/sys/fs/binfmt_misc/register ] || mount -t binfmt_misc binfmt_misc /proc/sys/fs/binfmt_misc
    [ -e /proc/sys/fs/binfmt_misc/qemu-aarch64 ] || update-binfmts --enable qemu-aarch64
    grep -q '^enabled' /proc/sys/fs/binfmt_misc/qemu-aarch64
}
step "binfmt_misc: qemu-aarch64" binfmt

# -- the root file system (once) -----------------------------------------------------------------
if [ ! -e "$ROOTFS/.lotsen-complete" ]; then
    rm -rf "$ROOTFS"; mkdir -p "$ROOTFS"
    step "debootstrap bookworm arm64 (once)" debootstrap --arch=arm64 \
        --include=python3,python3-venv,python3-dev,make,ca-certificates bookworm "$ROOTFS" "$MIRROR"
    touch "$ROOTFS/.lotsen-complete"
else
    STEPS+=("| debootstrap bookworm arm64 | cached (${ROOTFS/#$HOME/\~}) | 0 |")
fi

MOUNTS=()
cleanup() { for ((i=${#MOUNTS[@]}-1; i>=0; i--)); do umount -l "${MOUNTS[i]}" 2>/dev/null || true; done; }
trap cleanup EXIT
for m in proc sys dev dev/pts; do
    mountpoint -q "$ROOTFS/$m" || { mount --bind "/$m" "$ROOTFS/$m"; MOUNTS+=("$ROOTFS/$m"); }
done
cp -L /etc/resolv.conf "$ROOTFS/etc/resolv.conf"
# the host's own certificate authorities (a company or sandbox proxy) are trusted inside too
if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
    mkdir -p "$ROOTFS/usr/local/share/ca-certificates"
    cp /usr/local/share/ca-certificates/*.crt "$ROOTFS/usr/local/share/ca-certificates/"
    chroot "$ROOTFS" update-ca-certificates >>"$LOG" 2>&1
fi

in_pi() { chroot "$ROOTFS" /usr/bin/env -i HOME=/root PATH=/usr/local/bin:/usr/bin:/bin LANG=C.UTF-8 \
    PIP_CACHE_DIR=/var/cache/pip PIP_CERT=/etc/ssl/certs/ca-certificates.crt NUMBA_CACHE_DIR=/var/cache/numba MPLBACKEND=Agg bash -c "$*"; }

step "arch in the chroot is aarch64" in_pi '[ "$(uname -m)" = aarch64 ] && python3 -V'
PYV="$(in_pi 'python3 -V' 2>&1)"

# -- install as the README says (a fresh venv, pip install -e .) ----------------------------------
copy_checkout() {
    rm -rf "$ROOTFS/opt/lotsen" && mkdir -p "$ROOTFS/opt/lotsen"
    tar -C "$SRC" --exclude=./.venv --exclude=./.git --exclude='__pycache__' --exclude=.pytest_cache \
        --exclude=./bench/results -cf - . | tar -C "$ROOTFS/opt/lotsen" -xf -
}
step "copy the checkout" copy_checkout
step "make venv (pip install -e .)" in_pi 'cd /opt/lotsen && rm -rf .venv && make venv'
step "test tools (pytest, hypothesis pins)" in_pi "cd /opt/lotsen && .venv/bin/pip install -q \
    $(python3 - "$SRC/pyproject.toml" <<'PY'
import sys, tomllib
dev = tomllib.load(open(sys.argv[1], "rb"))["project"]["optional-dependencies"]["dev"]
print(" ".join(d for d in dev if d.split("==")[0] in ("pytest", "hypothesis")))
PY
)"

# -- run ------------------------------------------------------------------------------------------
step "lotsen check --emulated" in_pi 'cd /opt/lotsen && .venv/bin/lotsen check --emulated'
# the compiled kernels ahead of the run, into numba's disk cache, as an install would: compiling
# them under emulation takes minutes, longer than a process may take to start
step "compile the kernels (numba cache)" in_pi "cd /opt/lotsen && .venv/bin/python -c '
from lotsen.runtime.config import load_config
from lotsen.runtime.executor import SimExecutor
from lotsen.stack.launch import build_stack
build_stack(load_config(\"config/sim.yaml\"), realtime=True, parts=(\"state\", \"supervisor\"), executor=SimExecutor())'"
# the sim config, with the start-up allowance an emulated CPU needs
in_pi "cd /opt/lotsen && .venv/bin/python -c '
import yaml; d = yaml.safe_load(open(\"config/sim.yaml\")) or {}
d.setdefault(\"extra\", {}).setdefault(\"processes\", {})[\"ready_timeout_s\"] = 600
r = d.get(\"route\"); d[\"route\"] = \"/opt/lotsen/config/\" + r if isinstance(r, str) else r
d.setdefault(\"logging\", {})[\"directory\"] = \"/tmp/pi-run/logs\"
yaml.safe_dump(d, open(\"/tmp/pi-sim.yaml\", \"w\"))'" >>"$LOG" 2>&1
step "lotsen run --sim --duration $RUN_S (no browser)" in_pi "cd /tmp && rm -rf pi-run && mkdir pi-run && cd pi-run && \
    timeout $((RUN_S + 900)) /opt/lotsen/.venv/bin/lotsen run /tmp/pi-sim.yaml --sim --duration $RUN_S --port 18080"
step "no watchdog event in the run" bash -c "cp '$LOG' '$LOG.run' && [ \"\$(grep -c 'control loop silent' '$LOG.run')\" = 0 ]"
step "unit tests without a browser ($TESTS)" in_pi "cd /opt/lotsen && .venv/bin/python -m pytest -q -p no:cacheprovider \
    -m 'not browser and not live and not slow' $TESTS"

STEPS+=("| Python in the image | $PYV | |")
write_result pass
