"""The broker side of per-drone credentials: users, passwords and ACLs on the broker.

Works on plain data: drone ids and the hashes stored for them (fleet.credentials keeps the
drones, chooses the passwords and stores the hashes). The backend is chosen by
settings.MQTT_BROKER:

- Mosquitto (one node): the password and ACL files are regenerated from the live drones
  and Mosquitto gets SIGHUP; it re-reads both and disconnects clients whose credentials are
  gone (checked with Mosquitto 2.0.11), so a revoked drone is cut off at once.
- RabbitMQ (MQTT plugin, clustered): one user per drone through the management API
  (workers.broker.rabbitmq_admin), with vhost permissions limited to the drone's own MQTT
  session queues and `amq.topic`, and topic permissions on `amq.topic` equivalent to
  Mosquitto's ACL (RabbitMQ maps MQTT's `/` to `.` in routing keys). The user has no
  password of its own: its hash is a global parameter that the nodes' auth service
  (workers.broker.rabbitmq_auth) checks, with the client id. Revocation deletes the
  user and that parameter, closes its open connections and drops its session queues.

A stored hash holds Mosquitto's `$7$` hash (PBKDF2-SHA512, as `mosquitto_passwd` writes it)
followed, after a space, by RabbitMQ's own salted SHA-256 hash: the two formats cannot be
derived from each other, and keeping both lets either broker be rebuilt from the stored
hashes (`sync`) when a node or a whole cluster is replaced, without re-issuing any password.
"""

from __future__ import annotations

import base64
import fcntl
import hashlib
import logging
import os
import re
import secrets
import signal
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol
from urllib.parse import urlsplit

from django.conf import settings

from .rabbitmq_admin import (
    DEFAULT_VHOST,
    HASHING_ALGORITHM,
    RabbitMQAdmin,
    RabbitMQAdminError,
    rabbit_password_hash,
)
from .rabbitmq_auth import PARAMETER_PREFIX, password_parameter

log = logging.getLogger(__name__)

PBKDF2_ITERATIONS = 101  # mosquitto_passwd's own default for $7$
SALT_BYTES = 12
RABBIT_HASH_PREFIX = "rabbitmq-sha256:"
DRONE_TAG = "skyhive-drone"  # marks the RabbitMQ users this module owns


class BrokerUnavailable(RuntimeError):
    """The broker could not be updated; the database keeps the intended state."""


# -- addresses drones are given --------------------------------------------------------


def broker_address() -> tuple[str, int]:
    url = urlsplit(settings.MQTT_URL)
    host = settings.MQTT_PUBLIC_HOST or url.hostname or "127.0.0.1"
    port = settings.MQTT_PUBLIC_PORT or url.port or 1883
    return host, port


def broker_addresses() -> list[tuple[str, int]]:
    """Every node a drone may use. One node unless RabbitMQ runs with several; then
    MQTT_URLS' ports, each with MQTT_PUBLIC_HOST when set (MQTT_PUBLIC_PORT names one
    port, so it only applies to a single node)."""
    if settings.MQTT_BROKER != "rabbitmq" or len(settings.MQTT_URLS) <= 1:
        return [broker_address()]
    addresses = []
    for url in settings.MQTT_URLS:
        parts = urlsplit(url)
        host = settings.MQTT_PUBLIC_HOST or parts.hostname or "127.0.0.1"
        addresses.append((host, parts.port or 1883))
    return addresses


# -- hashes -------------------------------------------------------------------------------


def hash_password(password: str, *, salt: bytes | None = None) -> str:
    """A Mosquitto 2 password-file hash: `$7$<iterations>$<salt b64>$<sha512 b64>`."""
    salt = salt if salt is not None else secrets.token_bytes(SALT_BYTES)
    digest = hashlib.pbkdf2_hmac("sha512", password.encode(), salt, PBKDF2_ITERATIONS)
    salt_b64 = base64.b64encode(salt).decode()
    return f"$7${PBKDF2_ITERATIONS}${salt_b64}${base64.b64encode(digest).decode()}"


def check_password(password: str, hashed: str) -> bool:
    """Against a `$7$` hash or a stored value (its `$7$` part)."""
    try:
        _, kind, iterations, salt, digest = mosquitto_hash(hashed).split("$")
    except ValueError:
        return False
    if kind != "7":
        return False
    computed = hashlib.pbkdf2_hmac(
        "sha512", password.encode(), base64.b64decode(salt), int(iterations)
    )
    return secrets.compare_digest(base64.b64encode(computed).decode(), digest)


def stored_hash(password: str) -> str:
    """What `Drone.mqtt_password_hash` keeps: both brokers' hashes of one password."""
    return f"{hash_password(password)} {RABBIT_HASH_PREFIX}{rabbit_password_hash(password)}"


