"""The optional second factor: a TOTP authenticator app (django-otp's TOTPDevice).

django-otp brings the device model with clock-drift tolerance, one use per code and a
growing delay after wrong codes; the QR code is drawn as SVG here by `qrcode`, so the
secret never leaves the server. An organisation may require it of its operators and
admins: their session may then change nothing until they signed in with a code.
"""

from __future__ import annotations

import io
from base64 import b32encode
from typing import Any

import qrcode
import qrcode.image.svg
from django.db import transaction
from django_otp import DEVICE_ID_SESSION_KEY
from django_otp.plugins.otp_totp.models import TOTPDevice

from fleet.models import Membership, Role

from . import audit

DEVICE_NAME = "authenticator app"


def device_of(user: Any) -> TOTPDevice | None:
    """The user's confirmed authenticator, if they enrolled one."""
    return TOTPDevice.objects.filter(user=user, confirmed=True).first()


def required_for(user: Any) -> bool:
    """True when an organisation where the user operates or administers requires it."""
    return Membership.objects.filter(
        user=user,
        role__in=(Role.OPERATOR, Role.ADMIN),
        organisation__account_settings__require_second_factor=True,
    ).exists()


def session_verified(request: Any) -> bool:
    """Whether this session signed in (or enrolled) with a one-time code."""
    return _verified(request.user, getattr(request, "session", None))


def _verified(user: Any, session: Any) -> bool:
    device_id = session.get(DEVICE_ID_SESSION_KEY) if session is not None else None
    device = device_of(user) if device_id else None
    return bool(device and device.persistent_id == device_id)


def missing(request: Any) -> bool:
    """The user must use a second factor and this session has not."""
    user = request.user
    return bool(user.is_authenticated and required_for(user) and not session_verified(request))


def owes_second_factor(user: Any, organisation: Any, session: Any) -> bool:
    """The session (a request's or a websocket's) may not move `organisation`'s drones:
    the organisation requires a second factor of its operators and admins, the user is
    one there, and this session has not given a code. Named by the SECOND_FACTOR_CHECK
    setting for the apps that do not import accounts (pastview's teleoperation)."""
    required = Membership.objects.filter(
        user=user,
        organisation=organisation,
        role__in=(Role.OPERATOR, Role.ADMIN),
        organisation__account_settings__require_second_factor=True,
    ).exists()
    return required and not _verified(user, session)


def admin_allowed(request: Any) -> bool:
    """Staff reach the Django admin only from a session that gave its code, when they
    have an authenticator or an organisation of theirs requires one."""
    user = request.user
    needed = device_of(user) is not None or required_for(user)
    return not needed or session_verified(request)


def current_proof(user: Any, form: Any) -> bool:
    """Before the authenticator changes: the current code (`current_code`) of the one
    enrolled, or the password (`password`) when none is, so a borrowed session cannot
    move the second factor to another phone."""
    device = device_of(user)
    if device is not None:
        return check(device, form.get("current_code"))
    return user.check_password(str(form.get("password") or ""))


def start_enrolment(user: Any) -> TOTPDevice:
    """A new unconfirmed authenticator (an earlier unconfirmed one is dropped)."""
    with transaction.atomic():
        TOTPDevice.objects.filter(user=user, confirmed=False).delete()
        return TOTPDevice.objects.create(user=user, name=DEVICE_NAME, confirmed=False)


def pending_enrolment(user: Any) -> TOTPDevice | None:
    return TOTPDevice.objects.filter(user=user, confirmed=False).first()


def check(device: TOTPDevice, code: Any) -> bool:
    """The code is the device's current one (each code works once; wrong ones slow
    further tries down)."""
    code = str(code or "").strip().replace(" ", "")
    return code.isdigit() and device.verify_token(code)


def confirm(user: Any, device: TOTPDevice, code: Any) -> bool:
    """Confirm a new authenticator with its first code; the old one (if any) goes."""
    if not check(device, code):
        return False
    with transaction.atomic():
        TOTPDevice.objects.filter(user=user, confirmed=True).exclude(pk=device.pk).delete()
        device.confirmed = True
        device.save(update_fields=["confirmed"])
        _audit(user, "security.second_factor_on")
    return True


def disable(user: Any) -> None:
    TOTPDevice.objects.filter(user=user).delete()
    _audit(user, "security.second_factor_off")


def _audit(user: Any, action: str) -> None:
    audit.record(
        audit.organisation_ids_of(user),
        audit.Kind.SECURITY,
        action,
        target=user.get_username(),
        actor=user,
    )


def qr_svg(device: TOTPDevice) -> str:
    """The device's otpauth:// URL as an inline SVG QR code."""
    out = io.BytesIO()
    qrcode.make(device.config_url, image_factory=qrcode.image.svg.SvgPathImage).save(out)
    svg = out.getvalue().decode()
    return svg[svg.index("<svg") :]


def secret_of(device: TOTPDevice) -> str:
    """The key in base32, for typing into an app that cannot scan."""
    return b32encode(device.bin_key).decode()


def context(request: Any) -> dict:
    """Template context: `second_factor_missing` when the user must enrol or sign in
    with a code before changing anything."""
    user = getattr(request, "user", None)
    return {"second_factor_missing": bool(user and user.is_authenticated and missing(request))}
