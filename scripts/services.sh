#!/usr/bin/env bash
# Start, stop and describe the project's own PostgreSQL, Redis and Mosquitto instances.
#
#   scripts/services.sh start|stop|status|env  run|test
#
# Mosquitto listens for the ground's processes on MQTT_PORT and for drones on
# MQTT_DRONE_PORT (default MQTT_PORT + 1000; TEST_MQTT_DRONE_PORT for `test`).
#
# BROKER=rabbitmq runs a RabbitMQ node with its MQTT plugin (scripts/rabbitmq.sh) on the
# MQTT port instead of Mosquitto, and writes its settings into the env file.
#
# Each profile keeps everything in .data/<profile>/ and listens on its own ports, so the
# test suite never collides with a running `make run`. Nothing here touches the system's
# own service instances.
set -euo pipefail

ACTION=${1:?usage: services.sh start|stop|status|env run|test}
PROFILE=${2:-run}
ROOT=$(cd "$(dirname "$0")/.." && pwd)
DATA=${DATA_DIR:-$ROOT/.data/$PROFILE}

if [ "$PROFILE" = test ]; then
  PG_PORT=${TEST_PG_PORT:-54331}; REDIS_PORT=${TEST_REDIS_PORT:-63791}; MQTT_PORT=${TEST_MQTT_PORT:-18831}
else
  PG_PORT=${PG_PORT:-54330}; REDIS_PORT=${REDIS_PORT:-63790}; MQTT_PORT=${MQTT_PORT:-1883}
fi
# Mosquitto's listener for drones (MQTT_PORT is the ground's own; see mosquitto_start).
if [ "$PROFILE" = test ]; then MQTT_DRONE_PORT=${TEST_MQTT_DRONE_PORT:-$((MQTT_PORT + 1000))}
else MQTT_DRONE_PORT=${MQTT_DRONE_PORT:-$((MQTT_PORT + 1000))}; fi

