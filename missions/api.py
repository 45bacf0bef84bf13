"""REST resources of missions, filtered to the user's organisations.

Bodies are validated by the domain (planning, onboard.protocol) so the API and the drone
agree on what a valid step is; every refusal answers the project's error shape with the
offending field named.
"""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.http import HttpResponse
from drf_spectacular.types import OpenApiTypes
from drf_spectacular.utils import (
    OpenApiParameter,
    OpenApiResponse,
    extend_schema,
    inline_serializer,
)
from rest_framework import exceptions, serializers, status, viewsets
from rest_framework.decorators import action
from rest_framework.request import Request
from rest_framework.response import Response

from airspace import separation
from config.api import RefusalSerializer
from config.throttling import COMMAND_THROTTLES, MISSION_START_THROTTLES
from fleet import envelopes
from fleet.models import Drone, Membership, Organisation, Role
from fleet.permissions import OrganisationRole, require_role
from fleet.signals import note_refusal
from fleet.tenancy import current_membership
from missions.creation import create_mission, validate_steps
from missions.errors import MissionError
from missions.startstop import start_mission, stop_mission
from terrain.guard import has_terrain
from terrain.profile import profile as height_profile

from . import following, hold, logs, panic, pictures, plan_files, planning, qgc_plan
from .models import Mission, Picture
from .serializers import (
    MissionDetailSerializer,
    MissionSerializer,
    PictureSerializer,
    StepSerializer,
)

# A QGroundControl plan of thousands of items is a few MiB; anything bigger is not a plan.
MAX_PLAN_BYTES = 8 * 1024 * 1024


class Refused(exceptions.APIException):
    status_code = status.HTTP_400_BAD_REQUEST
    default_code = "invalid"

    def __init__(
        self, field: str, message: str, status_code: int = 400, code: str | None = None
    ) -> None:
        super().__init__({field: [message]})
        self.status_code = status_code
        if status_code != 400:
            self.default_code = {404: "not_found", 409: "conflict", 413: "too_large"}.get(
                status_code, "refused"
            )
        if code:
            self.default_code = code


def refuse(exc: MissionError | planning.PlanningError) -> Refused:
    if isinstance(exc, MissionError):
        refused = Refused(exc.field, exc.message, exc.status, exc.code)
        if exc.reasons is not None:
            refused.extra_body = {"reasons": exc.reasons}  # type: ignore[attr-defined]
        return refused
    return Refused(exc.field, exc.message, 400)


def _body(request: Request) -> dict:
    if not isinstance(request.data, dict):
        raise Refused("body", "must be a JSON object")
    return request.data


CONFIRM_FIELD = "confirm_beyond_defaults"
CONFIRM_HELP = (
    "The operator confirmed steps beyond the envelope's defaults (120 m high, 1000 m from "
    "home); without it such a mission answers 409 confirmation_required naming the step."
)


def _confirmed(data: Any) -> bool:
    """The body's confirmation flag: JSON true or false, or true/false (1/0, yes/no, on/off)
    in a form; anything else is refused naming the field."""
    value = data.get(CONFIRM_FIELD) if hasattr(data, "get") else None
    if value is None or isinstance(value, bool):
        return bool(value)
    text = str(value).strip().lower()
    if text not in ("true", "1", "yes", "on", "false", "0", "no", "off", ""):
        raise Refused(CONFIRM_FIELD, "must be true or false")
    return text in ("true", "1", "yes", "on")


def _organisation_for_write(request: Request, slug: object = None) -> Organisation:
    """The organisation named in the body (slug), else the portal's current one; the
    user must be an operator there."""
    if slug is not None:
        membership = (
            Membership.objects.for_user(request.user).filter(organisation__slug=slug).first()
        )
        if membership is None:
            raise Refused("organisation", f"you are not a member of {slug!r}", 404)
    else:
        membership = current_membership(request)
        if membership is None:
            raise Refused("organisation", "you are not a member of any organisation", 403)
    if not membership.allows(Role.OPERATOR):
        raise exceptions.PermissionDenied("Operators and admins only.")
    return membership.organisation


