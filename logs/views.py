"""The Logs pages: the list with upload and search, one log's viewer, logs side by side."""

from __future__ import annotations

import uuid

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import FileResponse, Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, render

from fleet.models import Drone, Role
from fleet.tenancy import acting_membership, acting_organisation
from logs import reports
from logs.models import FlightLog, LogStatus
from logs.uploads import human_bytes

MAX_COMPARED = 4


@login_required
def log_list(request: HttpRequest) -> HttpResponse:
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    logs = FlightLog.objects.filter(organisation=organisation).select_related("owner")
    query = request.GET.get("q", "").strip()
    logs = logs.search(query)
    wanted = request.GET.get("status", "")
    if wanted in LogStatus.values:
        logs = logs.filter(status=wanted)
    membership = acting_membership(request)
    shown = list(logs[:500])
    reports.summaries(shown)
    return render(
        request,
        "logs/list.html",
        {
            "logs": shown,
            "q": query,
            "status": wanted,
            "statuses": LogStatus.choices,
            "can_upload": membership.allows(Role.OPERATOR),
            "upload_limit": human_bytes(settings.LOG_UPLOAD_MAX_BYTES),
            "upload_limit_bytes": settings.LOG_UPLOAD_MAX_BYTES,
            "upload_concurrent": settings.UPLOAD_MAX_CONCURRENT,
        },
    )


@login_required
def log_detail(request: HttpRequest, pk: uuid.UUID) -> HttpResponse:
    # Any member of the log's organisation may open the link; outsiders get 404.
    log = get_object_or_404(
        FlightLog.objects.for_user(request.user).select_related("organisation", "owner", "drone"),
        pk=pk,
    )
    membership = log.organisation.memberships.filter(user=request.user).first()
    return render(
        request,
        "logs/detail.html",
        {
            "log": log,
            "logs": [log],
            "can_delete": bool(membership and membership.allows(Role.OPERATOR)),
            "share_url": request.build_absolute_uri(log.get_absolute_url()),
            "others": FlightLog.objects.filter(
                organisation=log.organisation, status=LogStatus.READY
            ).exclude(pk=log.pk)[:50],
            # An operator names the drone that flew the log (its trends: logs/trends.py).
            "drones": Drone.objects.filter(organisation=log.organisation)
            if membership and membership.allows(Role.OPERATOR)
            else [],
        },
    )


@login_required
def log_download(request: HttpRequest, pk: uuid.UUID) -> FileResponse:
    """The file as it was uploaded, for members of the log's organisation."""
    log = get_object_or_404(FlightLog.objects.for_user(request.user), pk=pk)
    try:
        handle = open(log.upload_path, "rb")  # noqa: SIM115 - FileResponse closes it
    except FileNotFoundError:
        raise Http404("The uploaded file is no longer stored.") from None
    return FileResponse(handle, as_attachment=True, filename=log.name)


@login_required
def log_compare(request: HttpRequest) -> HttpResponse:
    """`?ids=<uuid>,<uuid>,…` (or `?pick=` repeated, from the list's form): up to four logs, each with its own viewer, side by side."""
    ids: list[uuid.UUID] = []
    wanted = request.GET.get("ids", "").replace(" ", "").split(",") + request.GET.getlist("pick")
    for raw in wanted:
        try:
            ids.append(uuid.UUID(raw))
        except ValueError:
            continue
    ids = list(dict.fromkeys(ids))[:MAX_COMPARED]
    found = {log.pk: log for log in FlightLog.objects.for_user(request.user).filter(pk__in=ids)}
    if not ids or len(found) != len(ids):
        raise Http404("One of these logs does not exist or is not yours to see.")
    return render(
        request,
        "logs/compare.html",
        {"logs": [found[i] for i in ids]},
    )
