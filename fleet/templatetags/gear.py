"""Render a drone's announced specs and sensors (nested JSON) as readable lists."""

from __future__ import annotations

from django import template
from django.utils.html import format_html, format_html_join
from django.utils.safestring import SafeString

register = template.Library()


# Units of the announced specs (docs/protocol.md, gear), by the path of their key.
UNITS = {("BATTERY", "CAPACITY"): "mAh", ("FRAME_SIZE",): "mm"}


def _label(key: str) -> str:
    return key.replace("_", " ").capitalize()


@register.filter
def gear_list(value: object, path: tuple[str, ...] = ()) -> SafeString:
    """{"BATTERY": {"CAPACITY": 5500}, "TYPE": "HEXACOPTER"} → nested <dl> (escaped), a
    number with its unit where the key's meaning is known ("5500 mAh")."""
    if not isinstance(path, tuple):
        path = ()
    if isinstance(value, dict):
        return format_html(
            '<dl class="kv">{}</dl>',
            format_html_join(
                "",
                "<dt>{}</dt><dd>{}</dd>",
                ((_label(str(k)), gear_list(v, (*path, str(k).upper()))) for k, v in value.items()),
            ),
        )
    if isinstance(value, list):
        return format_html_join(", ", "{}", ((gear_list(v, path),) for v in value))
    unit = UNITS.get(path)
    if unit and isinstance(value, int | float | str) and str(value).replace(".", "", 1).isdigit():
        return format_html("{} {}", value, unit)
    return format_html("{}", value)
