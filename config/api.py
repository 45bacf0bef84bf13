"""One JSON error shape for the whole API, and strict request bodies.

Every error answers `{"error": "<sentence>", "code": "<code>", "fields": {name: [messages]}}`;
a refusal may add its own members (409 `not_airworthy`: `reasons`, a list of sentences).
"""

from __future__ import annotations

from django.core.exceptions import PermissionDenied
from django.http import Http404
from rest_framework import exceptions, serializers
from rest_framework.pagination import LimitOffsetPagination
from rest_framework.response import Response
from rest_framework.views import exception_handler as drf_exception_handler


def _flatten(detail: object) -> dict[str, list[str]]:
    if isinstance(detail, dict):
        out: dict[str, list[str]] = {}
        for key, value in detail.items():
            if isinstance(value, dict):
                for sub, messages in _flatten(value).items():
                    out[f"{key}.{sub}"] = messages
            elif isinstance(value, list):
                out[str(key)] = [str(v) for v in value]
            else:
                out[str(key)] = [str(value)]
        return out
    return {}


def exception_handler(exc: Exception, context: dict) -> Response | None:
    if isinstance(exc, Http404):
        exc = exceptions.NotFound()
    elif isinstance(exc, PermissionDenied):
        exc = exceptions.PermissionDenied()
    response = drf_exception_handler(exc, context)
    if response is None:
        return None
    detail = getattr(exc, "detail", None)
    fields = _flatten(detail) if isinstance(detail, dict) else {}
    if fields:
        first_field, messages = next(iter(fields.items()))
        if first_field == "non_field_errors":
            message = messages[0]
        else:
            message = f"{first_field}: {messages[0]}"
    elif isinstance(detail, list) and detail:
        message = str(detail[0])
    else:
        message = str(detail) if detail is not None else str(exc)
    code = getattr(exc, "default_code", "error")
    if isinstance(detail, exceptions.ErrorDetail):
        code = detail.code or code
    response.data = {"error": message, "code": code, "fields": fields}
    # A refusal may carry more than its sentence (a `not_airworthy` answer's `reasons`).
    extra = getattr(exc, "extra_body", None)
    if isinstance(extra, dict):
        response.data.update({k: v for k, v in extra.items() if k not in response.data})
    return response


class RefusalSerializer(serializers.Serializer):
    """The body of a refusal, as the API schema documents it."""

    error = serializers.CharField(help_text="the refusal in one sentence")
    code = serializers.CharField(help_text="why, e.g. `not_airworthy`")
    fields = serializers.DictField(child=serializers.ListField(child=serializers.CharField()))
    reasons = serializers.ListField(
        child=serializers.CharField(),
        required=False,
        help_text=(
            "with `code: not_airworthy` only: every reason the drone may not fly, as "
            "GET /api/v1/drones/{id}/airworthiness/ lists them"
        ),
    )


class StrictSerializer(serializers.Serializer):
    """Refuses fields it does not know, instead of silently ignoring a typo."""

    def to_internal_value(self, data):  # type: ignore[no-untyped-def]
        if hasattr(data, "keys"):
            known = set(self.fields)
            unknown = sorted(set(data.keys()) - known)
            if unknown:
                raise serializers.ValidationError({name: ["Unknown field."] for name in unknown})
        return super().to_internal_value(data)


class Pagination(LimitOffsetPagination):
    """`?limit=&offset=`, with a cap: an unbounded limit would reach the database as an
    out-of-range LIMIT."""

    default_limit = 100
    max_limit = 1000
