"""The maintenance API's bodies and answers as the OpenAPI schema shows them. The bodies
are checked by maintenance/schedules.py and signoff.py (which name the refused field);
these classes only describe them."""

from __future__ import annotations

from rest_framework import serializers

TRIGGER_HELP = "at least one of every_hours, every_flights, every_days; each > 0"


class ScheduleBody(serializers.Serializer):
    name = serializers.CharField(max_length=120)
    drone = serializers.CharField(allow_null=True, required=False, help_text="drone id; or model")
    model = serializers.CharField(required=False, allow_blank=True, max_length=120)
    every_hours = serializers.FloatField(allow_null=True, required=False, help_text=TRIGGER_HELP)
    every_flights = serializers.IntegerField(allow_null=True, required=False, min_value=1)
    every_days = serializers.IntegerField(allow_null=True, required=False, min_value=1)
    notes = serializers.CharField(required=False, allow_blank=True, max_length=2000)


class Schedule(ScheduleBody):
    id = serializers.IntegerField()
    created_at = serializers.DateTimeField()
    updated_at = serializers.DateTimeField()


class BulletinBody(serializers.Serializer):
    model = serializers.CharField(required=False, max_length=120, help_text="or drone")
    drone = serializers.CharField(required=False, help_text="a finding on one drone")
    title = serializers.CharField(max_length=200)
    text = serializers.CharField(max_length=10_000)


class Bulletin(BulletinBody):
    id = serializers.IntegerField()
    issued_by = serializers.CharField()
    issued_at = serializers.DateTimeField()


class Measure(serializers.Serializer):
    trigger = serializers.ChoiceField(choices=["hours", "flights", "days"])
    used = serializers.FloatField()
    limit = serializers.FloatField()


class Item(serializers.Serializer):
    name = serializers.CharField()
    status = serializers.ChoiceField(choices=["ok", "due_soon", "due"])
    kind = serializers.ChoiceField(choices=["schedule", "bulletin", "finding"])
    since = serializers.DateTimeField()
    schedule = serializers.IntegerField(allow_null=True)
    bulletin = serializers.IntegerField(allow_null=True)
    measures = Measure(many=True)
    overdue = serializers.CharField(help_text="how far past due, when due")


class DroneItems(serializers.Serializer):
    drone = serializers.CharField()
    items = Item(many=True)


class SignOffBody(serializers.Serializer):
    schedule = serializers.IntegerField(required=False, help_text="or bulletin")
    bulletin = serializers.IntegerField(required=False)
    notes = serializers.CharField(max_length=2000)
    parts = serializers.ListField(
        child=serializers.CharField(max_length=120), max_length=50, required=False
    )


class LogEntry(serializers.Serializer):
    id = serializers.IntegerField()
    drone = serializers.CharField()
    item = serializers.CharField()
    schedule = serializers.IntegerField(allow_null=True)
    bulletin = serializers.IntegerField(allow_null=True)
    signed_by = serializers.CharField()
    signed_at = serializers.DateTimeField()
    notes = serializers.CharField()
    parts = serializers.ListField(child=serializers.CharField())
    usage = Measure(many=True)


class LogPage(serializers.Serializer):
    count = serializers.IntegerField()
    next = serializers.URLField(allow_null=True)
    previous = serializers.URLField(allow_null=True)
    results = LogEntry(many=True)
