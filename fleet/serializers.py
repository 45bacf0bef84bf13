from __future__ import annotations

from rest_framework import serializers

from .models import ConnectionEvent, Drone, Membership


class DroneSerializer(serializers.ModelSerializer):
    organisation = serializers.SlugRelatedField(slug_field="slug", read_only=True)
    position = serializers.SerializerMethodField()
    battery = serializers.SerializerMethodField()

    class Meta:
        model = Drone
        fields = [
            "drone_id",
            "name",
            "organisation",
            "online",
            "last_seen",
            "position",
            "battery",
            "armed",
            "airborne",
            "flight_mode",
            "mission",
            "fc",
        ]
        read_only_fields = fields

    def get_position(self, drone: Drone) -> dict | None:
        return drone.position

    def get_battery(self, drone: Drone) -> dict | None:
        return drone.battery


class DroneDetailSerializer(DroneSerializer):
    class Meta(DroneSerializer.Meta):
        # log_collection is set at /api/v1/logs/collection/{drone_id}/ (logs/policy_api.py).
        fields = [*DroneSerializer.Meta.fields, "specs", "sensors", "log_collection", "created_at"]
        read_only_fields = fields


class ConnectionEventSerializer(serializers.ModelSerializer):
    class Meta:
        model = ConnectionEvent
        fields = ["kind", "at", "reason"]


class MembershipSerializer(serializers.ModelSerializer):
    organisation = serializers.CharField(source="organisation.slug")
    organisation_name = serializers.CharField(source="organisation.name")

    class Meta:
        model = Membership
        fields = ["organisation", "organisation_name", "role"]
