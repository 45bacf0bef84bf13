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
# other workers hold the CPU: they run after the workers, two at a time, then the tests
# marked `alone`. With TEST_REALTIME_BESIDE=1 they run beside the workers in a pytest of their
# own, with services of their own (.data/test-realtime, on the test ports plus 9), all of
# it at ten times the workers' CPU weight (scripts/cpu_weights.sh), where weights can be
# set, and the `alone` tests last; about a fifth faster, but the workers' timing-sensitive
# tests then meet stalls they do not meet otherwise (docs/performance.md).
# TEST_WORKERS=1 runs the whole suite serially on .data/test.
WORKERS=${TEST_WORKERS:-4}
# The real-time tests wait on simulated flights more than they compute (a third of the two
# cores, one at a time), but two at a time, a core each, they failed twice in eleven runs
# (a decision that came after the flight it was about): one by default
# (TEST_REALTIME_WORKERS=2 for the faster schedule; docs/performance.md).
REALTIME_WORKERS=${TEST_REALTIME_WORKERS:-1}; [ "$REALTIME_WORKERS" -le "$WORKERS" ] || REALTIME_WORKERS=$WORKERS
PG_BASE=${TEST_PG_PORT:-54331}; REDIS_BASE=${TEST_REDIS_PORT:-63791}; MQTT_BASE=${TEST_MQTT_PORT:-18831}
REALTIME_OFFSET=9
workers=(); [ "$WORKERS" -gt 1 ] && for k in $(seq 0 $((WORKERS - 1))); do workers+=("$k"); done
own_marks=""
for arg in "$@"; do case "$arg" in -m*) own_marks=yes ;; esac; done
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
realtime_services() { # realtime_services ACTION: scripts/services.sh ACTION for the real-time run
  DATA_DIR="$ROOT/.data/test-realtime" TEST_PG_PORT=$((PG_BASE + REALTIME_OFFSET)) \
    TEST_REDIS_PORT=$((REDIS_BASE + REALTIME_OFFSET)) TEST_MQTT_PORT=$((MQTT_BASE + REALTIME_OFFSET)) \
    scripts/services.sh "$1" test >/dev/null
}

