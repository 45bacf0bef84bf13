"""Render a drone's announced specs and sensors (nested JSON) as readable lists."""

from __future__ import annotations

from django import template
from django.utils.html import format_html, format_html_join
from django.utils.safestring import SafeString

register = template.Library()


def _label(key: str) -> str:
    return key.replace("_", " ").capitalize()


@register.filter
def gear_list(value: object) -> SafeString:
    """{"BATTERY": {"CELL_COUNT": 4}, "TYPE": "HEXACOPTER"} → nested <dl> (escaped)."""
    if isinstance(value, dict):
        return format_html(
            '<dl class="kv">{}</dl>',
            format_html_join(
                "",
                "<dt>{}</dt><dd>{}</dd>",
                ((_label(str(k)), gear_list(v)) for k, v in value.items()),
            ),
        )
    if isinstance(value, list):
        return format_html_join(", ", "{}", ((gear_list(v),) for v in value))
    return format_html("{}", value)
