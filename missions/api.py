"""REST resources of missions, filtered to the user's organisations."""

from __future__ import annotations

from rest_framework import viewsets

from fleet.permissions import OrganisationRole

from .models import Mission
from .serializers import MissionDetailSerializer, MissionSerializer


class MissionViewSet(viewsets.ReadOnlyModelViewSet):
    permission_classes = [OrganisationRole]

    def get_queryset(self):  # type: ignore[no-untyped-def]
        queryset = Mission.objects.for_user(self.request.user).select_related("organisation")
        status = self.request.query_params.get("status")
        if status:
            queryset = queryset.filter(status=status)
        if self.action == "retrieve":
            queryset = queryset.prefetch_related("steps__drone", "assignments__drone")
        return queryset

    def get_serializer_class(self):  # type: ignore[no-untyped-def]
        return MissionDetailSerializer if self.action == "retrieve" else MissionSerializer
