"""Logbook pages: a drone's and a member's flights with totals by month or year, and
their CSV export. Each page acts for the request's current organisation."""

from __future__ import annotations

from datetime import datetime

from django.conf import settings
from django.contrib.auth import get_user_model
from django.contrib.auth.decorators import login_required
from django.core.paginator import Paginator
from django.db.models import QuerySet
from django.http import Http404, HttpRequest, HttpResponse, StreamingHttpResponse
from django.shortcuts import get_object_or_404, render
from django.utils import timezone

from fleet.models import Drone, Membership
from fleet.tenancy import acting_organisation
from logs.collection import logs_of_flight

from . import logbook, pdf
from .models import FlightRecord

PAGE_SIZE = 50


def _organisation_or_404(request: HttpRequest):  # type: ignore[no-untyped-def]
    organisation = acting_organisation(request)
    if organisation is None:
        raise Http404("You are not a member of any organisation.")
    return organisation


@login_required
def drone_logbook(request: HttpRequest, drone_id: str) -> HttpResponse:
    organisation = _organisation_or_404(request)
    drone = get_object_or_404(Drone, organisation=organisation, drone_id=drone_id)
    records = FlightRecord.objects.filter(organisation=organisation, drone_ident=drone.drone_id)
    return _logbook(request, records, kind="drone", subject=drone.drone_id)


@login_required
def pilot_logbook(request: HttpRequest, username: str) -> HttpResponse:
    """Any member's logbook, for every member: records are the organisation's."""
    organisation = _organisation_or_404(request)
    user = get_object_or_404(get_user_model(), username=username)
    if not Membership.objects.filter(user=user, organisation=organisation).exists():
        raise Http404("No such member.")
    records = FlightRecord.objects.filter(organisation=organisation, pilot_name=username)
    return _logbook(request, records, kind="pilot", subject=username)


def _logbook(request: HttpRequest, records: QuerySet, *, kind: str, subject: str) -> HttpResponse:
    period = request.GET.get("period") or "month"
    if period not in logbook.PERIODS:
        raise Http404("Unknown period.")
    try:
        records = logbook.filtered(records.current(), request.GET)
    except logbook.BadFilter as exc:
        raise Http404(str(exc)) from None
    if request.GET.get("format") == "csv":
        return _csv(records, f"logbook-{kind}-{subject}")
    if request.GET.get("format") == "pdf":
        return _pdf(records, f"logbook-{kind}-{subject}")
    page = Paginator(records.order_by("-started_at", "-id"), PAGE_SIZE).get_page(
        request.GET.get("page")
    )
    params = request.GET.copy()
    params.pop("page", None)
    return render(
        request,
        "records/logbook.html",
        {
            "kind": kind,
            "subject": subject,
            "page": page,
            "period": period,
            "periods": list(logbook.PERIODS),
            "totals": logbook.totals(records, period),
            "overall": logbook.grand_total(records),
            "since": request.GET.get("since", ""),
            "until": request.GET.get("until", ""),
            "keep": params.urlencode(),
            "export_limit": settings.RECORDS_EXPORT_MAX_ROWS,
            "pdf_limit": settings.RECORDS_PDF_MAX_FLIGHTS,
        },
    )


def _csv(records: QuerySet, name: str) -> StreamingHttpResponse:
    """At most RECORDS_EXPORT_MAX_ROWS flights, newest first, streamed."""
    rows = records.order_by("-started_at", "-id")[: settings.RECORDS_EXPORT_MAX_ROWS]
    response = StreamingHttpResponse(
        logbook.csv_lines(rows.iterator(chunk_size=500)), content_type="text/csv; charset=utf-8"
    )
    stamp = timezone.localtime().strftime("%Y%m%d")
    response["Content-Disposition"] = f'attachment; filename="{name}-{stamp}.csv"'
    return response


def _pdf(records: QuerySet, name: str) -> HttpResponse:
    """At most RECORDS_PDF_MAX_FLIGHTS flights, newest first, a page each."""
    rows = records.order_by("-started_at", "-id")[: settings.RECORDS_PDF_MAX_FLIGHTS]
    response = HttpResponse(pdf.logbook_pdf(rows), content_type="application/pdf")
    stamp = timezone.localtime().strftime("%Y%m%d")
    response["Content-Disposition"] = f'attachment; filename="{name}-{stamp}.pdf"'
    return response


@login_required
def flight_detail(request: HttpRequest, pk: int) -> HttpResponse:
    organisation = _organisation_or_404(request)
    record = get_object_or_404(FlightRecord, organisation=organisation, pk=pk)
    if request.GET.get("format") == "pdf":
        return _pdf(FlightRecord.objects.filter(pk=record.pk), f"flight-{record.pk}")
    return render(
        request,
        "records/flight.html",
        {
            "record": record,
            "track_svg": track_svg(record.track),
            "events": _events(record),
            "logs": logs_of_flight(record.drone_id, record.started_at, record.ended_at),
        },
    )


def _events(record: FlightRecord) -> list[dict]:
    """The record's events with their times as datetimes, shown in the portal's zone."""
    out = []
    for event in record.events:
        try:
            at = datetime.fromisoformat(str(event.get("at")))
        except ValueError:
            at = None
        out.append({**event, "at": at})
    return out


SVG_SIZE = 320
SVG_MARGIN = 10


def track_svg(track: list) -> dict | None:
    """The track seen from above (north up) as SVG polyline points, scaled to fit."""
    points = [(p[2], p[1]) for p in track if isinstance(p, list) and len(p) >= 4]
    if len(points) < 2:
        return None
    east = [p[0] for p in points]
    north = [p[1] for p in points]
    span = max(max(east) - min(east), max(north) - min(north), 1.0)
    scale = (SVG_SIZE - 2 * SVG_MARGIN) / span
    xy = [
        (SVG_MARGIN + (e - min(east)) * scale, SVG_SIZE - SVG_MARGIN - (n - min(north)) * scale)
        for e, n in points
    ]
    return {
        "size": SVG_SIZE,
        "points": " ".join(f"{x:.1f},{y:.1f}" for x, y in xy),
        "start": xy[0],
        "end": xy[-1],
        "span_m": round(span, 1),
    }
