#!/usr/bin/env bash
# Install lotsen on a Raspberry Pi 4 (Raspberry Pi OS bookworm 64-bit; notes for Ubuntu in
# docs/drivers.md). Run as root from a checkout: sudo bash deploy/install-pi.sh
# It does not edit the boot config: enabling the UARTs and I2C is a deliberate step (docs/drivers.md).
set -euo pipefail
SRC="$(cd "$(dirname "$0")/.." && pwd)"
PREFIX=/opt/lotsen

python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))' || {
    echo "lotsen needs Python >= 3.11 (Raspberry Pi OS bookworm, Ubuntu 24.04); this is $(python3 -V)" >&2; exit 1; }
[ "$(uname -m)" = aarch64 ] || [ "$(uname -m)" = x86_64 ] || {
    echo "lotsen needs a 64-bit OS (aarch64 wheels); this is $(uname -m)" >&2; exit 1; }

apt-get update
apt-get install -y python3-venv python3-dev i2c-tools pigpio

id lotsen >/dev/null 2>&1 || useradd --system --create-home --home-dir /var/lib/lotsen --shell /usr/sbin/nologin lotsen
usermod -aG dialout,i2c,gpio lotsen

mkdir -p "$PREFIX" /etc/lotsen
rsync -a --delete --exclude .venv --exclude .git "$SRC/" "$PREFIX/"
python3 -m venv "$PREFIX/.venv"
"$PREFIX/.venv/bin/pip" install --upgrade pip
"$PREFIX/.venv/bin/pip" install "$PREFIX"          # the on-board extras only (no casadi/playwright)
[ -f /etc/lotsen/hardware.yaml ] || cp "$SRC/deploy/hardware.yaml" /etc/lotsen/hardware.yaml

# pigpiod: localhost only (-l); its default listens on every interface
mkdir -p /etc/systemd/system/pigpiod.service.d
cat > /etc/systemd/system/pigpiod.service.d/local.conf <<'CONF'
[Service]
ExecStart=
ExecStart=/usr/bin/pigpiod -l
CONF
cp "$SRC/deploy/lotsen.service" /etc/systemd/system/lotsen.service
systemctl daemon-reload
systemctl enable --now pigpiod
systemctl enable lotsen
echo "installed. Check: sudo -u lotsen $PREFIX/.venv/bin/python -m lotsen check /etc/lotsen/hardware.yaml"
echo "then: sudo systemctl start lotsen && journalctl -u lotsen -f"