# Stop at the end only what this run started: services that were up already (a
# developer's own `make test-services-up`) are left running.
status=$(scripts/services.sh status test)
if [ ${#workers[@]} -eq 0 ]; then
  base_started=""; grep -q "down" <<<"$status" && base_started=yes
  scripts/services.sh start test || exit 1
else
  base_started=""; grep -q "PostgreSQL down" <<<"$status" && base_started=yes
  scripts/services.sh pg-start test || exit 1
fi
[ -n "$base_started" ] || echo "[test] reusing the running test services"
started=()
for k in "${workers[@]}"; do
  status=$(DATA_DIR="$ROOT/.data/test-gw$k" TEST_REDIS_PORT=$((REDIS_BASE + 1 + k)) \
    TEST_MQTT_PORT=$((MQTT_BASE + 1 + k)) scripts/services.sh status test)
  grep -Eq "(Redis|Mosquitto) down" <<<"$status" && started+=("$k")
done
pids=()
for k in "${workers[@]}"; do worker_services "$k" redis-start mosquitto-start env & pids+=($!); done
# The real-time run's services start in its group, so they share its CPU weight.
weights=""
if [ "${TEST_REALTIME_BESIDE:-}" = 1 ] && [ ${#workers[@]} -gt 0 ] && [ -z "$own_marks" ] \
  && weights=$(scripts/cpu_weights.sh make $$); then
  (scripts/cpu_weights.sh join "$weights" realtime && realtime_services start) & pids+=($!)
fi
failed=""
for pid in "${pids[@]}"; do wait "$pid" || failed=yes; done
cleanup() {
  # The scale tests' RabbitMQ cluster stops itself; this catches an interrupted run.
  RABBIT_PORT_BASE=${RABBIT_PORT_BASE:-18900} scripts/rabbitmq.sh stop "${RABBIT_PROFILE:-test-rabbitmq}" 2>/dev/null || true
  for k in "${started[@]}"; do worker_services "$k" mosquitto-stop redis-stop & done
  [ -z "$weights" ] || realtime_services stop &
  wait
  [ -z "$weights" ] || scripts/cpu_weights.sh remove "$weights"
  if [ -n "$base_started" ]; then
    if [ ${#workers[@]} -eq 0 ]; then scripts/services.sh stop test; else scripts/services.sh pg-stop test; fi
  fi
}
trap cleanup EXIT
[ -z "$failed" ] || exit 1

set -e
export DJANGO_SETTINGS_MODULE=config.settings.test
echo "[test] ruff"
$PY -m ruff check .
echo "[test] migrations are up to date"
# Against the first worker's database when the serial profile's services are not started.
first_profile=(); [ ${#workers[@]} -gt 0 ] && first_profile=(env PYTEST_XDIST_WORKER=gw0)
"${first_profile[@]}" $PY manage.py makemigrations --check --dry-run >/dev/null
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
# Exit 5 is "no test selected": fine for one of two parts, not for both.
either() { echo $(( $1 == 5 ? $2 : $2 == 5 ? $1 : $1 | $2 )); }
if [ ${#workers[@]} -eq 0 ]; then
  pytest_run "$@"
  rc=$?
elif [ -n "$own_marks" ]; then  # the caller chose the tests by marker: one parallel run
  pytest_run -n "$WORKERS" --dist loadgroup "$@"
  rc=$?
elif [ -n "$weights" ]; then
  # The real-time tests (marker `realtime`) in their group, on their services (the test
  # settings read .data/test-<name>/env for the worker PYTEST_XDIST_WORKER names), beside
  # everything else in parallel in the other group. Their report follows the workers'.
  realtime_log=$BASETEMP-realtime.log
  echo "[test] the real-time tests run beside the others, at ten times their CPU weight"
  # A base folder of its own (pytest takes the last --basetemp given).
  (scripts/cpu_weights.sh join "$weights" realtime && PYTEST_XDIST_WORKER=realtime \
    pytest_run --basetemp "$BASETEMP-realtime" -m realtime "$@" >"$realtime_log" 2>&1) &
  realtime_pid=$!
  (scripts/cpu_weights.sh join "$weights" others && \
    pytest_run -n "$WORKERS" --dist loadgroup -m "not realtime and not alone" "$@")
  rc_parallel=$?
  wait "$realtime_pid"
  rc_realtime=$?
  echo "[test] the real-time tests"
  cat "$realtime_log"
  # What needs the machine to itself, in one worker (gw0's services), once both are done.
  echo "[test] the tests that run alone"
  pytest_run -n 1 -m alone "$@"
  rc=$(either "$(either $rc_parallel $rc_realtime)" $?)
else
  # Everything else in parallel; then the real-time tests with the machine to themselves,
  # REALTIME_WORKERS at a time (gw0's and gw1's services: a core each); then those that
  # run alone, in one worker.
  pytest_run -n "$WORKERS" --dist loadgroup -m "not realtime and not alone" "$@"
  rc_parallel=$?
  echo "[test] real-time tests, $REALTIME_WORKERS at a time"
  TEST_REALTIME_SPREAD=1 pytest_run -n "$REALTIME_WORKERS" --dist loadgroup -m realtime "$@"
  rc_realtime=$?
  echo "[test] the tests that run alone"
  pytest_run -n 1 -m alone "$@"
  rc=$(either "$(either $rc_parallel $rc_realtime)" $?)
fi
echo "[test] the whole run took $(( $(date +%s) - STARTED_AT )) s"
# pytest exit 5 means no tests ran: that is a failure for us.
if [ $rc -eq 5 ]; then echo "[test] no tests ran"; exit 1; fi
exit $rc
