"""The members and organisation settings pages (organisation admins) and the invitation
link (anyone with it)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from django.contrib import messages
from django.contrib.auth import login
from django.contrib.auth.decorators import login_required
from django.contrib.auth.forms import UserCreationForm
from django.core.exceptions import PermissionDenied
from django.db import transaction
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.http import require_POST

from fleet import remote_id
from fleet.identity import IdentityError
from fleet.models import Membership, Role
from fleet.tenancy import SESSION_KEY, acting_membership

from . import audit, members, twofactor
from . import organisation as org_settings
from .errors import Refused


def admin_organisation(request: HttpRequest):  # type: ignore[no-untyped-def]
    """The current organisation, if the user is its admin; 403 otherwise, and for a
    change while the session owes the second factor the organisation requires."""
    membership = acting_membership(request)
    if membership is None or not membership.allows(Role.ADMIN):
        raise PermissionDenied("Only the organisation's admins manage it.")
    if request.method == "POST" and twofactor.missing(request):
        raise PermissionDenied("Sign in with your second factor before changing anything.")
    return membership.organisation


def _members_page(request: HttpRequest, status: int = 200, **extra: object) -> HttpResponse:
    organisation = admin_organisation(request)
    context = {
        "members": members.members_of(organisation),
        "invitations": members.pending(organisation),
        "roles": Role.choices,
        **extra,
    }
    return render(request, "accounts/members.html", context, status=status)


@login_required
def members_page(request: HttpRequest) -> HttpResponse:
    return _members_page(request)


@login_required
@require_POST
def invite(request: HttpRequest) -> HttpResponse:
    organisation = admin_organisation(request)
    try:
        invited = members.invite(
            organisation, request.POST.get("email"), request.POST.get("role"), request.user
        )
    except Refused as exc:
        return _members_page(request, exc.status, invite_error=exc.message)
    link = request.build_absolute_uri(reverse("accounts:invitation", args=[invited.key]))
    try:
        members.send_invitation(invited, link)
    except Refused as exc:
        return _members_page(request, exc.status, invite_error=exc.message)
    messages.success(request, f"Invitation sent to {invited.invitation.email}.")
    return redirect("accounts:members")


def _member(request: HttpRequest, pk: int) -> Membership:
    return get_object_or_404(
        Membership.objects.select_related("user", "organisation"),
        pk=pk,
        organisation=admin_organisation(request),
    )


def _member_change(
    request: HttpRequest, pk: int, action: str, change: Callable[[Membership], str]
) -> HttpResponse:
    """Apply `change` (which returns what to tell the admin) to a member of the
    admin's organisation; a refusal is shown on the page (and audited), nothing changed."""
    membership = _member(request, pk)
    try:
        done = change(membership)
    except Refused as exc:
        audit.record(
            membership.organisation_id,
            audit.Kind.MEMBER,
            action,
            target=membership.user.get_username(),
            outcome="refused",
            detail={"reason": exc.message},
        )
        return _members_page(request, exc.status, member_error=exc.message)
    messages.success(request, done)
    return redirect("accounts:members")


@login_required
@require_POST
def change_role(request: HttpRequest, pk: int) -> HttpResponse:
    def change(membership: Membership) -> str:
        members.change_role(membership, request.POST.get("role"))
        return f"{membership.user} is now {membership.get_role_display()}."

    return _member_change(request, pk, "member.role", change)


@login_required
@require_POST
def remove_member(request: HttpRequest, pk: int) -> HttpResponse:
    def change(membership: Membership) -> str:
        members.remove(membership)
        return f"{membership.user} was removed."

    return _member_change(request, pk, "member.remove", change)


@login_required
@require_POST
def revoke_invitation(request: HttpRequest, pk: int) -> HttpResponse:
    invitation = get_object_or_404(members.pending(admin_organisation(request)), pk=pk)
    members.withdraw(invitation)
    messages.success(request, f"Invitation to {invitation.email} withdrawn.")
    return redirect("accounts:members")


class SignUpForm(UserCreationForm):
    class Meta(UserCreationForm.Meta):
        fields = ("username",)

    def save_with_email(self, email: str) -> Any:
        user = self.save(commit=False)
        user.email = email
        user.save()
        return user


def invitation(request: HttpRequest, key: str) -> HttpResponse:
    """Accept an invitation: sign up, or sign in first when the address has an account."""
    try:
        found = members.find_invitation(key)
    except Refused as exc:
        return render(
            request, "accounts/invitation.html", {"error": exc.message}, status=exc.status
        )
    context: dict = {"invitation": found, "form": None}
    existing = members.account_for(found)
    if request.user.is_authenticated:
        if request.method == "POST":
            return _join(request, key, lambda: request.user)
    elif existing is not None:
        context["sign_in"] = f"{reverse('login')}?next={request.path}"
    elif request.method == "POST":
        form = SignUpForm(request.POST)
        if form.is_valid():
            return _join(request, key, lambda: form.save_with_email(found.email))
        context["form"] = form
    else:
        context["form"] = SignUpForm()
    return render(request, "accounts/invitation.html", context)


def _join(request: HttpRequest, key: str, account: Callable[[], Any]) -> HttpResponse:
    """Accept with the account `account()` returns; a new account is kept only if the
    invitation is accepted (one transaction)."""
    try:
        with transaction.atomic():
            user = account()
            membership = members.accept(key, user)
    except Refused as exc:
        return render(
            request, "accounts/invitation.html", {"error": exc.message}, status=exc.status
        )
    if not request.user.is_authenticated:
        login(request, user, backend="django.contrib.auth.backends.ModelBackend")
    request.session[SESSION_KEY] = membership.organisation.slug
    messages.success(
        request,
        f"Welcome to {membership.organisation.name} ({membership.get_role_display()}).",
    )
    return redirect("fleet:index")


@login_required
def organisation_settings(request: HttpRequest) -> HttpResponse:
    """Name, default home, alert recipients and the second-factor rule (admins)."""
    organisation = admin_organisation(request)
    status, error, remote_id_error = 200, None, None
    if request.method == "POST" and request.POST.get("section") == "remote_id":
        try:
            remote_id.set_organisation_remote_id(
                organisation, remote_id_changes(organisation, request.POST), request.user
            )
        except IdentityError as exc:
            status, remote_id_error = 400, exc.message
        else:
            messages.success(request, "Remote ID settings saved.")
            return redirect("accounts:organisation")
    elif request.method == "POST":
        try:
            org_settings.update(organisation, org_settings.clean(request.POST))
        except Refused as exc:
            status, error = 400, exc.message
        else:
            messages.success(request, "Organisation settings saved.")
            return redirect("accounts:organisation")
    stored = org_settings.settings_of(organisation)
    context = {
        "stored": stored,
        "recipients_text": "\n".join(stored.alert_recipients),
        "error": error,
        "form": request.POST if error else None,
        "remote_id_error": remote_id_error,
        "remote_id_form": request.POST if remote_id_error else None,
    }
    return render(request, "accounts/organisation.html", context, status=status)


def remote_id_changes(organisation: Any, form: Any) -> dict:
    """The Remote ID section's fields; the stored operator number (its public part, the
    secret characters never kept) given back unchanged is no change."""
    changes: dict[str, Any] = {"require_remote_id": form.get("require_remote_id") == "on"}
    operator_id = str(form.get("operator_id") or "").strip()
    if operator_id != organisation.operator_id:
        changes["operator_id"] = operator_id
    return changes
