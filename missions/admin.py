from django.contrib import admin

from .models import Assignment, Event, Mission, Picture, Step


class StepInline(admin.TabularInline):
    model = Step
    extra = 0
    fields = ["index", "command", "params", "status", "drone", "duration_s"]


@admin.register(Mission)
class MissionAdmin(admin.ModelAdmin):
    list_display = ["name", "organisation", "status", "altitude", "created_at", "ended_at"]
    list_filter = ["status", "organisation"]
    search_fields = ["name"]
    date_hierarchy = "created_at"
    inlines = [StepInline]


@admin.register(Step)
class StepAdmin(admin.ModelAdmin):
    list_display = ["mission", "index", "command", "status", "drone", "duration_s"]
    list_filter = ["status", "command"]
    search_fields = ["mission__name"]


@admin.register(Assignment)
class AssignmentAdmin(admin.ModelAdmin):
    list_display = ["mission", "drone", "reason", "status", "created_at"]
    list_filter = ["reason", "status"]
    search_fields = ["mission__name", "drone__drone_id"]


@admin.register(Event)
class EventAdmin(admin.ModelAdmin):
    list_display = ["mission", "kind", "drone", "message", "at"]
    list_filter = ["kind"]
    search_fields = ["mission__name", "message"]
    date_hierarchy = "at"


@admin.register(Picture)
class PictureAdmin(admin.ModelAdmin):
    list_display = ["mission", "drone", "index", "name", "taken_at", "lat", "lon"]
    search_fields = ["mission__name", "name", "drone__drone_id"]
    date_hierarchy = "taken_at"
