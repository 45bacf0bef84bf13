"""Organisation members: invitations by e-mail, roles, removal.

Every change takes effect on the member's next request (roles are read from the
database on each one). Removal also revokes the member's tokens for the organisation
and closes their open websockets. An organisation always keeps at least one admin.
"""

from __future__ import annotations

import hashlib
import secrets
from dataclasses import dataclass
from datetime import timedelta
from smtplib import SMTPException
from typing import Any

from asgiref.sync import async_to_sync
from channels.layers import get_channel_layer
from django.conf import settings
from django.contrib.auth import get_user_model
from django.core.exceptions import ValidationError
from django.core.mail import send_mail
from django.core.validators import validate_email
from django.db import transaction
from django.template.loader import render_to_string
from django.utils import timezone

from fleet.consumers import user_group
from fleet.models import Membership, Organisation, Role

from . import audit, tokens
from .errors import Refused
from .models import Invitation


@dataclass(frozen=True)
class Invited:
    invitation: Invitation
    key: str  # in the link only


def _digest(key: str) -> str:
    return hashlib.sha256(key.encode()).hexdigest()


def _clean_role(role: Any) -> str:
    if role not in Role.values:
        raise Refused(f"role must be one of {', '.join(Role.values)}")
    return str(role)


def invite(organisation: Organisation, email: Any, role: Any, by: Any) -> Invited:
    """A new invitation (an earlier pending one to the same address is revoked)."""
    email = str(email or "").strip().lower()
    try:
        validate_email(email)
    except ValidationError:
        raise Refused(f"{email!r} is not an e-mail address") from None
    role = _clean_role(role)
    if Membership.objects.filter(organisation=organisation, user__email__iexact=email).exists():
        raise Refused(f"{email} is already a member of {organisation.name}", 409)
    key = secrets.token_urlsafe(32)
    with transaction.atomic():
        pending(organisation).filter(email=email).update(revoked_at=timezone.now())
        invitation = Invitation.objects.create(
            organisation=organisation,
            email=email,
            role=role,
            key_hash=_digest(key),
            invited_by=by,
            expires_at=timezone.now() + timedelta(days=settings.INVITATION_DAYS),
        )
        _audit(organisation, "member.invite", email, role=role)
    return Invited(invitation, key)


def _audit(organisation: Organisation, action: str, target: str, **detail: Any) -> None:
    audit.record(organisation.pk, audit.Kind.MEMBER, action, target=target, detail=detail)


def send_invitation(invited: Invited, link: str) -> None:
    """Mail the link; if the mail server refuses or is away, the invitation is withdrawn
    (nobody could use it) and Refused (502) says why."""
    invitation = invited.invitation
    context = {"invitation": invitation, "link": link, "days": settings.INVITATION_DAYS}
    try:
        send_mail(
            f"Join {invitation.organisation.name} on Skyhive",
            render_to_string("accounts/invitation_email.txt", context),
            None,
            [invitation.email],
        )
    except (OSError, SMTPException) as exc:
        withdraw(invitation)
        raise Refused(f"The invitation e-mail could not be sent ({exc}); try again.", 502) from None


def pending(organisation: Organisation):  # type: ignore[no-untyped-def]
    return Invitation.objects.filter(
        organisation=organisation,
        accepted_at__isnull=True,
        revoked_at__isnull=True,
        expires_at__gt=timezone.now(),
    )


def find_invitation(key: str) -> Invitation:
    """The usable invitation for a link's key; Refused (410) if used or expired."""
    invitation = (
        Invitation.objects.select_related("organisation").filter(key_hash=_digest(key)).first()
    )
    if invitation is None:
        raise Refused("This invitation link is not valid.", 404)
    refusals = {
        "accepted": "This invitation was already used.",
        "revoked": "This invitation was withdrawn.",
        "expired": "This invitation has expired; ask for a new one.",
    }
    if invitation.state in refusals:
        raise Refused(refusals[invitation.state], 410)
    return invitation


def account_for(invitation: Invitation) -> Any | None:
    """The existing account with the invited address, if any."""
    return get_user_model().objects.filter(email__iexact=invitation.email).first()


def accept(key: str, user: Any) -> Membership:
    """Join the invitation's organisation with its role; the link works once."""
    with transaction.atomic():
        invitation = find_invitation(key)
        invitation = Invitation.objects.select_for_update().get(pk=invitation.pk)
        if invitation.state != "pending":
            raise Refused("This invitation was already used.", 410)
        if (user.email or "").lower() != invitation.email:
            raise Refused(
                f"This invitation is for {invitation.email}; sign in with that account.", 403
            )
        if Membership.objects.filter(user=user, organisation=invitation.organisation).exists():
            raise Refused(f"You are already a member of {invitation.organisation.name}.", 409)
        membership = Membership.objects.create(
            user=user, organisation=invitation.organisation, role=invitation.role
        )
        invitation.accepted_at = timezone.now()
        invitation.accepted_by = user
        invitation.save(update_fields=["accepted_at", "accepted_by"])
        audit.record(
            invitation.organisation_id,
            audit.Kind.MEMBER,
            "member.join",
            target=user.get_username(),
            actor=user,
            detail={"role": invitation.role, "email": invitation.email},
        )
    return membership


def _lock_admins(organisation: Organisation) -> list[int]:
    """Ids of the organisation's admin memberships, locked until the transaction ends, so
    two admins demoting each other at once cannot leave none."""
    return list(
        Membership.objects.select_for_update()
        .filter(organisation=organisation, role=Role.ADMIN)
        .values_list("pk", flat=True)
    )


def _keep_an_admin(membership: Membership, becoming: str | None) -> None:
    admins = _lock_admins(membership.organisation)
    if becoming != Role.ADMIN and admins == [membership.pk]:
        raise Refused(
            f"{membership.organisation.name} must keep at least one admin; "
            "make someone else admin first.",
            409,
        )


def change_role(membership: Membership, role: Any) -> Membership:
    role = _clean_role(role)
    with transaction.atomic():
        _keep_an_admin(membership, role)
        Membership.objects.filter(pk=membership.pk).update(role=role)
        _audit(
            membership.organisation,
            "member.role",
            membership.user.get_username(),
            before=membership.role,
            after=role,
        )
    membership.role = role
    return membership


def remove(membership: Membership) -> None:
    """Remove the member: their tokens for the organisation are revoked and their open
    websockets closed once the removal is committed."""
    with transaction.atomic():
        _keep_an_admin(membership, None)
        membership.delete()
        revoked = tokens.revoke_for_organisation(membership.user, membership.organisation)
        _audit(
            membership.organisation,
            "member.remove",
            membership.user.get_username(),
            role=membership.role,
            tokens_revoked=revoked,
        )
        user_id = membership.user_id
        transaction.on_commit(lambda: close_sockets(user_id))


def close_sockets(user_id: int) -> None:
    """Close every open websocket of the user; their pages reconnect and are authorised
    again, so what they may no longer see stays closed."""
    layer = get_channel_layer()
    if layer is not None:
        async_to_sync(layer.group_send)(user_group(user_id), {"type": "access.changed"})


def members_of(organisation: Organisation) -> list[Membership]:
    return list(
        Membership.objects.filter(organisation=organisation)
        .select_related("user")
        .order_by("user__username")
    )


def withdraw(invitation: Invitation) -> None:
    if Invitation.objects.filter(pk=invitation.pk, revoked_at__isnull=True).update(
        revoked_at=timezone.now()
    ):
        _audit(invitation.organisation, "member.withdraw", invitation.email)