PG_BIN=$(ls -d /usr/lib/postgresql/*/bin 2>/dev/null | sort -V | tail -n 1)
[ -n "$PG_BIN" ] || PG_BIN=$(dirname "$(command -v initdb 2>/dev/null || echo /usr/bin/initdb)")
REDIS_SERVER=$(command -v redis-server || echo /usr/bin/redis-server)
REDIS_CLI=$(command -v redis-cli || echo /usr/bin/redis-cli)
MOSQUITTO=$(command -v mosquitto || echo /usr/sbin/mosquitto)
MOSQUITTO_PASSWD=$(command -v mosquitto_passwd || echo /usr/bin/mosquitto_passwd)

BROKER=${BROKER:-mosquitto}
case "$BROKER" in mosquitto|rabbitmq) ;; *) echo "BROKER must be mosquitto or rabbitmq, not $BROKER" >&2; exit 2 ;; esac
RABBITMQ_SH="$ROOT/scripts/rabbitmq.sh"

log() { echo "[services:$PROFILE] $*" >&2; }

# PostgreSQL refuses to run as root: run its tools as the postgres user then.
as_pg() {
  if [ "$(id -u)" = 0 ]; then runuser -u postgres -- "$@"; else "$@"; fi
}

secret() { # secret NAME: a random value generated once and kept in the data directory
  local file="$DATA/secrets/$1" draft
  if [ ! -s "$file" ]; then
    mkdir -p "$DATA/secrets"; chmod 700 "$DATA/secrets"
    draft=$(mktemp "$DATA/secrets/.$1.XXXXXX")
    head -c 24 /dev/urandom | base64 | tr -dc 'A-Za-z0-9' | head -c 32 >"$draft"
    # A hard link is made only if the name is free: when several starts race (parallel
    # test workers share one secrets folder) the first value is the one every one reads.
    ln "$draft" "$file" 2>/dev/null || true
    rm -f "$draft"
  fi
  cat "$file"
}

wait_port() { # wait_port PORT NAME
  for _ in $(seq 1 100); do
    if (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; then return 0; fi
    sleep 0.1
  done
  log "$2 did not start on port $1"; return 1
}

port_open() { (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }

pg_start() {
  local dir="$DATA/postgres"
  mkdir -p "$DATA"
  if [ ! -s "$dir/PG_VERSION" ]; then
    log "initialising PostgreSQL in $dir"
    mkdir -p "$dir"
    [ "$(id -u)" = 0 ] && chown postgres:postgres "$dir"
    chmod 700 "$dir"
    # mktemp makes it 0600; as root, initdb runs as postgres, which gets the file rather
    # than everyone getting to read it.
    local pwfile; pwfile=$(mktemp); secret pg_password >"$pwfile"
    [ "$(id -u)" = 0 ] && chown postgres "$pwfile"
    as_pg "$PG_BIN/initdb" -D "$dir" -U postgres --pwfile="$pwfile" -A scram-sha-256 \
      --auth-local=peer -E UTF8 --locale=C.UTF-8 >/dev/null
    rm -f "$pwfile"
    {
      echo "listen_addresses = '127.0.0.1'"
      echo "unix_socket_directories = '$dir'"
      echo "max_connections = 200"
      echo "shared_buffers = 256MB"
      if [ "$PROFILE" = test ]; then
        # A throw-away test cluster: durability buys nothing and costs a lot of time.
        echo "fsync = off"; echo "synchronous_commit = off"; echo "full_page_writes = off"
      fi
    } | as_pg tee -a "$dir/postgresql.conf" >/dev/null
    # peer auth for the local superuser when we run as root via runuser
    echo "local all postgres peer map=root_as_postgres" | as_pg tee "$dir/pg_hba.local" >/dev/null
    cat "$dir/pg_hba.local" "$dir/pg_hba.conf" | as_pg tee "$dir/pg_hba.new" >/dev/null
    as_pg mv "$dir/pg_hba.new" "$dir/pg_hba.conf"
    printf 'root_as_postgres root postgres\nroot_as_postgres postgres postgres\nroot_as_postgres %s postgres\n' "$(id -un)" \
      | as_pg tee "$dir/pg_ident.conf" >/dev/null
  fi
  if port_open "$PG_PORT"; then log "PostgreSQL already up on $PG_PORT"; return 0; fi
  log "starting PostgreSQL on 127.0.0.1:$PG_PORT"
  # The port is in the kernel's ephemeral range: an outgoing connection may hold it for a
  # moment (many test processes start at once), so a failed bind is tried again.
  local try
  for try in 1 2 3; do
    as_pg "$PG_BIN/pg_ctl" -D "$dir" -l "$dir/server.log" -o "-p $PG_PORT" -w -t 60 start >/dev/null && break
    [ "$try" = 3 ] && return 1
    log "PostgreSQL did not start on $PG_PORT; trying again"; sleep 1
  done
  touch "$DATA/.started.postgres"
  local pw; pw=$(secret pg_password)
  local appw; appw=$(secret db_password)
  # The application role and database; idempotent.
  as_pg psql -h "$dir" -p "$PG_PORT" -U postgres -d postgres -qAt -v ON_ERROR_STOP=1 <<SQL >/dev/null
DO \$\$BEGIN
  IF NOT EXISTS (SELECT FROM pg_roles WHERE rolname = 'skyhive') THEN
    CREATE ROLE skyhive LOGIN CREATEDB PASSWORD '$appw';
  ELSE
    ALTER ROLE skyhive PASSWORD '$appw';
  END IF;
END\$\$;
SQL
  if ! as_pg psql -h "$dir" -p "$PG_PORT" -U postgres -d postgres -qAt -c "SELECT 1 FROM pg_database WHERE datname='skyhive'" | grep -q 1; then
    as_pg psql -h "$dir" -p "$PG_PORT" -U postgres -d postgres -q -c "CREATE DATABASE skyhive OWNER skyhive" >/dev/null
  fi
  : "$pw"
}

pg_stop() {
  local dir="$DATA/postgres"
  [ -s "$dir/postmaster.pid" ] || return 0
  log "stopping PostgreSQL"
  as_pg "$PG_BIN/pg_ctl" -D "$dir" -m fast -w stop >/dev/null || true
}

redis_start() {
  local dir="$DATA/redis"; mkdir -p "$dir"
  if port_open "$REDIS_PORT"; then log "Redis already up on $REDIS_PORT"; return 0; fi
  log "starting Redis on 127.0.0.1:$REDIS_PORT"
  # The append-only file keeps the outbox and the counters across a crash (at most a
  # second lost); the test profile keeps nothing.
  local persist=(--save "60 1000" --appendonly yes --appendfsync everysec)
  [ "$PROFILE" = test ] && persist=(--save "" --appendonly no)
  "$REDIS_SERVER" --bind 127.0.0.1 --port "$REDIS_PORT" --dir "$dir" --daemonize yes \
    --pidfile "$dir/redis.pid" --logfile "$dir/redis.log" --requirepass "$(secret redis_password)" \
    "${persist[@]}" >/dev/null
  wait_port "$REDIS_PORT" Redis
}

redis_stop() {
  local dir="$DATA/redis"
  [ -s "$dir/redis.pid" ] || return 0
  log "stopping Redis"
  kill "$(cat "$dir/redis.pid")" 2>/dev/null || true
  for _ in $(seq 1 50); do port_open "$REDIS_PORT" || break; sleep 0.1; done
  rm -f "$dir/redis.pid"
}

# Mosquitto started as root drops to this user (Debian's `mosquitto`, else `nobody`).
mosquitto_user() { if id -u mosquitto >/dev/null 2>&1; then echo mosquitto; else echo nobody; fi; }

# An optional TLS listener: MQTT_TLS_PORT with MQTT_TLS_CERT and MQTT_TLS_KEY (PEM files),
# on MQTT_TLS_BIND (every interface for `run`, loopback for `test`). The plain listener
# stays on 127.0.0.1 for the ground's own processes.
mosquitto_tls_config() {
  local dir=$1
  [ -n "${MQTT_TLS_PORT:-}" ] || return 0
  if [ ! -r "${MQTT_TLS_CERT:-}" ] || [ ! -r "${MQTT_TLS_KEY:-}" ]; then
    log "MQTT_TLS_PORT needs MQTT_TLS_CERT and MQTT_TLS_KEY (readable PEM files)"; return 1
  fi
  # Copies the broker's user may read, whoever owns the originals.
  mkdir -p "$dir/tls"
  (umask 077; cp "$MQTT_TLS_CERT" "$dir/tls/cert.pem"; cp "$MQTT_TLS_KEY" "$dir/tls/key.pem")
  chmod 640 "$dir/tls/cert.pem" "$dir/tls/key.pem"
  local bind=${MQTT_TLS_BIND:-$([ "$PROFILE" = test ] && echo 127.0.0.1 || echo 0.0.0.0)}
  printf 'listener %s %s\ncertfile %s\nkeyfile %s\ntls_version tlsv1.2\n' \
    "$MQTT_TLS_PORT" "$bind" "$dir/tls/cert.pem" "$dir/tls/key.pem"
  mosquitto_drone_security "$dir"
}

# A drones' listener: drone accounts, and the broker takes the username as the client id,
# so no drone can pick another client's id (see mosquitto_start).
mosquitto_drone_security() {
  printf 'allow_anonymous false\npassword_file %s/passwd\nacl_file %s/acl\nuse_username_as_clientid true\n' "$1" "$1"
}

# Root: the broker's files belong to its user, and files rewritten later (passwd and acl,
# by provisioning, as root) stay readable by its group (setgid directory, mode 0640).
mosquitto_own_files() {
  local dir=$1 user; user=$(mosquitto_user)
  [ "$(id -u)" = 0 ] || return 0
  chown -R "$user:$(id -gn "$user")" "$dir"
  # It must reach the directory: folders above it that it may not enter (/root is 0700)
  # get the execute bit for others only, so nothing in them can be listed.
  local parent; parent=$(cd "$dir" && pwd -P)
  while [ "$parent" != / ]; do
    parent=$(dirname "$parent")
    if ! runuser -u "$user" -- test -x "$parent"; then
      log "letting $user pass through $parent (chmod o+x) to reach $dir"
      chmod o+x "$parent"
    fi
  done
  chmod 2770 "$dir"
  chmod 640 "$dir/passwd" "$dir/acl" "$dir/ground.passwd"
}

# Sessions belong to their account. Mosquitto 2.0 lets any client that connects with a
# client id in use disconnect its holder and, with a clean session, wipe that session and
# its queued QoS 1 messages. So the ground's processes (MQTT_URL) have a loopback listener
# of their own on MQTT_PORT that knows only the service users (ground.passwd), and drones
# connect to MQTT_DRONE_PORT (and the TLS listener), where the broker replaces the client
# id with the username (`use_username_as_clientid`): a drone's session is named after the
# drone, whatever id it asks for. Drone ids that look like a ground client's id are
# refused at provisioning (workers.broker.credentials.GROUND_CLIENT_ID_PREFIXES).
mosquitto_start() {
  local dir="$DATA/mosquitto"; mkdir -p "$dir"
  # Passwords and ACLs are never readable by others, not even for a moment (umask); the
  # ground's own credentials go in here, drone entries are added by `manage.py
  # provision_drone`, which regenerates these files from the database and sends SIGHUP.
  (
    umask 077
    [ -f "$dir/passwd" ] || : >"$dir/passwd"
    if ! grep -q '^ground:' "$dir/passwd"; then
      "$MOSQUITTO_PASSWD" -b "$dir/passwd" ground "$(secret mqtt_ground_password)"
    fi
    # The ground's listener: the service users' lines only (MQTT_SERVICE_USERS, as the
    # settings read it; provisioning keeps this file in step afterwards).
    local users; users=$(echo "${MQTT_SERVICE_USERS:-ground}" | tr -d ' ' | tr ',' '|')
    grep -E "^(ground|$users):" "$dir/passwd" >"$dir/ground.passwd.new"
    mv "$dir/ground.passwd.new" "$dir/ground.passwd"
    [ -f "$dir/acl" ] || printf 'user ground\ntopic readwrite #\ntopic read $SYS/#\n\npattern write %%u/+/out\npattern read %%u/+/in\n' >"$dir/acl"
  )
  cat >"$dir/mosquitto.conf" <<CONF
# Generated by scripts/services.sh; edits are overwritten.
per_listener_settings true
# The ground's processes: service users only.
listener $MQTT_PORT 127.0.0.1
allow_anonymous false
password_file $dir/ground.passwd
acl_file $dir/acl
# Drones: the username is the client id.
listener $MQTT_DRONE_PORT ${MQTT_DRONE_BIND:-127.0.0.1}
$(mosquitto_drone_security "$dir")
set_tcp_nodelay true
pid_file $dir/mosquitto.pid
persistence $([ "$PROFILE" = test ] && echo false || echo true)
persistence_location $dir/
log_dest file $dir/mosquitto.log
log_type error
log_type warning
log_type notice
max_queued_messages 100000
# No payload the gateway would keep is larger (pictures, workers/dispatch.py): bigger
# ones are not forwarded at all (workers/mosquitto.py MESSAGE_SIZE_LIMIT).
message_size_limit 16777216
# Sessions of clients gone for good (a retired gateway instance) stop queueing.
persistent_client_expiration 1d
# Started as root, it runs as an unprivileged user once its ports are open.
user $(mosquitto_user)
CONF
  mosquitto_tls_config "$dir" >>"$dir/mosquitto.conf"
  mosquitto_own_files "$dir"
  if port_open "$MQTT_PORT"; then
    # Listeners are not reloaded on SIGHUP: a broker started before the drones' listener
    # existed is restarted once to take it.
    if port_open "$MQTT_DRONE_PORT"; then log "Mosquitto already up on $MQTT_PORT"; return 0; fi
    log "restarting Mosquitto for its drones' listener on $MQTT_DRONE_PORT"; mosquitto_stop
  fi
  log "starting Mosquitto on 127.0.0.1:$MQTT_PORT (ground) and $MQTT_DRONE_PORT (drones)"
  "$MOSQUITTO" -c "$dir/mosquitto.conf" -d
  wait_port "$MQTT_PORT" Mosquitto && wait_port "$MQTT_DRONE_PORT" "Mosquitto (drones)"
}

mosquitto_stop() {
  local dir="$DATA/mosquitto"
  [ -s "$dir/mosquitto.pid" ] || return 0
  log "stopping Mosquitto"
  kill "$(cat "$dir/mosquitto.pid")" 2>/dev/null || true
  for _ in $(seq 1 50); do port_open "$MQTT_PORT" || break; sleep 0.1; done
  rm -f "$dir/mosquitto.pid"
}

write_env() {
  mkdir -p "$DATA"
  local envfile="$DATA/env"
  cat >"$envfile" <<ENV
DATA_DIR=$DATA
DATABASE_URL=postgresql://skyhive:$(secret db_password)@127.0.0.1:$PG_PORT/skyhive
REDIS_URL=redis://:$(secret redis_password)@127.0.0.1:$REDIS_PORT/0
$(if [ "$BROKER" = rabbitmq ]; then DATA_DIR="$DATA" MQTT_PORT=$MQTT_PORT "$RABBITMQ_SH" env "$PROFILE" 1; else
  echo "MQTT_BROKER=mosquitto"; echo "MQTT_URL=mqtt://ground:$(secret mqtt_ground_password)@127.0.0.1:$MQTT_PORT"
  echo "MQTT_DRONE_PORT=$MQTT_DRONE_PORT"; echo "MQTT_PUBLIC_PORT=${MQTT_PUBLIC_PORT:-$MQTT_DRONE_PORT}"; fi)
MOSQUITTO_DIR=$DATA/mosquitto
SECRET_KEY=$(secret django_secret_key)$(secret django_secret_key_2)
LIVE_VIDEO_TICKET_KEY=$(secret live_video_ticket_key)
PG_ADMIN_SOCKET=$DATA/postgres
PG_PORT=$PG_PORT
REDIS_PORT=$REDIS_PORT
MQTT_PORT=$MQTT_PORT
ENV
  chmod 600 "$envfile"
  echo "$envfile"
}

broker_start() {
  if [ "$BROKER" = rabbitmq ]; then
    mosquitto_stop  # ours, if a previous run used it: the MQTT port is RabbitMQ's now
    DATA_DIR="$DATA" MQTT_PORT=$MQTT_PORT "$RABBITMQ_SH" start "$PROFILE" 1
  else
    DATA_DIR="$DATA" MQTT_PORT=$MQTT_PORT "$RABBITMQ_SH" stop "$PROFILE" 2>/dev/null || true
    mosquitto_start
  fi
}

broker_stop() {
  mosquitto_stop
  if [ -d "$DATA/rabbitmq" ]; then DATA_DIR="$DATA" MQTT_PORT=$MQTT_PORT "$RABBITMQ_SH" stop "$PROFILE" || true; fi
}

case "$ACTION" in
  start) pg_start; redis_start; broker_start; write_env >/dev/null ;;
  stop) broker_stop; redis_stop; pg_stop ;;
  env) write_env ;;
  status)
    broker_name=Mosquitto; [ "$BROKER" = rabbitmq ] && broker_name=RabbitMQ
    ports=("$PG_PORT:PostgreSQL" "$REDIS_PORT:Redis" "$MQTT_PORT:$broker_name")
    [ "$BROKER" = mosquitto ] && ports+=("$MQTT_DRONE_PORT:Mosquitto (drones)")
    for p in "${ports[@]}"; do
      if port_open "${p%%:*}"; then echo "${p#*:} up on ${p%%:*}"; else echo "${p#*:} down (${p%%:*})"; fi
    done ;;
  pg-start) pg_start ;; pg-stop) pg_stop ;;
  redis-start) redis_start ;; redis-stop) redis_stop ;;
  mosquitto-start) mosquitto_start ;; mosquitto-stop) mosquitto_stop ;;
  *) echo "unknown action $ACTION" >&2; exit 2 ;;
esac
