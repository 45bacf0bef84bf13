#!/usr/bin/env bash
# Install what the project needs on a fresh Debian/Ubuntu machine, once:
# OS packages (only those missing), the virtualenv and the pinned Python packages.
#   scripts/bootstrap.sh [run|test]
set -euo pipefail
PROFILE=${1:-run}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"

log() { echo "[bootstrap] $*" >&2; }
SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"

need=()
have_cmd() { command -v "$1" >/dev/null 2>&1; }
ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || need+=(postgresql postgresql-contrib)
have_cmd psql || need+=(postgresql-client)
have_cmd redis-server || [ -x /usr/bin/redis-server ] || need+=(redis-server)
have_cmd mosquitto || [ -x /usr/sbin/mosquitto ] || need+=(mosquitto)
have_cmd mosquitto_passwd || need+=(mosquitto-clients)
have_cmd g++ || need+=(g++)
# RabbitMQ (MQTT plugin): the clusterable ground broker (`make run BROKER=rabbitmq`, the
# scale-out tests); Mosquitto stays the default.
[ -x /usr/lib/rabbitmq/bin/rabbitmq-server ] || need+=(rabbitmq-server)
have_cmd make || need+=(make)
python3.11 -c 'import venv, ensurepip' >/dev/null 2>&1 || python3 -c 'import sys, venv, ensurepip; assert sys.version_info[:2] == (3, 11)' >/dev/null 2>&1 || need+=(python3-venv python3-dev)
if [ "$PROFILE" = test ]; then
  have_cmd chromium || [ -x /usr/bin/chromium ] || need+=(chromium)
  # The arming-switch sketch is linked for the Nano's ATmega328P in the firmware tests.
  have_cmd avr-g++ || need+=(gcc-avr avr-libc binutils-avr)
  # The logbook PDF is read back by poppler, a reader independent of our writer.
  have_cmd pdftoppm || need+=(poppler-utils)
fi
if [ ${#need[@]} -gt 0 ]; then
  log "installing OS packages: ${need[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  # Debian starts the packaged services on install; we run our own instances instead.
  for svc in postgresql redis-server mosquitto rabbitmq-server; do
    $SUDO systemctl disable --now "$svc" >/dev/null 2>&1 || $SUDO service "$svc" stop >/dev/null 2>&1 || true
  done
fi

PY=$(command -v python3.11 || command -v python3)
if [ ! -x .venv/bin/python ]; then
  log "creating the virtualenv with $PY"
  "$PY" -m venv .venv
fi
stamp=.venv/.requirements.sha
want=$(cat requirements.lock pyproject.toml | sha256sum | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  log "installing Python packages (requirements.lock)"
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null
  .venv/bin/python -m pip install -q -r requirements.lock
  echo "$want" >"$stamp"
fi

# The onboard agent's wheelhouse: tests/onboard/test_package.py installs the agent into a
# fresh virtualenv from these files alone (--no-index), as on a drone without the repository.
wheels=.data/wheels/onboard
wstamp=$wheels/.sha
wwant=$(cat requirements.lock onboard/pyproject.toml | sha256sum | cut -d' ' -f1)
if [ "$PROFILE" = test ] && [ "$(cat "$wstamp" 2>/dev/null)" != "$wwant" ]; then
  log "downloading the onboard agent's wheels into $wheels"
  mkdir -p "$wheels"
  # The build backend (onboard/pyproject.toml [build-system]) and the agent's dependencies.
  .venv/bin/python -m pip download -q --only-binary=:all: -c requirements.lock -d "$wheels" \
    "setuptools>=77" "./onboard[mavlink]"
  rm -rf onboard/*.egg-info onboard/build
  echo "$wwant" >"$wstamp"
fi
