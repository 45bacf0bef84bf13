"""Per-drone broker credentials: issue, revoke, and rebuild the broker's users from the DB.

The domain half: which drones exist and in which organisation, a fresh password per
issue, only its hashes stored on the Drone (never the password), the JSON a drone is given,
and revocation recorded before the broker is told. The broker half (Mosquitto's files and
SIGHUP, or RabbitMQ's users and permissions) is workers.broker.credentials, chosen by
settings.MQTT_BROKER and fed plain drone ids and hashes from here.
"""

from __future__ import annotations

import secrets
from collections.abc import Sequence
from dataclasses import dataclass
from urllib.parse import quote

from django.conf import settings
from django.db import transaction

from workers.broker import credentials as broker
from workers.broker.credentials import (
    DRONE_TAG,
    BrokerUnavailable,
    SyncReport,
    check_password,
    hash_password,
    stored_hash,
)

from .models import DRONE_ID_RE, Drone, Organisation, reserved_drone_ids

# What callers of provisioning use besides the functions here: the errors to catch, the
# report of a sync, and the stored hashes' check (callers verify a drone's password).
__all__ = [
    "DRONE_TAG",
    "BrokerUnavailable",
    "Credentials",
    "ProvisioningError",
    "SyncReport",
    "check_password",
    "hash_password",
    "provision",
    "provision_many",
    "revoke",
    "revoke_many",
    "sync_broker",
    "upgrade_broker",
]


class ProvisioningError(ValueError):
    """The request itself is wrong (unknown organisation, bad id, another org's drone)."""


# -- what a drone is told -----------------------------------------------------------------


@dataclass(frozen=True)
class Credentials:
    drone_id: str
    host: str
    port: int
    password: str
    # Every broker node as mqtt(s)://<id>:<password>@host:port, in the order to try them.
    urls: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        """The JSON `provision_drone` prints (docs/protocol.md, "Provisioning a drone")."""
        mqtt = {
            "host": self.host,
            "port": self.port,
            "username": self.drone_id,
            "password": self.password,
        }
        if self.urls:
            mqtt["urls"] = list(self.urls)
        return {"drone_id": self.drone_id, "mqtt": mqtt}


def _credentials(drone_id: str, password: str, addresses: list[tuple[str, int]]) -> Credentials:
    userinfo = f"{quote(drone_id, safe='')}:{quote(password, safe='')}"
    scheme = "mqtts" if settings.MQTT_PUBLIC_TLS else "mqtt"
    urls = tuple(f"{scheme}://{userinfo}@{host}:{port}" for host, port in addresses)
    host, port = addresses[0]
    return Credentials(drone_id, host, port, password, urls)


# -- provisioning -------------------------------------------------------------------------


def provision(drone_id: str, organisation_slug: str | None = None) -> Credentials:
    """Create the drone if needed, give it a new password, update the broker."""
    return provision_many([drone_id], organisation_slug)[0]


def provision_many(
    drone_ids: Sequence[str], organisation_slug: str | None = None
) -> list[Credentials]:
    """New passwords for many drones (created in the organisation when missing), applied
    to the broker in one step: one file rewrite and SIGHUP, or one definitions import.
    All or nothing: a bad id or another organisation's drone refuses the whole batch."""
    ids = list(drone_ids)
    _validate_ids(ids)
    if not ids:
        return []
    backend = _backend()
    passwords = {drone_id: secrets.token_urlsafe(24) for drone_id in ids}
    hashes = {drone_id: stored_hash(password) for drone_id, password in passwords.items()}
    with transaction.atomic():
        _store_hashes(hashes, organisation_slug)
        # Inside the transaction where the backend can be told exactly what changed (a
        # failure then rolls the new passwords back, leaving the old ones valid on both
        # sides); Mosquitto's files are rebuilt from committed rows after it.
        backend.apply(list(hashes.items()))
    backend.after_commit()
    addresses = broker.broker_addresses()
    return [_credentials(drone_id, passwords[drone_id], addresses) for drone_id in ids]


