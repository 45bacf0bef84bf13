"""Pre-flight checklists: each organisation's rule, its templates, and the runs (kept
append-only: a run is what was confirmed and measured at that moment, never edited)."""

from __future__ import annotations

from django.conf import settings
from django.db import models

APPEND_ONLY = "checklist runs are append-only"


class Policy(models.Model):
    """An organisation's own rule; without one the site's defaults apply
    (CHECKLIST_REQUIRED_DEFAULT, CHECKLIST_VALID_MINUTES_DEFAULT)."""

    organisation = models.OneToOneField(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="checklist_policy"
    )
    required = models.BooleanField()
    valid_minutes = models.PositiveIntegerField()
    updated_at = models.DateTimeField(auto_now=True)

    def __str__(self) -> str:
        return f"{self.organisation}: {'required' if self.required else 'not required'}"


class Template(models.Model):
    """Items a person confirms and automatic items the platform checks (checklists/items.py)."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="checklist_templates"
    )
    name = models.CharField(max_length=120)
    items = models.JSONField()
    valid_minutes = models.PositiveIntegerField()
    active = models.BooleanField(default=True)
    created_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    created_at = models.DateTimeField(auto_now_add=True)
    updated_at = models.DateTimeField(auto_now=True)

    class Meta:
        ordering = ["name", "id"]

    def __str__(self) -> str:
        return self.name


class RunQuerySet(models.QuerySet):
    def update(self, **kwargs: object) -> int:
        raise PermissionError(APPEND_ONLY)

    def delete(self) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)


class Run(models.Model):
    """One checklist run for one drone: the template's items as they were, the answers,
    the automatic values with their thresholds, and whether it passed."""

    organisation = models.ForeignKey(
        "fleet.Organisation", on_delete=models.CASCADE, related_name="+"
    )
    # A drone with runs is not deleted (its runs would go with it, unrecorded); its
    # organisation's removal still takes both.
    drone = models.ForeignKey(
        "fleet.Drone", on_delete=models.RESTRICT, related_name="checklist_runs"
    )
    template = models.ForeignKey(
        Template, null=True, on_delete=models.SET_NULL, related_name="runs"
    )
    template_name = models.CharField(max_length=120)
    results = models.JSONField()
    passed = models.BooleanField()
    failures = models.JSONField(default=list)
    run_by = models.ForeignKey(
        settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL, related_name="+"
    )
    run_by_name = models.CharField(max_length=150, blank=True)
    at = models.DateTimeField()
    expires_at = models.DateTimeField()

    objects = RunQuerySet.as_manager()

    class Meta:
        ordering = ["-at", "-id"]
        indexes = [models.Index(fields=["drone", "-at"])]

    def __str__(self) -> str:
        return f"{self.template_name} on drone {self.drone_id}: {'passed' if self.passed else 'failed'}"

    def save(self, *args: object, **kwargs: object) -> None:
        if self.pk is not None:
            raise PermissionError(APPEND_ONLY)
        super().save(*args, **kwargs)  # type: ignore[arg-type]

    def delete(self, *args: object, **kwargs: object) -> tuple[int, dict[str, int]]:
        raise PermissionError(APPEND_ONLY)
