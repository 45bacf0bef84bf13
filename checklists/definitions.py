"""Defining checklists (organisation admins): the templates and the organisation's rule.
Bad input raises ChecklistError naming the field and changes nothing; every change is
announced with `definition_changed` (the audit trail hears it)."""

from __future__ import annotations

from typing import Any

from django.conf import settings
from django.db import transaction

from fleet.models import Organisation

from .gate import Rule, rule_of
from .items import ChecklistError, clean_template, clean_valid_minutes
from .models import Policy, Template
from .signals import definition_changed


def template_dict(template: Template) -> dict:
    return {
        "id": template.pk,
        "name": template.name,
        "items": template.items,
        "valid_minutes": template.valid_minutes,
        "active": template.active,
        "created_at": template.created_at.isoformat(),
        "updated_at": template.updated_at.isoformat(),
    }


def _announce(
    organisation: Organisation, user: Any, action: str, target: str, detail: dict
) -> None:
    definition_changed.send(
        Template,
        organisation_id=organisation.pk,
        user=user,
        action=action,
        target=target,
        detail=detail,
    )


def create_template(organisation: Organisation, data: Any, user: Any) -> Template:
    clean = clean_template(data, default_valid_minutes=rule_of(organisation).valid_minutes)
    if Template.objects.filter(organisation=organisation, active=True).count() >= (
        settings.CHECKLIST_MAX_TEMPLATES
    ):
        raise ChecklistError("name", f"at most {settings.CHECKLIST_MAX_TEMPLATES} templates")
    with transaction.atomic():
        template = Template.objects.create(organisation=organisation, created_by=user, **clean)
        _announce(organisation, user, "checklist.template", template.name, {"created": clean})
    return template


def update_template(template: Template, data: Any, user: Any) -> Template:
    """Replace a template's name, items and validity; runs made before keep their copy."""
    clean = clean_template(data, default_valid_minutes=template.valid_minutes)
    with transaction.atomic():
        for key, value in clean.items():
            setattr(template, key, value)
        template.save()
        _announce(
            template.organisation, user, "checklist.template", template.name, {"changed": clean}
        )
    return template


def retire_template(template: Template, user: Any) -> None:
    """No longer run nor required; its runs stay."""
    with transaction.atomic():
        Template.objects.filter(pk=template.pk).update(active=False)
        _announce(
            template.organisation, user, "checklist.template", template.name, {"retired": True}
        )


def set_rule(organisation: Organisation, data: Any, user: Any) -> Rule:
    """`required` (bool) and/or `valid_minutes` (1..1440)."""
    if not isinstance(data, dict):
        raise ChecklistError("body", "must be a JSON object")
    unknown = sorted(set(data) - {"required", "valid_minutes"})
    if unknown:
        raise ChecklistError(unknown[0], "unknown field")
    rule = rule_of(organisation)
    required = data.get("required", rule.required)
    if not isinstance(required, bool):
        raise ChecklistError("required", "must be true or false")
    minutes = clean_valid_minutes(data.get("valid_minutes", rule.valid_minutes))
    with transaction.atomic():
        Policy.objects.update_or_create(
            organisation=organisation, defaults={"required": required, "valid_minutes": minutes}
        )
        _announce(
            organisation, user, "checklist.rule", organisation.name,
            {"required": required, "valid_minutes": minutes},
        )  # fmt: skip
    return Rule(required, minutes)
