"""REST resources of flight logs: upload, list, search, status, delete, and the series and
analyses the viewer page reads (`/api/v1/logs/`)."""

from __future__ import annotations

import numpy as np
from django.conf import settings
from django.db import transaction
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import OpenApiParameter, extend_schema, inline_serializer
from rest_framework import exceptions, mixins, serializers, status, viewsets
from rest_framework.decorators import action
from rest_framework.permissions import SAFE_METHODS
from rest_framework.request import Request
from rest_framework.response import Response

from fleet.models import Membership, Organisation, Role
from fleet.permissions import OrganisationRole
from fleet.tenancy import acting_organisation
from logs import reports, services, uploads
from logs import spectrum as spectra
from logs.checks import CHECKS, STATUSES
from logs.compare_api import CompareActions
from logs.importers import HEAD_BYTES, pick_importer
from logs.importers.base import LogFormatError
from logs.models import FlightLog, LogStatus
from logs.store import LogStore

MAX_TIMELINE_BINS = 4000
MAX_SPECTRUM_SERIES = 6


class NotReady(exceptions.APIException):
    status_code = status.HTTP_409_CONFLICT
    default_code = "not_ready"
    default_detail = "The log is not ready: it is still processing or it failed."


def _query(name: str, kind: OpenApiTypes, text: str, required: bool = False) -> OpenApiParameter:
    return OpenApiParameter(name, kind, OpenApiParameter.QUERY, required=required, description=text)


START = _query("start", OpenApiTypes.DOUBLE, "From this time (seconds on the log's clock).")
END = _query("end", OpenApiTypes.DOUBLE, "Up to this time (seconds on the log's clock).")
NUMBERS = serializers.ListField(child=serializers.FloatField(allow_null=True))
SERIES_INFO = inline_serializer(
    "FlightLogSeriesInfo",
    {
        "path": serializers.CharField(),
        "unit": serializers.CharField(help_text="The display unit (m, m/s, °, %, V, A…)."),
        "recorded_unit": serializers.CharField(help_text="The unit the file recorded."),
        "count": serializers.IntegerField(),
        "start": serializers.FloatField(allow_null=True),
        "end": serializers.FloatField(allow_null=True),
        "kind": serializers.CharField(),
        "time_source": serializers.CharField(),
        "labels": serializers.DictField(child=serializers.CharField(), allow_null=True),
    },
)
CHECK_RESULT = inline_serializer(
    "FlightLogCheck",
    {
        "check": serializers.ChoiceField(
            list(CHECKS), help_text="The check's stable name (docs/log-checks.md)."
        ),
        "name": serializers.CharField(help_text="The same as `check`."),
        "status": serializers.ChoiceField(list(STATUSES)),
        "value": serializers.FloatField(allow_null=True),
        "unit": serializers.CharField(),
        "threshold": serializers.DictField(allow_null=True),
        "t": serializers.FloatField(
            allow_null=True, help_text="Seconds since the log's start where it shows."
        ),
        "reason": serializers.CharField(),
        "series": serializers.ListField(child=serializers.CharField()),
        "window": serializers.ListField(child=serializers.FloatField(), allow_null=True),
        "link": serializers.CharField(help_text="The viewer at that moment, on that plot."),
    },
)
SPECTRUM = inline_serializer(
    "FlightLogSpectrumSeries",
    {
        "path": serializers.CharField(),
        "unit": serializers.CharField(),
        "fs": serializers.FloatField(),
        "nperseg": serializers.IntegerField(),
        "segments": serializers.IntegerField(),
        "segments_available": serializers.IntegerField(),
        "frequency": NUMBERS,
        "psd": NUMBERS,
    },
)


class LogPermission(OrganisationRole):
    """Reads need no second membership query: the queryset only holds logs of the user's
    organisations (outsiders get 404). Writes still need the operator role."""

    def has_object_permission(self, request, view, obj) -> bool:  # type: ignore[no-untyped-def]
        if request.method in SAFE_METHODS:
            return True
        return super().has_object_permission(request, view, obj)


