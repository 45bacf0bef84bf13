"""The Django admin behind the portal's one sign-in policy, and in the audit trail.

`/admin/login/` is the portal's own sign-in view (accounts.signin.LoginView): the same
LOGIN_RATE limit per address and per username (429), and the authenticator's code for
a user who has one. A staff user reaches the admin only from a session that gave that
code, when they have an authenticator or an organisation of theirs requires one. The
first admin page a session opens, and each change the admin makes (its LogEntry), are
recorded in the audit trail, as is every action run on selected rows.
"""

from __future__ import annotations

from functools import update_wrapper
from typing import Any

from django.contrib import admin, messages
from django.core.exceptions import ObjectDoesNotExist
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect

from fleet.models import Organisation

from . import audit, signin, twofactor

# Set in a session once its opening of the admin is in the audit trail.
OPENED = "accounts_admin_opened"


class AdminSite(admin.AdminSite):
    def has_permission(self, request: HttpRequest) -> bool:
        allowed = super().has_permission(request) and twofactor.admin_allowed(request)
        if allowed and not request.session.get(OPENED):
            request.session[OPENED] = True
            _record(request.user, None, "admin.open", "the Django admin")
        return allowed

    def admin_view(self, view: Any, cacheable: bool = False) -> Any:
        """Every admin view; an action run on selected rows (which Django logs in bulk,
        without the signal the receiver below hears) is recorded here."""
        inner = super().admin_view(view, cacheable)

        def audited(request: HttpRequest, *args: Any, **kwargs: Any) -> HttpResponse:
            response = inner(request, *args, **kwargs)
            action = request.POST.get("action") if request.method == "POST" else None
            if action and response.status_code in (301, 302, 303):  # done, not asked
                selected = request.POST.getlist("_selected_action")[:100]
                _record(request.user, None, f"admin.{action}", request.path, selected=selected)
            return response

        return update_wrapper(audited, inner)

    def login(self, request: HttpRequest, extra_context: Any = None) -> HttpResponse:
        """The portal's sign-in; a staff user whose organisation requires a second
        factor they have not set up is sent to set it up."""
        user = request.user
        if self.has_permission(request):
            return redirect("admin:index")
        if user.is_authenticated and user.is_staff and twofactor.device_of(user) is None:
            messages.error(request, "The admin needs your second factor: set it up first.")
            return redirect("accounts:security")
        return signin.LoginView.as_view()(request)


def _audience(user: Any, changed: Any) -> list[int]:
    """Whose trail an admin action goes to: the changed row's organisation when it has
    one; else the user's organisations, or every one for a superuser in none."""
    if isinstance(changed, Organisation):
        return [changed.pk]
    if getattr(changed, "organisation_id", None):
        return [changed.organisation_id]
    ids = audit.organisation_ids_of(user)
    if not ids and user.is_superuser:
        ids = list(Organisation.objects.values_list("pk", flat=True))
    return ids


def _record(user: Any, changed: Any, action: str, target: str, **detail: Any) -> None:
    audit.record(
        _audience(user, changed),
        audit.Kind.SECURITY,
        action,
        target=target,
        actor=user,
        detail=detail,
    )


ACTIONS = {1: "admin.add", 2: "admin.change", 3: "admin.delete"}


def logged(sender: Any, instance: Any, created: bool, **kwargs: Any) -> None:
    """post_save of the admin's LogEntry: one audit entry per change made there."""
    if not created:
        return
    try:
        changed = instance.get_edited_object()
    except (ObjectDoesNotExist, AttributeError):  # deleted, or its model is gone
        changed = None
    model = instance.content_type.model if instance.content_type else ""
    _record(
        instance.user,
        changed,
        ACTIONS.get(instance.action_flag, "admin.change"),
        f"{model} {instance.object_repr}",
        message=instance.get_change_message(),
    )
