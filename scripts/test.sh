#!/usr/bin/env bash
# The whole suite against the test profile's own services (never the ones `make run` uses).
set -uo pipefail
STARTED_AT=$(date +%s)
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
PY=.venv/bin/python

# Parallel pytest workers (pytest-xdist). They share the test profile's PostgreSQL server,
# each in a test database of its own (pytest-django names it after the worker), and each
# has its own Redis and Mosquitto in .data/test-gw<K>, on the test ports plus 1+K: workers
# never share a database, a queue or a drone id. Most end-to-end tests wait on simulated
# drones rather than compute, so more workers than cores pays, even on 2 cores. The
# real-time tests (simulated flights against time bounds) would miss their bounds while
# other workers hold the CPU: they run in a pytest of their own on .data/test's services,
# beside the workers but at ten times their CPU weight (scripts/cpu_weights.sh), or
# afterwards, alone, where weights cannot be set. TEST_WORKERS=1 runs the whole suite
# serially on .data/test.
WORKERS=${TEST_WORKERS:-4}
REDIS_BASE=${TEST_REDIS_PORT:-63791}; MQTT_BASE=${TEST_MQTT_PORT:-18831}
workers=(); [ "$WORKERS" -gt 1 ] && for k in $(seq 0 $((WORKERS - 1))); do workers+=("$k"); done
worker_services() { # worker_services K ACTION...: scripts/services.sh ACTIONs for worker K
  local k=$1 dir="$ROOT/.data/test-gw$1" action; shift
  mkdir -p "$dir"
  # The one PostgreSQL server, and so one set of passwords, for every worker.
  ln -sfn ../test/postgres "$dir/postgres"; ln -sfn ../test/secrets "$dir/secrets"
  for action in "$@"; do
    DATA_DIR="$dir" TEST_REDIS_PORT=$((REDIS_BASE + 1 + k)) TEST_MQTT_PORT=$((MQTT_BASE + 1 + k)) \
      scripts/services.sh "$action" test >/dev/null || return 1
  done
}

# Stop at the end only what this run started: services that were up already (a
# developer's own `make test-services-up`) are left running.
# The real-time tests run on .data/test's own services, beside the workers'.
status=$(scripts/services.sh status test)
base_started=""; grep -q "down" <<<"$status" && base_started=yes
scripts/services.sh start test || exit 1
[ -n "$base_started" ] || echo "[test] reusing the running test services"
started=()
for k in "${workers[@]}"; do
  status=$(DATA_DIR="$ROOT/.data/test-gw$k" TEST_REDIS_PORT=$((REDIS_BASE + 1 + k)) \
    TEST_MQTT_PORT=$((MQTT_BASE + 1 + k)) scripts/services.sh status test)
  grep -Eq "(Redis|Mosquitto) down" <<<"$status" && started+=("$k")
done
pids=()
for k in "${workers[@]}"; do worker_services "$k" redis-start mosquitto-start env & pids+=($!); done
failed=""
for pid in "${pids[@]}"; do wait "$pid" || failed=yes; done
cleanup() {
  # The scale tests' RabbitMQ cluster stops itself; this catches an interrupted run.
  RABBIT_PORT_BASE=${RABBIT_PORT_BASE:-18900} scripts/rabbitmq.sh stop "${RABBIT_PROFILE:-test-rabbitmq}" 2>/dev/null || true
  for k in "${started[@]}"; do worker_services "$k" mosquitto-stop redis-stop & done
  wait
  [ -z "$weights" ] || scripts/cpu_weights.sh remove "$weights"
  [ -z "$base_started" ] || scripts/services.sh stop test
}
weights=""
trap cleanup EXIT
[ -z "$failed" ] || exit 1

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
# Each pytest session that starts makes the shared /tmp/pytest-of-<user> private again,
# which would lock the brokers the tests start (they run as the mosquitto user) out of
# their password files at their next reload; this checkout's own base folder is left alone.
BASETEMP=${TMPDIR:-/tmp}/skyhive-test-$(id -u)-$(printf %s "$ROOT" | md5sum | cut -c1-8)
# The slowest tests are listed at the end: where the suite's time goes.
pytest_run() { $PY -m pytest --durations=25 --basetemp "$BASETEMP" "$@"; }
own_marks=""
for arg in "$@"; do case "$arg" in -m*) own_marks=yes ;; esac; done
if [ ${#workers[@]} -eq 0 ]; then
  pytest_run "$@"
  rc=$?
elif [ -n "$own_marks" ]; then  # the caller chose the tests by marker: one parallel run
  pytest_run -n "$WORKERS" --dist loadgroup "$@"
  rc=$?
elif weights=$(scripts/cpu_weights.sh make); then
  # The real-time tests (marker `realtime`) in a pytest of their own, on .data/test's
  # services and database, beside everything else in parallel: their processes weigh ten
  # times the workers' on the CPU, so the workers take only what they leave idle. Their
  # report is printed once both are done.
  realtime_log=$BASETEMP-realtime.log
  echo "[test] real-time tests beside the others, at ten times their CPU weight ($realtime_log)"
  (scripts/cpu_weights.sh join "$weights" realtime && exec env -u PYTEST_XDIST_WORKER \
    $PY -m pytest --durations=25 --basetemp "$BASETEMP-realtime" -m realtime "$@" \
    >"$realtime_log" 2>&1) &
  realtime_pid=$!
  (scripts/cpu_weights.sh join "$weights" others && \
    exec $PY -m pytest --durations=25 --basetemp "$BASETEMP" -n "$WORKERS" --dist loadgroup -m "not realtime" "$@")
  rc_parallel=$?
  wait "$realtime_pid"
  rc_alone=$?
  echo "[test] real-time tests"
  cat "$realtime_log"
  rc=$(( rc_parallel == 5 ? rc_alone : rc_alone == 5 ? rc_parallel : rc_parallel | rc_alone ))
else
  # Where CPU weights cannot be set: everything else in parallel, then the real-time tests
  # in one worker (gw0's services) with the machine to themselves.
  pytest_run -n "$WORKERS" --dist loadgroup -m "not realtime" "$@"
  rc_parallel=$?
  echo "[test] real-time tests, alone"
  pytest_run -n 1 -m realtime "$@"
  rc_alone=$?
  # Exit 5 is "no test selected": fine for one part, not for both.
  rc=$(( rc_parallel == 5 ? rc_alone : rc_alone == 5 ? rc_parallel : rc_parallel | rc_alone ))
fi
echo "[test] the whole run took $(( $(date +%s) - STARTED_AT )) s"
# pytest exit 5 means no tests ran: that is a failure for us.
if [ $rc -eq 5 ]; then echo "[test] no tests ran"; exit 1; fi
exit $rc