class FlightLogSerializer(serializers.ModelSerializer):
    owner = serializers.SlugRelatedField(slug_field="username", read_only=True)
    organisation = serializers.SlugRelatedField(slug_field="slug", read_only=True)
    url = serializers.CharField(source="get_absolute_url", read_only=True)
    start = serializers.FloatField(source="start_s", read_only=True)
    end = serializers.FloatField(source="end_s", read_only=True)
    duration = serializers.FloatField(source="duration_s", read_only=True)

    class Meta:
        model = FlightLog
        fields = [
            "id",
            "name",
            "size",
            "status",
            "progress",
            "error",
            "format",
            "series_count",
            "start",
            "end",
            "duration",
            "organisation",
            "owner",
            "created_at",
            "processed_at",
            "url",
        ]
        read_only_fields = fields


def _points(raw: str | None, *, default: int | None = None) -> int | None:
    if raw in (None, ""):
        return default
    limit = int(settings.LOGS_MAX_PLOT_POINTS)
    try:
        points = int(raw)
    except ValueError:
        raise exceptions.ValidationError({"points": ["Must be a whole number."]}) from None
    if not 1 <= points <= limit:
        raise exceptions.ValidationError({"points": [f"Must be between 1 and {limit}."]})
    return points


def _seconds(request: Request, name: str) -> float | None:
    try:
        return services.parse_float(request.query_params.get(name), name)
    except ValueError as exc:
        raise exceptions.ValidationError({name: [str(exc)]}) from None


def _upload_organisation(request: Request) -> Organisation:
    """The organisation an upload goes to: the `organisation` field (slug) if given, else
    the one the portal acts for, else the user's only membership; operators and up."""
    membership = chosen_membership(request, request.data.get("organisation") or "")
    if not membership.allows(Role.OPERATOR):
        raise exceptions.PermissionDenied("Uploading logs needs the operator role.")
    return membership.organisation


def chosen_membership(request: Request, slug: str) -> Membership:
    """The membership of the organisation named by `slug`, else of the one the portal acts
    for, else the user's only one."""
    memberships = Membership.objects.for_user(request.user)
    # Only a portal (session) request acts for one organisation; a token acts for none.
    current = acting_organisation(request._request) if request.auth is None else None
    if slug:
        memberships = memberships.filter(organisation__slug=slug)
    elif current is not None:
        memberships = memberships.filter(organisation=current)
    elif memberships.count() > 1:
        raise exceptions.ValidationError(
            {"organisation": ["You belong to several organisations: name one (its slug)."]}
        )
    membership = memberships.first()
    if membership is None:
        raise exceptions.NotFound("You are not a member of that organisation.")
    return membership