CoverageRequest = inline_serializer(
    "CoverageRequest",
    {
        "vertices": serializers.ListField(
            child=serializers.ListField(child=serializers.FloatField())
        ),
        "step_distance": serializers.FloatField(),
        "line_spacing": serializers.FloatField(
            required=False, help_text="metres between lines (default: step_distance)"
        ),
        "altitude": serializers.FloatField(required=False),
        "terrain_following": serializers.JSONField(
            required=False,
            help_text='{"home": [lat, lon], "tolerance_m": 10}: also answer `followed`, the '
            "path at `altitude` above the terrain (docs/airspace.md)",
        ),
    },
)
CoverageResponse = inline_serializer(
    "CoverageResponse",
    {
        "waypoints": serializers.ListField(child=serializers.ListField()),
        "area_m2": serializers.FloatField(),
        "vectors": serializers.DictField(),
        "step_distance": serializers.FloatField(),
        "shape": serializers.ListField(child=serializers.IntegerField()),
        "followed": serializers.ListField(
            child=serializers.DictField(),
            required=False,
            help_text="with terrain_following: lat, lon, height_m (above home), waypoint, "
            "speed_m_s of every point of the path",
        ),
    },
)
ExtendRequest = inline_serializer(
    "ExtendRequest",
    {
        "vertices": serializers.ListField(
            child=serializers.ListField(child=serializers.FloatField())
        ),
        "step_distance": serializers.FloatField(),
        "altitude": serializers.FloatField(required=False),
        "center": serializers.ListField(child=serializers.FloatField()),
        "joining_drones": serializers.IntegerField(),
    },
)
ExtendResponse = inline_serializer(
    "ExtendResponse",
    {
        "waypoints": serializers.ListField(child=serializers.ListField()),
        "area_m2": serializers.FloatField(),
        "target_area_m2": serializers.FloatField(),
        "parts": serializers.ListField(child=serializers.ListField()),
    },
)
CreateRequest = inline_serializer(
    "MissionCreateRequest",
    {
        "name": serializers.CharField(required=False),
        "organisation": serializers.SlugField(required=False),
        "altitude": serializers.FloatField(required=False),
        "steps": serializers.ListField(child=serializers.DictField(), required=False),
        "coverage": inline_serializer(
            "MissionCoverage",
            {
                "vertices": serializers.ListField(child=serializers.ListField()),
                "step_distance": serializers.FloatField(),
                "line_spacing": serializers.FloatField(required=False),
                "intermediate_action": serializers.JSONField(required=False),
                "terrain_following": serializers.JSONField(
                    required=False,
                    help_text='{"home": [lat, lon], "tolerance_m": 10}: fly `altitude` above '
                    "the imported terrain instead of above home (points are added where the "
                    "ground departs from a leg by more than the tolerance)",
                ),
            },
        ),
        "extensibility": serializers.DictField(required=False),
        CONFIRM_FIELD: serializers.BooleanField(required=False, help_text=CONFIRM_HELP),
    },
)
StartRequest = inline_serializer(
    "MissionStartRequest",
    {
        "drone": serializers.CharField(required=False, allow_null=True),
        CONFIRM_FIELD: serializers.BooleanField(required=False, help_text=CONFIRM_HELP),
    },
)
HoldRequest = inline_serializer(
    "MissionHoldRequest",
    {
        "drone": serializers.CharField(
            required=False, help_text="only this drone of the mission holds or resumes"
        )
    },
)
PanicRequest = inline_serializer(
    "PanicRequest",
    {
        "lat": serializers.FloatField(),
        "lon": serializers.FloatField(),
        CONFIRM_FIELD: serializers.BooleanField(required=False, help_text=CONFIRM_HELP),
    },
)


