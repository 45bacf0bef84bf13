"""An organisation's own settings, changed by its admins: name, default home, alert
recipients, and whether operators and admins must sign in with a second factor.

The flight envelope has its own page (fleet); alert recipients are kept for the alerts
that will be sent to them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from django.core.exceptions import ValidationError
from django.core.validators import URLValidator, validate_email
from django.db import transaction

from config import outbound
from fleet.models import Organisation
from onboard.envelope import EnvelopeError, parse_latlon

from . import audit
from .errors import Refused
from .models import OrganisationSettings

MAX_RECIPIENTS = 50
_url = URLValidator(schemes=["http", "https"])


@dataclass(frozen=True)
class Changes:
    name: str
    default_home: list[float] | None
    alert_recipients: list[str]
    require_second_factor: bool


def settings_of(organisation: Organisation) -> OrganisationSettings:
    found, _ = OrganisationSettings.objects.get_or_create(organisation=organisation)
    return found


def _home(text: Any) -> list[float] | None:
    """`lat, lon` (or empty for none)."""
    text = str(text or "").strip()
    if not text:
        return None
    parts = [part.strip() for part in text.replace(";", ",").split(",")]
    try:
        return list(parse_latlon([float(p) for p in parts] if len(parts) == 2 else [], "home"))
    except (ValueError, EnvelopeError) as exc:
        reason = exc.message if isinstance(exc, EnvelopeError) else "must be numbers"
        raise Refused(
            f"default home: {reason} (like 40.6303, -8.6575)", field="default_home"
        ) from None


def _recipient(entry: str) -> str:
    """An e-mail address or an http(s) webhook URL."""
    try:
        if entry.startswith(("http://", "https://")):
            _url(entry)
        else:
            validate_email(entry)
    except ValidationError:
        raise Refused(
            f"alert recipients: {entry!r} is neither an e-mail address nor an http(s) URL",
            field="alert_recipients",
        ) from None
    if entry.startswith(("http://", "https://")):
        try:
            outbound.check(entry)  # a public address only, unless the site allows private
        except outbound.Refused as exc:
            raise Refused(f"alert recipients: {exc}", field="alert_recipients") from None
    return entry


def _recipients(text: Any) -> list[str]:
    """One per line (or comma-separated), duplicates dropped, order kept."""
    entries = [e.strip() for e in str(text or "").replace(",", "\n").splitlines() if e.strip()]
    if len(entries) > MAX_RECIPIENTS:
        raise Refused(f"alert recipients: at most {MAX_RECIPIENTS}", field="alert_recipients")
    return list(dict.fromkeys(_recipient(e) for e in entries))


def clean(form: Any) -> Changes:
    """Validated settings from the page's form; Refused names the bad field."""
    name = str(form.get("name") or "").strip()
    if not 1 <= len(name) <= 120:
        raise Refused("name: 1 to 120 characters", field="name")
    return Changes(
        name=name,
        default_home=_home(form.get("default_home")),
        alert_recipients=_recipients(form.get("alert_recipients")),
        require_second_factor=form.get("require_second_factor") in ("on", "true", "1", True),
    )


def update(organisation: Organisation, changes: Changes) -> None:
    with transaction.atomic():
        stored = settings_of(organisation)
        before = {
            "name": organisation.name,
            "default_home": stored.default_home,
            "alert_recipients": stored.alert_recipients,
            "require_second_factor": stored.require_second_factor,
        }
        after = vars(changes)
        Organisation.objects.filter(pk=organisation.pk).update(name=changes.name)
        organisation.name = changes.name
        OrganisationSettings.objects.filter(pk=stored.pk).update(
            default_home=changes.default_home,
            alert_recipients=changes.alert_recipients,
            require_second_factor=changes.require_second_factor,
        )
        changed = {key: after[key] for key in after if after[key] != before[key]}
        if changed:
            audit.record(
                organisation.pk,
                audit.Kind.ORGANISATION,
                "organisation.change",
                target=organisation.name,
                detail={"changed": changed},
            )
