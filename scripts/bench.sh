#!/usr/bin/env bash
# Run every benchmark module; each writes its keys into bench/results.json.
set -uo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
started=""
status=$(scripts/services.sh status test)
if grep -q down <<<"$status"; then started=yes; fi
scripts/services.sh start test || exit 1
trap '[ -n "$started" ] && scripts/services.sh stop test' EXIT
export DJANGO_SETTINGS_MODULE=config.settings.test
export DB_POOL=true  # measure the production database configuration
status=0
for module in bench/bench_*.py; do
  name=$(basename "$module" .py)
  echo "== $name"
  timeout 900 .venv/bin/python -m "bench.$name" || { echo "$name failed"; status=1; }
done
exit $status
