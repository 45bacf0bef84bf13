"""A new password ends what the old one let out: the user's personal tokens are revoked.

Whatever sets it (the portal's change and reset pages, the admin, `manage.py
changepassword`) goes through `set_password` and `save`, and Django keeps the new raw
password on the instance until `save` returns, except when it only upgrades the hash of
the same password on sign-in; the receiver below acts on exactly that. The user's other
sessions end by Django's own rule: a session is kept with a hash of the password and is
refused once that no longer matches (the change page keeps its own session only).
"""

from __future__ import annotations

from typing import Any

from django.utils import timezone

from . import audit, tokens
from .models import ApiToken


def password_saved(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    """post_save of the user model: revoke every token after a password change."""
    if created or getattr(instance, "_password", None) is None:
        return
    revoked = ApiToken.objects.filter(user=instance, revoked_at__isnull=True).update(
        revoked_at=timezone.now()
    )
    revoked += tokens.revoke_legacy(instance)
    audit.record(
        audit.organisation_ids_of(instance),
        audit.Kind.SECURITY,
        "security.password_change",
        target=instance.get_username(),
        detail={"tokens_revoked": revoked},
    )
