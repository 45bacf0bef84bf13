"""The operations page and its JSON API: every process instance and what to watch."""

from __future__ import annotations

from django.contrib.auth.decorators import login_required
from django.core.exceptions import PermissionDenied
from django.http import HttpRequest, HttpResponse
from django.shortcuts import render
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import extend_schema
from rest_framework.decorators import api_view
from rest_framework.request import Request
from rest_framework.response import Response

from . import operations

REFRESH_S = 5


@login_required
def operations_page(request: HttpRequest) -> HttpResponse:
    if not operations.may_see(request.user):
        raise PermissionDenied("The operations page is for operators and admins.")
    return render(
        request,
        "operations/index.html",
        {"figures": operations.gather(), "refresh_s": REFRESH_S},
    )


@extend_schema(
    summary="Process instances, queues, broker and the figures to watch",
    responses={200: OpenApiTypes.OBJECT},
)
@api_view(["GET"])
def operations_api(request: Request) -> Response:
    if not operations.may_see(request.user):
        raise PermissionDenied("The operations figures are for operators and admins.")
    return Response(operations.gather())