def _altitude(body: dict) -> float:
    altitude = body.get("altitude", 10.0)
    if isinstance(altitude, bool) or not isinstance(altitude, int | float):
        raise Refused("altitude", "must be a number of metres")
    if not 0.5 <= altitude <= 1000:
        raise Refused("altitude", "must be between 0.5 and 1000 m")
    return float(altitude)


def _checked_home(organisation: Organisation, steps: list, drone: Drone | None) -> list | None:
    """The home a checked plan is flown from: the drone's, else the plan's."""
    if drone is not None:
        return envelopes.home_of(drone)
    return envelopes.plan_home(organisation, steps)


def _steps_from_coverage(
    spec: object, altitude: float, max_waypoints: int
) -> tuple[list, dict, list | None]:
    """A coverage spec → mission steps, the extensibility parameters to keep and the plan
    home (a terrain-following coverage is placed from its own home)."""
    if not isinstance(spec, dict):
        raise Refused("coverage", "must be an object with vertices and step_distance")
    home = None
    try:
        area = planning.coverage(
            spec.get("vertices"),
            spec.get("step_distance"),
            line_spacing=spec.get("line_spacing"),
            max_waypoints=max_waypoints,
        )
        action = spec.get("intermediate_action")
        if spec.get(following.FIELD) is not None:
            steps, home, kept = following.coverage_steps(
                spec[following.FIELD],
                area.waypoints,
                altitude,
                action,
                max_waypoints,
                settings.MISSIONS_SURVEY_SPEED_M_S,
            )
        else:
            steps = planning.mission_steps(
                area.waypoints, altitude=altitude, intermediate_action=action
            )
            kept = None
    except planning.PlanningError as exc:
        raise Refused(f"coverage.{exc.field}", exc.message) from None
    extensibility = {
        "vertices": spec.get("vertices"),
        "vectors": area.vectors.to_dict(),
        "step_distance": area.step_distance,
        "intermediate_action": action,
        "area_m2": area.area_m2,
    }
    if kept:
        extensibility[following.FIELD] = kept
    return steps, extensibility, home


