#!/usr/bin/env bash
# The whole suite against the test profile's own services (never the ones `make run` uses).
set -uo pipefail
STARTED_AT=$(date +%s)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
PY=.venv/bin/python

# Stop at the end only what this run started: when every service was already up (a
# developer's own `make test-services-up`), leave them running.
started=""
status=$(scripts/services.sh status test)
if grep -q "down" <<<"$status"; then started=yes; else echo "[test] reusing the running test services"; fi
scripts/services.sh start test || exit 1
cleanup() {
  # The scale tests' RabbitMQ cluster stops itself; this catches an interrupted run.
  RABBIT_PORT_BASE=${RABBIT_PORT_BASE:-18900} scripts/rabbitmq.sh stop "${RABBIT_PROFILE:-test-rabbitmq}" 2>/dev/null || true
  [ -n "$started" ] && scripts/services.sh stop test
}
trap cleanup EXIT

set -e
export DJANGO_SETTINGS_MODULE=config.settings.test
echo "[test] ruff"
$PY -m ruff check .
echo "[test] migrations are up to date"
$PY manage.py makemigrations --check --dry-run >/dev/null
if [ -f firmware/arming_switch/Makefile ]; then
  echo "[test] arming-switch firmware host tests"
  make -s --no-print-directory -C firmware/arming_switch test
fi
set +e
echo "[test] pytest"
# The slowest tests are listed at the end: where the suite's time goes.
$PY -m pytest --durations=25 "$@"
rc=$?
echo "[test] the whole run took $(( $(date +%s) - STARTED_AT )) s"
# pytest exit 5 means no tests ran: that is a failure for us.
if [ $rc -eq 5 ]; then echo "[test] no tests ran"; exit 1; fi
exit $rc
