"""The organisation's audit trail: a filtered page and the same entries as CSV.

Every member sees their current organisation's trail (who commanded what is shared
knowledge in a crew); only admins see the callers' addresses and webhook URLs. Nothing
here changes it.
"""

from __future__ import annotations

import csv

from django.contrib.auth.decorators import login_required
from django.core.paginator import Paginator
from django.http import Http404, HttpRequest, HttpResponse, StreamingHttpResponse
from django.shortcuts import render

from config import outbound
from fleet.models import Role
from fleet.tenancy import acting_membership

from . import audit
from .models import AuditEvent


def _membership(request: HttpRequest):  # type: ignore[no-untyped-def]
    membership = acting_membership(request)
    if membership is None:
        raise Http404("You are not a member of any organisation.")
    return membership


@login_required
def audit_page(request: HttpRequest) -> HttpResponse:
    membership = _membership(request)
    events = audit.filtered(membership.organisation, request.GET)
    page = Paginator(events, 100).get_page(request.GET.get("page"))
    query = request.GET.copy()
    query.pop("page", None)
    context = {
        "page": page,
        "kinds": AuditEvent.Kind.choices,
        "filters": request.GET,
        "query": query.urlencode(),
        "with_ip": membership.allows(Role.ADMIN),
    }
    return render(request, "accounts/audit.html", context)


class _Echo:
    def write(self, value: str) -> str:
        return value


@login_required
def audit_csv(request: HttpRequest) -> StreamingHttpResponse:
    membership = _membership(request)
    events = audit.filtered(membership.organisation, request.GET)
    writer = csv.writer(_Echo())
    admin = membership.allows(Role.ADMIN)
    rows = audit.csv_rows(events, with_ip=admin)
    if not admin:  # a webhook URL often holds the receiver's secret: admins only
        rows = ([outbound.hide_urls(cell) for cell in row] for row in rows)
    response = StreamingHttpResponse(
        (writer.writerow(row) for row in rows), content_type="text/csv"
    )
    name = f"{membership.organisation.slug}-audit.csv"
    response["Content-Disposition"] = f'attachment; filename="{name}"'
    return response