class MissionViewSet(viewsets.ReadOnlyModelViewSet):
    """Missions of the user's organisations: plan, create, start, stop, follow, export."""

    permission_classes = [OrganisationRole]

    def get_queryset(self):  # type: ignore[no-untyped-def]
        queryset = Mission.objects.for_user(self.request.user).select_related("organisation")
        status_filter = self.request.query_params.get("status")
        if status_filter:
            queryset = queryset.filter(status=status_filter)
        if self.action == "retrieve":
            queryset = queryset.prefetch_related("steps__drone", "assignments__drone")
        return queryset

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        return MissionDetailSerializer if self.action == "retrieve" else MissionSerializer

    def _writable(self, pk: str | None) -> Mission:
        mission = self.get_object()
        if not require_role(self.request.user, mission.organisation, Role.OPERATOR):
            raise exceptions.PermissionDenied("Operators and admins only.")
        return mission

    # -- planning --------------------------------------------------------------------------

    @extend_schema(request=CoverageRequest, responses=CoverageResponse)
    @action(detail=False, methods=["post"], url_path="coverage")
    def coverage(self, request: Request) -> Response:
        """Serpentine waypoints over the parallelogram of three consecutive vertices."""
        body = _body(request)
        if "altitude" in body:
            _altitude(body)
        try:
            area = planning.coverage(
                body.get("vertices"),
                body.get("step_distance"),
                line_spacing=body.get("line_spacing"),
                max_waypoints=settings.MISSIONS_MAX_WAYPOINTS,
            )
            answer = area.to_dict()
            if body.get(following.FIELD) is not None:
                answer["followed"] = following.followed_body(
                    body[following.FIELD],
                    area.waypoints,
                    _altitude(body),
                    settings.MISSIONS_MAX_WAYPOINTS,
                    settings.MISSIONS_SURVEY_SPEED_M_S,
                )
        except planning.PlanningError as exc:
            raise refuse(exc) from None
        return Response(answer)

    @extend_schema(request=ExtendRequest, responses=ExtendResponse)
    @action(detail=False, methods=["post"], url_path="coverage/extend")
    def coverage_extend(self, request: Request) -> Response:
        """The same shape around a new centre, +50 % area per joining drone, split in parts."""
        body = _body(request)
        if "altitude" in body:
            _altitude(body)
        try:
            extension = planning.extend(
                body.get("vertices"),
                body.get("step_distance"),
                center=body.get("center"),  # type: ignore[arg-type]
                joining_drones=body.get("joining_drones"),  # type: ignore[arg-type]
                max_waypoints=settings.MISSIONS_MAX_WAYPOINTS,
            )
        except planning.PlanningError as exc:
            raise refuse(exc) from None
        return Response(extension.to_dict())

    # -- lifecycle -------------------------------------------------------------------------

    @extend_schema(request=CreateRequest, responses={201: MissionDetailSerializer})
    def create(self, request: Request) -> Response:
        """A draft mission from `steps`, or from a `coverage` (which also keeps the
        extensibility parameters a collaboration needs). 409 `outside_envelope`,
        `terrain_clearance` (the leg, the clearance found, the minimum) and `zone` (the
        zone's name and band) name the first step refused (docs/airspace.md)."""
        body = _body(request)
        organisation = _organisation_for_write(request, body.get("organisation"))
        altitude = _altitude(body)
        extensibility = body.get("extensibility")
        if extensibility is not None and not isinstance(extensibility, dict):
            raise Refused("extensibility", "must be an object")
        home = None
        if "coverage" in body:
            steps, extensibility, home = _steps_from_coverage(
                body["coverage"], altitude, settings.MISSIONS_MAX_WAYPOINTS
            )
        else:
            steps = body.get("steps")
        if extensibility and "vectors" in extensibility:
            try:
                planning.Vectors.from_dict(extensibility["vectors"])
                planning.normalise_actions(extensibility.get("intermediate_action"))
            except planning.PlanningError as exc:
                raise Refused(f"extensibility.{exc.field}", exc.message) from None
        try:
            mission = create_mission(
                organisation=organisation,
                name=str(body.get("name") or ""),
                steps=steps,
                altitude=altitude,
                extensibility=extensibility,
                user=request.user,
                home=home,
                confirmed=_confirmed(body),
            )
        except MissionError as exc:
            raise refuse(exc) from None
        return Response(_created(mission), status=status.HTTP_201_CREATED)

    @extend_schema(
        request=StartRequest,
        responses={
            200: MissionDetailSerializer,
            404: OpenApiResponse(description="no such mission, or `drone` not in its organisation"),
            409: OpenApiResponse(
                response=RefusalSerializer,
                description=(
                    "refused, nothing sent; `code` says why: `not_airworthy` (the reasons in "
                    "`error` and, one by one, in `reasons`), `checklist_required`, `wind`, `conflict`, `outside_envelope`, "
                    "`terrain_clearance`, `zone`, `confirmation_required`"
                ),
            ),
        },
    )
    @action(detail=True, methods=["post"], throttle_classes=MISSION_START_THROTTLES)
    def start(self, request: Request, pk: str | None = None) -> Response:
        """Send the mission to `drone` (an id of the same organisation) or, without one,
        to the nearest available drone. 409 `not_airworthy` names the reasons a drone may
        not fly (each in `reasons`); 409 `checklist_required` names a drone without a passed pre-flight
        checklist within its validity (docs/checklists.md); 409 `wind` gives the wind
        above the chosen drone's limit; 409 `conflict` names the other drone whose
        reservation the flight would come within the separation minima of, the place
        and the time; 409 `outside_envelope`, `terrain_clearance` and `zone` name the
        first step refused from the chosen drone (docs/airspace.md)."""
        mission = self._writable(pk)
        body = _body(request)
        drone = None
        drone_id = body.get("drone")
        if drone_id not in (None, ""):
            drone = Drone.objects.filter(
                drone_id=str(drone_id), organisation=mission.organisation
            ).first()
            if drone is None:
                raise Refused("drone", f"no drone {drone_id!r} in this organisation", 404)
        try:
            start_mission(mission, drone=drone, user=request.user, confirmed=_confirmed(body))
        except MissionError as exc:
            note_refusal(
                mission.organisation_id, request.user, "mission.start", mission, exc.message
            )
            raise refuse(exc) from None
        mission.refresh_from_db()
        return Response(MissionDetailSerializer(mission).data)

    @extend_schema(request=None, responses=MissionDetailSerializer)
    @action(detail=True, methods=["post"])
    def stop(self, request: Request, pk: str | None = None) -> Response:
        """Stop every drone flying the mission (stopchain)."""
        return self._operate(pk, request, stop_mission)

    @extend_schema(request=None, responses=MissionDetailSerializer)
    @action(detail=True, methods=["post"], throttle_classes=COMMAND_THROTTLES)
    def release(self, request: Request, pk: str | None = None) -> Response:
        """Release a panic call: its drone returns home and lands; the call is completed."""
        return self._operate(pk, request, panic.release)

    @extend_schema(request=HoldRequest, responses=MissionDetailSerializer)
    @action(detail=True, methods=["post"])
    def pause(self, request: Request, pk: str | None = None) -> Response:
        """Pause a running mission: its drones hold where they are (409 unless running);
        with `drone`, only that drone holds."""
        return self._operate(pk, request, _for_drone(request, hold.pause))

    @extend_schema(request=HoldRequest, responses=MissionDetailSerializer)
    @action(detail=True, methods=["post"], throttle_classes=MISSION_START_THROTTLES)
    def resume(self, request: Request, pk: str | None = None) -> Response:
        """Resume a paused mission: each held drone carries on from its step (409 unless
        one holds); with `drone`, only that drone."""
        return self._operate(pk, request, _for_drone(request, hold.resume))

    def _operate(self, pk: str | None, request: Request, operation: Any) -> Response:
        """Run one operator action on a mission the user may change; a refusal is an error."""
        mission = self._writable(pk)
        try:
            operation(mission, user=request.user)
        except MissionError as exc:
            action = f"mission.{operation.__name__.removesuffix('_mission')}"
            note_refusal(mission.organisation_id, request.user, action, mission, exc.message)
            raise refuse(exc) from None
        mission.refresh_from_db()
        return Response(MissionDetailSerializer(mission).data)

    @extend_schema(responses=StepSerializer(many=True))
    @action(detail=True, methods=["get"])
    def steps(self, request: Request, pk: str | None = None) -> Response:
        mission = self.get_object()
        steps = mission.steps.select_related("drone").order_by("index")
        return Response(StepSerializer(steps, many=True).data)

    @extend_schema(request=OpenApiTypes.OBJECT, responses={200: OpenApiTypes.OBJECT})
    @action(detail=False, methods=["post"], url_path="check-envelope")
    def check_envelope(self, request: Request) -> Response:
        """Every step of `steps` the flight envelope refuses (flown by `drone` when given),
        for the planner to mark before anything is sent, and every step beyond the
        envelope's defaults (`beyond_defaults`: to confirm); nothing is stored or sent."""
        body = _body(request)
        organisation = _organisation_for_write(request, body.get("organisation"))
        try:
            steps = validate_steps(body.get("steps"))
        except MissionError as exc:
            raise refuse(exc) from None
        drone = None
        if body.get("drone"):
            drone = Drone.objects.filter(
                drone_id=str(body["drone"]), organisation=organisation
            ).first()
            if drone is None:
                raise Refused("drone", f"no drone {body['drone']!r} in this organisation", 404)
        found = envelopes.step_violations(organisation, steps, drone)
        beyond = envelopes.steps_beyond_defaults(organisation, steps, drone)
        return Response(
            {
                "violations": [_violation_row(v) for v in found],
                "beyond_defaults": [_violation_row(v) for v in beyond],
                "terrain_warnings": envelopes.terrain_warnings(organisation, steps, drone),
                "terrain_imported": has_terrain(),
                "envelope": envelopes.envelope_body(organisation),
                "profile": height_profile(
                    _checked_home(organisation, steps, drone),
                    steps,
                    organisation.pk,
                    envelopes.drone_pace(drone) if drone else None,
                ),
                "conflicts": separation.plan_conflicts(drone, steps) if drone else [],
            }
        )

    @extend_schema(request=PanicRequest, responses={201: MissionDetailSerializer})
    @action(detail=False, methods=["post"], throttle_classes=MISSION_START_THROTTLES)
    def panic(self, request: Request) -> Response:
        """The panic button: the nearest available drone flies to (lat, lon) at 10 m.
        409 `conflict` names the other drone, the place and the time when the flight would
        come within the separation minima of its reservation (docs/airspace.md)."""
        body = _body(request)
        organisation = _organisation_for_write(request, body.get("organisation"))
        try:
            started = panic.call_drone(
                organisation=organisation,
                lat=body.get("lat"),
                lon=body.get("lon"),
                user=request.user,
                confirmed=_confirmed(body),
            )
        except MissionError as exc:
            raise refuse(exc) from None
        started.mission.refresh_from_db()
        return Response(
            MissionDetailSerializer(started.mission).data, status=status.HTTP_201_CREATED
        )

    # -- logs, pictures, plans -------------------------------------------------------------

    @extend_schema(responses={200: OpenApiTypes.OBJECT})
    @action(detail=True, methods=["get"])
    def log(self, request: Request, pk: str | None = None) -> Response:
        """The mission log: mission, drones, assignments, steps, stages and every event."""
        mission = self.get_object()
        response = Response(logs.build_log(mission))
        if request.query_params.get("download"):
            response["Content-Disposition"] = f'attachment; filename="mission-{mission.pk}.json"'
        return response

    @extend_schema(
        request={
            "multipart/form-data": inline_serializer("LogUpload", {"file": serializers.FileField()})
        },
        responses={200: OpenApiTypes.OBJECT},
    )
    @action(detail=False, methods=["post"], url_path="logs/check")
    def check_log(self, request: Request) -> Response:
        """Read an uploaded mission log for the viewer; 4xx says what is wrong with it."""
        upload = request.FILES.get("file")
        if upload is None:
            raise Refused("file", "attach the mission log as `file`")
        if upload.size > logs.MAX_LOG_BYTES:
            raise Refused("file", "is too large", 413)
        try:
            return Response(logs.parse_log(upload.read()))
        except MissionError as exc:
            raise refuse(exc) from None

    @extend_schema(responses=PictureSerializer(many=True))
    @action(detail=True, methods=["get"])
    def pictures(self, request: Request, pk: str | None = None) -> Response:
        mission = self.get_object()
        rows = Picture.objects.filter(mission=mission).select_related("drone")
        return Response(PictureSerializer(rows, many=True).data)

    @extend_schema(
        parameters=[OpenApiParameter("undistort", bool, description="barrel correction")],
        responses={(200, "application/zip"): OpenApiTypes.BINARY},
    )
    @action(detail=True, methods=["get"], url_path="pictures/odm")
    def pictures_odm(self, request: Request, pk: str | None = None) -> HttpResponse:
        """Every picture plus `geo.txt`, ready for OpenDroneMap."""
        mission = self.get_object()
        if not mission.pictures.exists():
            raise Refused("pictures", "this mission has no pictures", 404)
        correct = request.query_params.get("undistort") in ("1", "true", "yes")
        data = pictures.odm_archive(mission, correct_barrel=correct)
        response = HttpResponse(data, content_type="application/zip")
        response["Content-Disposition"] = f'attachment; filename="mission-{mission.pk}-odm.zip"'
        return response

    @extend_schema(responses={(200, "application/json"): OpenApiTypes.OBJECT})
    @action(detail=True, methods=["get"], url_path="plan")
    def export_plan(self, request: Request, pk: str | None = None) -> HttpResponse:
        """The mission as a QGroundControl `.plan` file."""
        mission = self.get_object()
        try:
            document = plan_files.export_document(mission)
        except planning.PlanningError as exc:
            raise refuse(exc) from None
        response = HttpResponse(qgc_plan.dumps(document), content_type="application/json")
        response["Content-Disposition"] = f'attachment; filename="mission-{mission.pk}.plan"'
        return response

    @extend_schema(
        request={
            "multipart/form-data": inline_serializer(
                "PlanUpload",
                {
                    "file": serializers.FileField(),
                    CONFIRM_FIELD: serializers.BooleanField(required=False, help_text=CONFIRM_HELP),
                },
            )
        },
        parameters=[
            OpenApiParameter(
                "fence",
                str,
                enum=list(plan_files.FENCE_SCOPES),
                description="where the plan's geoFence goes: the mission (default) or, "
                "for admins, the organisation's envelope",
            )
        ],
        responses={201: MissionDetailSerializer},
    )
    @action(detail=False, methods=["post"], url_path="import-plan")
    def import_plan(self, request: Request) -> Response:
        """A draft mission from a QGroundControl `.plan` file or a `QGC WPL 110` text mission
        (multipart `file`), or the plan itself as the JSON body."""
        upload = request.FILES.get("file")
        organisation = _organisation_for_write(request, request.data.get("organisation"))
        if upload is not None:
            if upload.size > MAX_PLAN_BYTES:
                raise Refused("file", "is too large", 413)
            source: object = upload.read()
        elif isinstance(request.data, dict) and request.data.get("fileType"):
            source = dict(request.data)
        else:
            raise Refused("file", "attach the .plan file as `file`")
        try:
            mission = plan_files.import_document(
                source,  # type: ignore[arg-type]
                organisation=organisation,
                user=request.user,
                name=upload.name if upload is not None else "",
                fence_scope=request.query_params.get("fence", "mission"),
                confirmed=_confirmed(request.data),
            )
        except (planning.PlanningError, MissionError) as exc:
            raise refuse(exc) from None
        return Response(_created(mission), status=status.HTTP_201_CREATED)


def _created(mission: Mission) -> dict:
    """A new mission, and where its terrain clearance could not be checked
    (`terrain_warnings`: the envelope's other limits still held)."""
    steps = list(mission.steps.order_by("index").values("command", "params"))
    warnings = envelopes.terrain_warnings(mission.organisation, steps, home=mission.plan_home)
    return {**MissionDetailSerializer(mission).data, "terrain_warnings": warnings}


def _for_drone(request: Request, operation: Any) -> Any:
    """The pause or resume of the whole mission, or of the body's `drone` only."""
    data = request.data if isinstance(request.data, dict) else {}
    drone = data.get("drone")
    if drone in (None, ""):
        return operation
    return lambda mission, user: operation(mission, user=user, drone=str(drone))


def _violation_row(found: Any) -> dict:
    """One refused step for the planner; `leg` ([[lat, lon], [lat, lon]]) when it is the
    straight leg to the step's target, not the target, that breaks the fence."""
    violation = found.violation
    leg = [list(point) for point in violation.leg] if violation.leg else None
    return {
        "index": found.index,
        "limit": violation.limit,
        "message": violation.message,
        "leg": leg,
    }