class FlightLogViewSet(
    CompareActions, mixins.ListModelMixin, mixins.DestroyModelMixin, viewsets.GenericViewSet
):
    """Flight logs of the user's organisations. `?q=` searches names, formats and owners;
    `?status=` filters. Viewers read; operators upload and delete."""

    permission_classes = [LogPermission]
    serializer_class = FlightLogSerializer
    lookup_value_regex = "[0-9a-fA-F-]{32,36}"

    def initialize_request(self, request, *args, **kwargs):  # type: ignore[no-untyped-def]
        # Before anything reads the body (the CSRF check reads request.POST), so uploads
        # stream to the logs folder and stop at the limit.
        if request.method == "POST" and "pk" not in kwargs:
            uploads.install(request)
        return super().initialize_request(request, *args, **kwargs)

    def initial(self, request: Request, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        if request.method == "POST":
            uploads.check_content_length(request._request)
        super().initial(request, *args, **kwargs)

    def get_queryset(self):  # type: ignore[no-untyped-def]
        queryset = FlightLog.objects.for_user(self.request.user).select_related(
            "organisation", "owner"
        )
        if self.action == "list":
            queryset = queryset.search(self.request.query_params.get("q", ""))
            wanted = self.request.query_params.get("status")
            if wanted in LogStatus.values:
                queryset = queryset.filter(status=wanted)
        return queryset

    @extend_schema(
        request={
            "multipart/form-data": inline_serializer(
                "FlightLogUpload",
                {
                    "file": serializers.FileField(),
                    "organisation": serializers.SlugField(required=False),
                },
            )
        },
        responses={
            201: inline_serializer(
                "FlightLogUploaded",
                {
                    "id": serializers.UUIDField(),
                    "status": serializers.CharField(),
                    "url": serializers.CharField(),
                },
            )
        },
    )
    def create(self, request: Request) -> Response:
        upload = request.FILES.get(uploads.FIELD)
        if upload is None:
            raise exceptions.ValidationError({"file": ["Choose a flight log file to upload."]})
        try:
            if not upload.size:
                raise exceptions.ValidationError({"file": ["The file is empty."]})
            with open(upload.path, "rb") as f:
                head = f.read(HEAD_BYTES)
            try:
                pick_importer(upload.path.with_name(upload.name or "log"), head)
            except LogFormatError as exc:
                raise exceptions.ValidationError(
                    {"file": [str(exc)]}, code="unsupported_format"
                ) from None
            organisation = _upload_organisation(request)
            with transaction.atomic():
                log = services.create_log(
                    organisation=organisation, owner=request.user, upload=upload
                )
        finally:
            upload.discard()  # a no-op once create_log moved it into place
        return Response(
            {"id": str(log.pk), "status": log.status, "url": log.get_absolute_url()},
            status=status.HTTP_201_CREATED,
        )

    @extend_schema(
        responses=inline_serializer(
            "FlightLogDetail",
            {
                **FlightLogSerializer().get_fields(),
                "owner": serializers.CharField(allow_null=True),
                "organisation": serializers.CharField(),
                "series": serializers.ListField(child=SERIES_INFO),
                "layers": serializers.ListField(child=serializers.DictField()),
                "special": serializers.DictField(
                    child=serializers.ListField(child=serializers.CharField())
                ),
                "warnings": serializers.ListField(child=serializers.CharField()),
            },
        )
    )
    def retrieve(self, request: Request, pk: str | None = None) -> Response:
        log = self.get_object()
        body = dict(FlightLogSerializer(log).data)
        body.update(series=[], layers=[], special={}, warnings=[])
        if log.status == LogStatus.READY:
            store = self._store(log)
            body.update(
                series=services.series_list(store),
                layers=store.index["layers"],
                special=store.special,
                warnings=store.index["warnings"][:200],
                metadata=store.index["metadata"],
            )
        return Response(body)

    def perform_destroy(self, instance: FlightLog) -> None:
        services.delete_log(instance)

    def _store(self, log: FlightLog) -> LogStore:
        if log.status != LogStatus.READY:
            raise NotReady()
        try:
            return services.store_of(log)
        except (OSError, ValueError) as exc:
            raise exceptions.APIException(
                "The processed data of this log is missing; upload it again."
            ) from exc

    @extend_schema(
        parameters=[
            _query("path", OpenApiTypes.STR, "The series, e.g. navdata/Altitude.", required=True),
            START,
            END,
            _query(
                "points",
                OpenApiTypes.INT,
                "Buckets for min/max level of detail; all samples when absent.",
            ),
        ],
        responses=inline_serializer(
            "FlightLogSeriesData",
            {
                "t": serializers.ListField(child=serializers.FloatField()),
                "v": serializers.ListField(),
                "unit": serializers.CharField(help_text="The unit of `v` (converted)."),
            },
        ),
    )
    @action(detail=True, methods=["get"])
    def series(self, request: Request, pk: str | None = None) -> Response:
        """`?path=&start=&end=&points=` → {"t": [seconds], "v": [values]}: every sample in
        the range, or min/max per bucket when `points` is given."""
        store = self._store(self.get_object())
        path = request.query_params.get("path")
        if not path:
            raise exceptions.ValidationError({"path": ["Name the series to read."]})
        if path not in store.index["series"]:
            raise exceptions.NotFound(f"There is no series {path!r} in this log.")
        return Response(
            services.plot(
                store,
                path,
                start=_seconds(request, "start"),
                end=_seconds(request, "end"),
                points=_points(request.query_params.get("points")),
            )
        )

    @extend_schema(
        parameters=[_query("t", OpenApiTypes.DOUBLE, "The time (seconds).", required=True)],
        responses=inline_serializer(
            "FlightLogValuesAt", {"t": serializers.FloatField(), "values": serializers.DictField()}
        ),
    )
    @action(detail=True, methods=["get"])
    def values(self, request: Request, pk: str | None = None) -> Response:
        """`?t=` → every value at or before t, nested by group: {"t", "values": {...}}."""
        store = self._store(self.get_object())
        t = _seconds(request, "t")
        if t is None:
            raise exceptions.ValidationError({"t": ["Give the time in seconds."]})
        return Response({"t": t, "values": services.values_at_time(store, t)})

    @extend_schema(
        parameters=[
            START,
            END,
            _query("bins", OpenApiTypes.INT, "Equal time slices (default 1000)."),
        ],
        responses=inline_serializer(
            "FlightLogTimeline",
            {
                "start": serializers.FloatField(allow_null=True),
                "end": serializers.FloatField(allow_null=True),
                "bins": serializers.IntegerField(),
                "layers": serializers.ListField(child=serializers.DictField()),
            },
        ),
    )
    @action(detail=True, methods=["get"])
    def timeline(self, request: Request, pk: str | None = None) -> Response:
        """`?start=&end=&bins=` → per layer, how many samples fall in each of `bins` equal
        time slices: what the timeline draws, whatever the log's length."""
        store = self._store(self.get_object())
        index = store.index
        start = _seconds(request, "start")
        end = _seconds(request, "end")
        start = index["start"] if start is None else start
        end = index["end"] if end is None else end
        bins = _points(request.query_params.get("bins"), default=1000) or 1000
        bins = min(bins, MAX_TIMELINE_BINS)
        if start is None or end is None or end <= start:
            return Response({"start": start, "end": end, "layers": []})
        edges = np.linspace(start, end, bins + 1) * 1e9
        layers = []
        times_by_layer = services.layer_times(store)
        for layer in index["layers"]:
            times = times_by_layer.get(layer["name"])
            if times is None:
                continue
            cuts = np.searchsorted(times, edges)
            cuts[-1] = np.searchsorted(times, edges[-1], side="right")  # the end is inside
            layers.append({"name": layer["name"], "counts": np.diff(cuts).tolist()})
        return Response({"start": start, "end": end, "bins": bins, "layers": layers})

    @extend_schema(
        parameters=[
            _query("points", OpenApiTypes.INT, "At most this many positions (default 2000).")
        ],
        responses=inline_serializer(
            "FlightLogTrack",
            {
                "source": serializers.ChoiceField(["gps", "estimated"], allow_null=True),
                "t": NUMBERS,
                "lat": NUMBERS,
                "lon": NUMBERS,
                "x": NUMBERS,
                "y": NUMBERS,
                "unit": serializers.CharField(),
                "tracks": serializers.ListField(child=serializers.DictField()),
            },
        ),
    )
    @action(detail=True, methods=["get"])
    def track(self, request: Request, pk: str | None = None) -> Response:
        """The GPS path, or the trajectory estimated from velocity and yaw without GPS."""
        store = self._store(self.get_object())
        points = _points(request.query_params.get("points"), default=2000) or 2000
        return Response(services.track(store, points=points))

    @extend_schema(
        parameters=[
            _query("points", OpenApiTypes.INT, "At most this many samples (default 4000).")
        ],
        responses=inline_serializer(
            "FlightLogAttitude",
            {"t": NUMBERS, "roll": NUMBERS, "pitch": NUMBERS, "yaw": NUMBERS},
        ),
    )
    @action(detail=True, methods=["get"])
    def attitude(self, request: Request, pk: str | None = None) -> Response:
        """Roll, pitch and yaw in radians for the 3D view (applied yaw, then pitch, then roll)."""
        store = self._store(self.get_object())
        points = _points(request.query_params.get("points"), default=4000) or 4000
        return Response(services.attitude(store, points=points))

    @extend_schema(
        responses=inline_serializer(
            "FlightLogChecks",
            {
                "checked_at": serializers.DateTimeField(),
                "airframe": serializers.CharField(allow_null=True),
                "checks": serializers.ListField(child=CHECK_RESULT),
            },
        )
    )
    @action(detail=True, methods=["get"])
    def checks(self, request: Request, pk: str | None = None) -> Response:
        """The log's health report: each automatic check (vibration, clipping, gps,
        battery_sag, rc_loss, motor_imbalance, estimator, failsafe, cpu_load,
        logging_dropouts) with its status, figure, threshold, the time it shows and a
        link opening the viewer there (docs/log-checks.md)."""
        log = self.get_object()
        store = self._store(log)
        report = reports.report_of(log, store)
        checks = [
            {"check": c["name"], **c, "link": reports.viewer_link(log, c)} for c in report["checks"]
        ]
        return Response(
            {"checked_at": report["checked_at"], "airframe": report["airframe"], "checks": checks}
        )

    @extend_schema(
        parameters=[
            _query(
                "series",
                OpenApiTypes.STR,
                f"Series paths, comma-separated (at most {MAX_SPECTRUM_SERIES}).",
                required=True,
            ),
            START,
            END,
            _query(
                "nperseg",
                OpenApiTypes.INT,
                f"Samples per Welch segment, {spectra.MIN_NPERSEG}-{spectra.MAX_NPERSEG} "
                f"(default {spectra.DEFAULT_NPERSEG}, halved until a short window holds one).",
            ),
        ],
        responses=inline_serializer(
            "FlightLogSpectrum",
            {
                "start": serializers.FloatField(allow_null=True),
                "end": serializers.FloatField(allow_null=True),
                "series": serializers.ListField(child=SPECTRUM),
            },
        ),
    )
    @action(detail=True, methods=["get"])
    def spectrum(self, request: Request, pk: str | None = None) -> Response:
        """`?series=&start=&end=&nperseg=` → the power spectral density (Welch) of each
        series over the window (the whole log when absent); at most
        LOGS_SPECTRUM_MAX_SEGMENTS segments are read, spread over the window."""
        store = self._store(self.get_object())
        paths = [p for p in (request.query_params.get("series") or "").split(",") if p]
        if not paths:
            raise exceptions.ValidationError({"series": ["Name the series to analyse."]})
        if len(paths) > MAX_SPECTRUM_SERIES:
            raise exceptions.ValidationError(
                {"series": [f"At most {MAX_SPECTRUM_SERIES} series at once."]}
            )
        for path in paths:
            if path not in store.index["series"]:
                raise exceptions.NotFound(f"There is no series {path!r} in this log.")
        start, end = _seconds(request, "start"), _seconds(request, "end")
        raw = request.query_params.get("nperseg")
        try:
            nperseg = int(raw) if raw not in (None, "") else None
        except ValueError:
            raise exceptions.ValidationError({"nperseg": ["Must be a whole number."]}) from None
        out = []
        for path in paths:
            try:
                result = spectra.spectrum(
                    store,
                    path,
                    start=start,
                    end=end,
                    nperseg=nperseg,
                    max_segments=int(settings.LOGS_SPECTRUM_MAX_SEGMENTS),
                )
            except spectra.SpectrumError as exc:
                raise exceptions.ValidationError({"series": [str(exc)]}) from None
            out.append(result.to_dict())
        return Response({"start": start, "end": end, "series": out})
