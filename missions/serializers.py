from __future__ import annotations

from rest_framework import serializers

from .models import Assignment, Mission, Step


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
        fields = ["id", "drone", "step_indexes", "preparation", "reason", "status", "created_at"]
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
        ]
        read_only_fields = fields


class MissionDetailSerializer(MissionSerializer):
    steps = StepSerializer(many=True, read_only=True)
    assignments = AssignmentSerializer(many=True, read_only=True)

    class Meta(MissionSerializer.Meta):
        fields = [*MissionSerializer.Meta.fields, "steps", "assignments"]
        read_only_fields = fields