def _store_hashes(hashes: dict[str, str], organisation_slug: str | None) -> None:
    """Set these drones' stored hashes (creating the missing ones), in the caller's
    transaction; refuse a drone of another organisation than the one named."""
    existing = {
        drone.drone_id: drone
        for drone in Drone.objects.select_for_update(of=("self",))
        .select_related("organisation")
        .filter(drone_id__in=list(hashes))
    }
    for drone in existing.values():
        if organisation_slug and drone.organisation.slug != organisation_slug:
            raise ProvisioningError(
                f"Drone {drone.drone_id} belongs to {drone.organisation.slug}, "
                f"not {organisation_slug}."
            )
    missing = [drone_id for drone_id in hashes if drone_id not in existing]
    if missing:
        organisation = _organisation(organisation_slug)
        Drone.objects.bulk_create(
            [
                Drone(
                    drone_id=drone_id,
                    organisation=organisation,
                    mqtt_password_hash=hashes[drone_id],
                )
                for drone_id in missing
            ]
        )
    for drone in existing.values():
        drone.mqtt_password_hash = hashes[drone.drone_id]
        drone.credentials_revoked = False
    Drone.objects.bulk_update(
        list(existing.values()), ["mqtt_password_hash", "credentials_revoked"]
    )


def revoke(drone: Drone) -> None:
    """Forget the drone's password and cut it off: the broker closes its connections."""
    revoke_many([drone])


def revoke_many(drones: Sequence[Drone]) -> None:
    ids = [drone.drone_id for drone in drones]
    # The database first: whatever happens to the broker call, the ground treats the
    # drones as revoked, and the next sync_broker() finishes the job.
    Drone.objects.filter(drone_id__in=ids).update(mqtt_password_hash="", credentials_revoked=True)
    for drone in drones:
        drone.mqtt_password_hash = ""
        drone.credentials_revoked = True
    _backend().revoke(ids)


def _validate_ids(ids: list[str]) -> None:
    bad = [
        drone_id
        for drone_id in ids
        if not isinstance(drone_id, str) or not DRONE_ID_RE.fullmatch(drone_id)
    ]
    if bad:
        shown = ", ".join(repr(b) for b in bad[:5])
        raise ProvisioningError(
            f"Invalid drone id(s) {shown}: use 1 to 64 letters, digits, '_' or '-'."
        )
    reserved = [drone_id for drone_id in ids if drone_id.lower() in reserved_drone_ids()]
    if reserved:
        shown = ", ".join(repr(r) for r in reserved[:5])
        raise ProvisioningError(
            f"Reserved drone id(s) {shown}: broker account names are not drone ids."
        )
    ground_like = [drone_id for drone_id in ids if broker.is_ground_client_id(drone_id)]
    if ground_like:
        shown = ", ".join(repr(g) for g in ground_like[:5])
        prefixes = ", ".join(broker.GROUND_CLIENT_ID_PREFIXES)
        raise ProvisioningError(
            f"Reserved drone id(s) {shown}: the ground's client ids start with {prefixes}."
        )
    if len(set(ids)) != len(ids):
        raise ProvisioningError("The same drone id appears twice.")


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


def _live_drones() -> list[tuple[str, str]]:
    """(drone id, stored hash) of every drone that may connect, from the database."""
    return list(
        Drone.objects.filter(credentials_revoked=False)
        .exclude(mqtt_password_hash="")
        .order_by("drone_id")
        .values_list("drone_id", "mqtt_password_hash")
    )


def sync_broker() -> SyncReport:
    """Rebuild the broker's drone users and permissions from the database (after a broker
    node or cluster is replaced, or to finish a revocation the broker missed)."""
    return _backend().sync(_live_drones())


def upgrade_broker() -> list[str]:
    """Bring drone users the broker keeps in an earlier form to the current one, and
    return their ids; nothing when none is left, so it is run at every start of the
    ground. The drones' rows are locked meanwhile: a password issued at the same time
    waits, and is not overwritten by the hash read here."""
    backend = _backend()
    outdated = backend.outdated_users()
    if not outdated:
        return []
    with transaction.atomic():
        live = list(
            Drone.objects.select_for_update(of=("self",))
            .filter(drone_id__in=outdated, credentials_revoked=False)
            .exclude(mqtt_password_hash="")
            .order_by("drone_id")
            .values_list("drone_id", "mqtt_password_hash")
        )
        backend.upgrade(outdated, live)
    return outdated


def _backend() -> broker.BrokerBackend:
    return broker.backend(_live_drones)
