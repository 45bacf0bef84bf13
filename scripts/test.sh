#!/usr/bin/env bash
# The whole suite against the test profile's own services (never the ones `make run` uses).
set -uo pipefail
STARTED_AT=$(date +%s)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
PY=.venv/bin/python

# Parallel pytest workers (pytest-xdist), each with its own PostgreSQL, Redis and Mosquitto
# in .data/test-gw<K>, on the test ports plus 1+K: workers never share a database, a queue
# or a drone id. Most end-to-end tests wait on simulated drones rather than compute, so
# more workers than cores pays. TEST_WORKERS=1 runs serially on .data/test.
WORKERS=${TEST_WORKERS:-$(( $(nproc) * 2 < 4 ? $(nproc) * 2 : 4 ))}
PG_BASE=${TEST_PG_PORT:-54331}; REDIS_BASE=${TEST_REDIS_PORT:-63791}; MQTT_BASE=${TEST_MQTT_PORT:-18831}
profiles=()
if [ "$WORKERS" -gt 1 ]; then
  for k in $(seq 0 $((WORKERS - 1))); do profiles+=("$k"); done
else
  profiles=(serial)
fi
in_profile() { # in_profile K|serial COMMAND...: COMMAND with worker K's service settings
  local k=$1; shift
  if [ "$k" = serial ]; then "$@"; return; fi
  DATA_DIR="$ROOT/.data/test-gw$k" TEST_PG_PORT=$((PG_BASE + 1 + k)) \
    TEST_REDIS_PORT=$((REDIS_BASE + 1 + k)) TEST_MQTT_PORT=$((MQTT_BASE + 1 + k)) "$@"
}

# Stop at the end only what this run started: when a profile's services were all up
# already (a developer's own `make test-services-up`), leave them running.
started=()
for k in "${profiles[@]}"; do
  status=$(in_profile "$k" scripts/services.sh status test)
  if grep -q "down" <<<"$status"; then started+=("$k")
  else echo "[test] reusing the running test services ($k)"; fi
done
pids=()
for k in "${profiles[@]}"; do in_profile "$k" scripts/services.sh start test & pids+=($!); done
failed=""
for pid in "${pids[@]}"; do wait "$pid" || failed=yes; done
cleanup() {
  # The scale tests' RabbitMQ cluster stops itself; this catches an interrupted run.
  RABBIT_PORT_BASE=${RABBIT_PORT_BASE:-18900} scripts/rabbitmq.sh stop "${RABBIT_PROFILE:-test-rabbitmq}" 2>/dev/null || true
  for k in "${started[@]}"; do in_profile "$k" scripts/services.sh stop test & done
  wait
}
trap cleanup EXIT
[ -z "$failed" ] || exit 1

set -e
export DJANGO_SETTINGS_MODULE=config.settings.test
echo "[test] ruff"
$PY -m ruff check .
echo "[test] migrations are up to date"
# Against the first worker's database when the serial profile's services are not started.
first_profile=(); [ "$WORKERS" -gt 1 ] && first_profile=(env PYTEST_XDIST_WORKER=gw0)
"${first_profile[@]}" $PY manage.py makemigrations --check --dry-run >/dev/null
if [ -f firmware/arming_switch/Makefile ]; then
  echo "[test] arming-switch firmware host tests"
  make -s --no-print-directory -C firmware/arming_switch test
fi
set +e
echo "[test] pytest"
# The slowest tests are listed at the end: where the suite's time goes.
xdist=(); [ "$WORKERS" -gt 1 ] && xdist=(-n "$WORKERS" --dist loadgroup)
$PY -m pytest --durations=25 "${xdist[@]}" "$@"
rc=$?
echo "[test] the whole run took $(( $(date +%s) - STARTED_AT )) s"
# pytest exit 5 means no tests ran: that is a failure for us.
if [ $rc -eq 5 ]; then echo "[test] no tests ran"; exit 1; fi
exit $rc