def mosquitto_hash(stored: str) -> str:
    return stored.split(" ", 1)[0]


def rabbitmq_hash(stored: str) -> str | None:
    """None for a drone provisioned before RabbitMQ was supported: it needs a new password."""
    for part in stored.split(" ")[1:]:
        if part.startswith(RABBIT_HASH_PREFIX):
            return part[len(RABBIT_HASH_PREFIX) :]
    return None


# -- backends -----------------------------------------------------------------------------


@dataclass
class SyncReport:
    """What a full rebuild did."""

    broker: str
    users: int  # drone users now on the broker
    removed: list[str] = field(default_factory=list)  # drone users that were not in the DB
    # Drones whose stored hash the broker cannot use (provisioned before RabbitMQ support):
    # they must be provisioned again.
    needs_new_password: list[str] = field(default_factory=list)
    reloaded: bool = True

    def to_dict(self) -> dict:
        return {
            "broker": self.broker,
            "users": self.users,
            "removed": self.removed,
            "needs_new_password": self.needs_new_password,
            "reloaded": self.reloaded,
        }


# Reads the (drone id, stored hash) of every drone that may connect, when asked: the
# Mosquitto backend rebuilds its files from committed rows, not from what it was told.
LiveDrones = Callable[[], list[tuple[str, str]]]


class BrokerBackend(Protocol):
    def apply(self, drones: list[tuple[str, str]]) -> None:
        """Inside the provisioning transaction: these drones' new stored hashes."""

    def after_commit(self) -> None:
        """After the transaction committed."""

    def revoke(self, drone_ids: list[str]) -> None: ...

    def sync(self, drones: list[tuple[str, str]]) -> SyncReport: ...

    def outdated_users(self) -> list[str]:
        """Drone users the broker holds in an earlier form than provisioning writes now."""

    def upgrade(self, outdated: list[str], drones: list[tuple[str, str]]) -> None:
        """Bring these outdated users to the current form: `drones` are the live ones among
        them with their stored hashes; the others go."""


def backend(live_drones: LiveDrones) -> BrokerBackend:
    """The backend of the configured broker (settings.MQTT_BROKER)."""
    if settings.MQTT_BROKER == "rabbitmq":
        if not settings.RABBITMQ_API_URLS:
            raise BrokerUnavailable(
                "MQTT_BROKER=rabbitmq needs RABBITMQ_API_URLS (scripts/rabbitmq.sh env prints it)."
            )
        return RabbitMQBackend(RabbitMQAdmin.from_settings())
    return MosquittoBackend(Path(settings.MOSQUITTO_DIR), live_drones)


# -- Mosquitto's files --------------------------------------------------------------------


# The client ids the ground's processes take (workers/gateway.py and its batch readers,
# workers/direct.py, telemetry/ingest.py, pastview/runner.py and pastview/service.py) and
# Mosquitto's own `auto-` ids for clients that send none. On the drones' listener a
# drone's client id is its username (scripts/services.sh), so no drone id may start like
# one of these: the drone would take over that ground session.
GROUND_CLIENT_ID_PREFIXES = ("gateway-", "web-", "ingest-", "pastview-", "auto-")


def is_ground_client_id(drone_id: str) -> bool:
    return drone_id.lower().startswith(GROUND_CLIENT_ID_PREFIXES)


def service_users() -> list[str]:
    users = list(settings.MQTT_SERVICE_USERS)
    ground = urlsplit(settings.MQTT_URL).username
    if ground and ground not in users:
        users.append(ground)
    return users


@contextmanager
def _locked(directory: Path) -> Iterator[None]:
    """One writer at a time across processes (API, admin, command)."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / ".provisioning.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _write_atomically(path: Path, text: str) -> None:
    # A new file is readable by its group too: the broker runs unprivileged, in the group
    # of its setgid folder, and must read what provisioning (as root) writes there.
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o640
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def render_passwd(existing: str, drones: list[tuple[str, str]]) -> str:
    """Keep the service users' lines as they are; one line per drone with credentials."""
    keep = set(service_users())
    lines = [line for line in existing.splitlines() if line.split(":", 1)[0] in keep]
    lines += [f"{drone_id}:{mosquitto_hash(stored)}" for drone_id, stored in drones]
    return "\n".join(lines) + "\n"


def render_acl(drone_ids: list[str]) -> str:
    """Ground services read and write everything; each drone only its own tree, spelt out
    per drone (not a `%u` pattern) so a user that is not a live drone gets nothing."""
    parts = ["# Generated from the database (manage.py provision_drone); edits are overwritten."]
    # `#` does not match `$SYS/...`: the operations page reads the broker's figures there.
    for user in service_users():
        parts.append(f"user {user}\ntopic readwrite #\ntopic read $SYS/#")
    for drone_id in drone_ids:
        parts.append(f"user {drone_id}\ntopic write {drone_id}/+/out\ntopic read {drone_id}/+/in")
    return "\n\n".join(parts) + "\n"


