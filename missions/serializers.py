from __future__ import annotations

from django.urls import reverse
from rest_framework import serializers

from .models import Assignment, Mission, Picture, Step


class StepSerializer(serializers.ModelSerializer):
    drone = serializers.SlugRelatedField(slug_field="drone_id", read_only=True)

    class Meta:
        model = Step
        fields = [
            "index",
            "command",
            "params",
            "status",
            "drone",
            "started_at",
            "ended_at",
            "position",
            "duration_s",
            "result",
        ]
        read_only_fields = fields


class AssignmentSerializer(serializers.ModelSerializer):
    drone = serializers.SlugRelatedField(slug_field="drone_id", read_only=True)

    class Meta:
        model = Assignment
        fields = [
            "id",
            "drone",
            "step_indexes",
            "preparation",
            "reason",
            "status",
            "replaces",
            "decode_ms",
            "created_at",
            "held",
        ]
        read_only_fields = fields


class MissionSerializer(serializers.ModelSerializer):
    organisation = serializers.SlugRelatedField(slug_field="slug", read_only=True)

    class Meta:
        model = Mission
        fields = [
            "id",
            "name",
            "organisation",
            "status",
            "altitude",
            "extensibility",
            "created_at",
            "started_at",
            "ended_at",
            "held",
        ]
        read_only_fields = fields


class MissionDetailSerializer(MissionSerializer):
    steps = StepSerializer(many=True, read_only=True)
    assignments = AssignmentSerializer(many=True, read_only=True)

    class Meta(MissionSerializer.Meta):
        fields = [*MissionSerializer.Meta.fields, "steps", "assignments"]
        read_only_fields = fields


class PictureSerializer(serializers.ModelSerializer):
    drone = serializers.SlugRelatedField(slug_field="drone_id", read_only=True)
    url = serializers.SerializerMethodField()
    thumbnail_url = serializers.SerializerMethodField()

    class Meta:
        model = Picture
        fields = [
            "id",
            "drone",
            "index",
            "name",
            "taken_at",
            "lat",
            "lon",
            "alt",
            "url",
            "thumbnail_url",
        ]
        read_only_fields = fields

    def get_url(self, picture: Picture) -> str:
        return reverse("missions:picture", args=[picture.pk])

    def get_thumbnail_url(self, picture: Picture) -> str:
        return reverse("missions:picture-thumbnail", args=[picture.pk])
