"""Per-drone broker credentials: issue, revoke, and regenerate Mosquitto's files.

Only a hash is stored, in Mosquitto's own `$7$` format (PBKDF2-SHA512, as
`mosquitto_passwd` writes it), so the password file can be rebuilt from the database at
any time. After writing, Mosquitto gets SIGHUP: it re-reads both files and disconnects
clients whose credentials are gone (checked with Mosquitto 2.0.11: a revoked drone's
open connection is closed on the reload), so a revoked drone is cut off at once.
"""

from __future__ import annotations

import base64
import fcntl
import hashlib
import logging
import os
import secrets
import signal
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

from django.conf import settings
from django.db import transaction

from .models import Drone, Organisation

log = logging.getLogger(__name__)

PBKDF2_ITERATIONS = 101  # mosquitto_passwd's own default for $7$
SALT_BYTES = 12


class ProvisioningError(ValueError):
    pass


def hash_password(password: str, *, salt: bytes | None = None) -> str:
    """A Mosquitto 2 password-file hash: `$7$<iterations>$<salt b64>$<sha512 b64>`."""
    salt = salt if salt is not None else secrets.token_bytes(SALT_BYTES)
    digest = hashlib.pbkdf2_hmac("sha512", password.encode(), salt, PBKDF2_ITERATIONS)
    salt_b64 = base64.b64encode(salt).decode()
    return f"$7${PBKDF2_ITERATIONS}${salt_b64}${base64.b64encode(digest).decode()}"


def check_password(password: str, hashed: str) -> bool:
    try:
        _, kind, iterations, salt, digest = hashed.split("$")
    except ValueError:
        return False
    if kind != "7":
        return False
    computed = hashlib.pbkdf2_hmac(
        "sha512", password.encode(), base64.b64decode(salt), int(iterations)
    )
    return secrets.compare_digest(base64.b64encode(computed).decode(), digest)


@dataclass(frozen=True)
class Credentials:
    drone_id: str
    host: str
    port: int
    password: str

    def to_dict(self) -> dict:
        """The JSON `provision_drone` prints (PROTOCOL.md, "Ground side contract")."""
        return {
            "drone_id": self.drone_id,
            "mqtt": {
                "host": self.host,
                "port": self.port,
                "username": self.drone_id,
                "password": self.password,
            },
        }


def broker_address() -> tuple[str, int]:
    url = urlsplit(settings.MQTT_URL)
    host = settings.MQTT_PUBLIC_HOST or url.hostname or "127.0.0.1"
    port = settings.MQTT_PUBLIC_PORT or url.port or 1883
    return host, port


def provision(drone_id: str, organisation_slug: str | None = None) -> Credentials:
    """Create the drone if needed, give it a new password, reload the broker."""
    with transaction.atomic():
        drone = Drone.objects.select_for_update().filter(drone_id=drone_id).first()
        if drone is None:
            drone = Drone(drone_id=drone_id, organisation=_organisation(organisation_slug))
            drone.full_clean(exclude=["organisation"])
        elif organisation_slug and drone.organisation.slug != organisation_slug:
            raise ProvisioningError(
                f"Drone {drone_id} belongs to {drone.organisation.slug}, not {organisation_slug}."
            )
        password = secrets.token_urlsafe(24)
        drone.mqtt_password_hash = hash_password(password)
        drone.credentials_revoked = False
        drone.save()
    sync_broker()
    host, port = broker_address()
    return Credentials(drone.drone_id, host, port, password)


def revoke(drone: Drone) -> None:
    """Forget the drone's password; the broker disconnects it on the reload."""
    Drone.objects.filter(pk=drone.pk).update(mqtt_password_hash="", credentials_revoked=True)
    drone.mqtt_password_hash = ""
    drone.credentials_revoked = True
    sync_broker()


def _organisation(slug: str | None) -> Organisation:
    if slug:
        organisation = Organisation.objects.filter(slug=slug).first()
        if organisation is None:
            raise ProvisioningError(f"No organisation {slug!r}.")
        return organisation
    organisations = list(Organisation.objects.all()[:2])
    if len(organisations) != 1:
        raise ProvisioningError("Name the drone's organisation with --org SLUG.")
    return organisations[0]


# -- Mosquitto's files --------------------------------------------------------------------


def service_users() -> list[str]:
    users = list(settings.MQTT_SERVICE_USERS)
    ground = urlsplit(settings.MQTT_URL).username
    if ground and ground not in users:
        users.append(ground)
    return users


@contextmanager
def _locked(directory: Path):  # type: ignore[no-untyped-def]
    """One writer at a time across processes (API, admin, command)."""
    directory.mkdir(parents=True, exist_ok=True)
    with open(directory / ".provisioning.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _write_atomically(path: Path, text: str) -> None:
    mode = path.stat().st_mode & 0o777 if path.exists() else 0o600
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
    lines += [f"{drone_id}:{hashed}" for drone_id, hashed in drones]
    return "\n".join(lines) + "\n"


def render_acl(drone_ids: list[str]) -> str:
    """Ground services read and write everything; each drone only its own tree, spelt out
    per drone (not a `%u` pattern) so a user that is not a live drone gets nothing."""
    parts = ["# Generated by fleet.credentials from the database; edits are overwritten."]
    for user in service_users():
        parts.append(f"user {user}\ntopic readwrite #")
    for drone_id in drone_ids:
        parts.append(f"user {drone_id}\ntopic write {drone_id}/+/out\ntopic read {drone_id}/+/in")
    return "\n\n".join(parts) + "\n"


def sync_broker() -> bool:
    """Rewrite passwd and acl from the database and SIGHUP Mosquitto. True if reloaded."""
    directory = Path(settings.MOSQUITTO_DIR)
    drones = list(
        Drone.objects.filter(credentials_revoked=False)
        .exclude(mqtt_password_hash="")
        .order_by("drone_id")
        .values_list("drone_id", "mqtt_password_hash")
    )
    with _locked(directory):
        passwd = directory / "passwd"
        existing = passwd.read_text() if passwd.exists() else ""
        _write_atomically(passwd, render_passwd(existing, drones))
        _write_atomically(directory / "acl", render_acl([d for d, _ in drones]))
        return _reload(directory / "mosquitto.pid")


def _reload(pid_file: Path) -> bool:
    try:
        pid = int(pid_file.read_text().strip())
        os.kill(pid, signal.SIGHUP)
    except (OSError, ValueError) as exc:
        log.warning("broker not reloaded (%s): %s", pid_file, exc)
        return False
    return True