class MosquittoBackend:
    """Every change is a full rewrite of passwd and acl plus one SIGHUP."""

    def __init__(self, directory: Path, live_drones: LiveDrones) -> None:
        self.directory = directory
        self.live_drones = live_drones

    def apply(self, drones: list[tuple[str, str]]) -> None:
        pass  # the files are rebuilt from committed rows in after_commit

    def after_commit(self) -> None:
        self.sync(self.live_drones())

    def revoke(self, drone_ids: list[str]) -> None:
        self.sync(self.live_drones())

    def sync(self, drones: list[tuple[str, str]]) -> SyncReport:
        with _locked(self.directory):
            passwd = self.directory / "passwd"
            existing = passwd.read_text() if passwd.exists() else ""
            _write_atomically(passwd, render_passwd(existing, drones))
            _write_atomically(self.directory / "acl", render_acl([d for d, _ in drones]))
            ground = self.directory / "ground.passwd"
            if ground.exists():  # the ground's own listener (scripts/services.sh)
                _write_atomically(ground, render_passwd(existing, []))
            reloaded = _reload(self.directory / "mosquitto.pid")
        before = {line.split(":", 1)[0] for line in existing.splitlines() if ":" in line}
        removed = sorted(before - set(service_users()) - {d for d, _ in drones})
        return SyncReport("mosquitto", users=len(drones), removed=removed, reloaded=reloaded)

    def outdated_users(self) -> list[str]:
        # The files are rewritten whole from the database at every change, and the client
        # id is bound to the username by the broker's configuration: no earlier form stays.
        return []

    def upgrade(self, outdated: list[str], drones: list[tuple[str, str]]) -> None:
        pass


def _reload(pid_file: Path) -> bool:
    try:
        pid = int(pid_file.read_text().strip())
        os.kill(pid, signal.SIGHUP)
    except (OSError, ValueError) as exc:
        log.warning("broker not reloaded (%s): %s", pid_file, exc)
        return False
    return True


# -- RabbitMQ users and permissions -------------------------------------------------------


def session_queue_pattern(drone_id: str) -> str:
    """The MQTT plugin's queues of the drone's sessions (`mqtt-subscription-<client id>
    qos0|qos1`), for the client ids drones use: the drone id (load drones) and
    `skyhive-agent-<id>` (the onboard agent). No wider: `<id>.*` would match `<id>2`."""
    return rf"mqtt-subscription-(skyhive-agent-)?{re.escape(drone_id)}qos[01]"


def rabbitmq_definitions(drones: list[tuple[str, str]]) -> dict:
    """Users, vhost and topic permissions and password hashes of these drones, as
    `POST /api/definitions` takes them. The drone may declare, bind and consume only its
    own session queues and publish only to amq.topic; on amq.topic it may write only
    `<id>.<channel>.out` and read (subscribe to) only `<id>.<channel>.in`, like the
    Mosquitto ACL's `<id>/+/out` and `<id>/+/in`. The user's own password hash is empty,
    so the internal backend never logs a drone in: the auth service does, from the hash
    in the drone's global parameter, and only under the drone's own client ids."""
    users, permissions, topic_permissions, parameters = [], [], [], []
    for drone_id, hashed in drones:
        queues = session_queue_pattern(drone_id)
        own = rf"^(amq\.topic|{queues})$"
        users.append(
            {
                "name": drone_id,
                "password_hash": "",
                "hashing_algorithm": HASHING_ALGORITHM,
                "tags": DRONE_TAG,
            }
        )
        parameters.append(
            {
                "name": password_parameter(drone_id),
                "value": {"password_hash": hashed, "hashing_algorithm": HASHING_ALGORITHM},
            }
        )
        permissions.append(
            {
                "user": drone_id,
                "vhost": DEFAULT_VHOST,
                "configure": f"^{queues}$",
                "write": own,
                "read": own,
            }
        )
        escaped = re.escape(drone_id)
        topic_permissions.append(
            {
                "user": drone_id,
                "vhost": DEFAULT_VHOST,
                "exchange": "amq.topic",
                "write": rf"^{escaped}\.[^.]+\.out$",
                "read": rf"^{escaped}\.[^.]+\.in$",
            }
        )
    return {
        "users": users,
        "permissions": permissions,
        "topic_permissions": topic_permissions,
        "global_parameters": parameters,
    }


class RabbitMQBackend:
    """Per-drone users through the management API of any node of the cluster."""

    def __init__(self, admin: RabbitMQAdmin) -> None:
        self.admin = admin

    def apply(self, drones: list[tuple[str, str]]) -> None:
        usable, unusable = _split_by_rabbit_hash(drones)
        if unusable:  # cannot happen for a fresh password; a bug if it does
            raise BrokerUnavailable(f"no RabbitMQ hash for {', '.join(unusable)}")
        self._call(lambda: self.admin.import_definitions(rabbitmq_definitions(usable)))

    def after_commit(self) -> None:
        pass

    def revoke(self, drone_ids: list[str]) -> None:
        self._call(lambda: self._remove(drone_ids))

    def sync(self, drones: list[tuple[str, str]]) -> SyncReport:
        usable, unusable = _split_by_rabbit_hash(drones)
        for drone_id in unusable:
            log.warning("drone %s has no RabbitMQ password hash: provision it again", drone_id)
        wanted = {drone_id for drone_id, _ in usable}

        def rebuild() -> list[str]:
            if usable:
                self.admin.import_definitions(rabbitmq_definitions(usable))
            ours = [u["name"] for u in self.admin.users() if DRONE_TAG in _tags(u)]
            extra = sorted(set(ours) - wanted)
            self._remove(extra)
            # A hash left without its user (its removal was cut short) goes too.
            for drone_id in sorted(set(self.admin.global_parameters(PARAMETER_PREFIX)) - wanted):
                self.admin.delete_global_parameter(password_parameter(drone_id))
            return extra

        removed = self._call(rebuild)
        return SyncReport(
            "rabbitmq", users=len(usable), removed=removed, needs_new_password=unusable
        )

    def outdated_users(self) -> list[str]:
        """Drone users that still hold a password of their own (provisioned before the
        auth service checked the client id: the internal backend logs them in under any
        client id) or whose hash parameter is missing."""

        def listed() -> list[str]:
            hashes = set(self.admin.global_parameters(PARAMETER_PREFIX))
            return sorted(
                user["name"]
                for user in self.admin.users()
                if DRONE_TAG in _tags(user)
                and (user.get("password_hash") or user["name"] not in hashes)
            )

        return self._call(listed)

    def upgrade(self, outdated: list[str], drones: list[tuple[str, str]]) -> None:
        """The live drones among `outdated` get the current form (no password of their
        own, their hash in its parameter, the same permissions); any other outdated user
        (a drone gone from the database, or one without a RabbitMQ hash) is removed, so no
        user keeps a password the internal backend would accept."""
        usable, _ = _split_by_rabbit_hash([(d, h) for d, h in drones if d in set(outdated)])
        kept = {drone_id for drone_id, _ in usable}

        def rewrite() -> None:
            if usable:
                self.admin.import_definitions(rabbitmq_definitions(usable))
            self._remove(sorted(set(outdated) - kept))

        self._call(rewrite)

    def _remove(self, drone_ids: list[str]) -> None:
        """Delete the users, close their connections, drop their session queues."""
        if not drone_ids:
            return
        # Connections listed before the users go (deleting a user also makes RabbitMQ
        # close its connections, but one opened a moment ago may not be listed yet: the
        # second listing catches it).
        connections = self.admin.connections_of(drone_ids)
        self.admin.delete_users(drone_ids)
        for drone_id in drone_ids:
            self.admin.delete_global_parameter(password_parameter(drone_id))
        for name in dict.fromkeys(connections + self.admin.connections_of(drone_ids)):
            self.admin.close_connection(name, "broker credentials revoked")
        # Commands queued for a revoked drone must not reach it if it is ever re-issued.
        for start in range(0, len(drone_ids), 100):
            chunk = drone_ids[start : start + 100]
            alternatives = "|".join(re.escape(d) for d in chunk)
            pattern = f"^mqtt-subscription-(skyhive-agent-)?({alternatives})qos[01]$"
            for queue in self.admin.queues_named(pattern):
                self.admin.delete_queue(queue)

    def _call(self, action):  # type: ignore[no-untyped-def]
        try:
            return action()
        except RabbitMQAdminError as exc:
            raise BrokerUnavailable(f"RabbitMQ was not updated: {exc}") from exc


def _split_by_rabbit_hash(drones: list[tuple[str, str]]) -> tuple[list[tuple[str, str]], list[str]]:
    usable, unusable = [], []
    for drone_id, stored in drones:
        hashed = rabbitmq_hash(stored)
        if hashed is None:
            unusable.append(drone_id)
        else:
            usable.append((drone_id, hashed))
    return usable, unusable


def _tags(user: dict) -> list[str]:
    tags = user.get("tags") or []
    return tags.split(",") if isinstance(tags, str) else list(tags)
