"""The API's body parsers: DRF's own, refusing a body that holds a NUL character.

PostgreSQL text and jsonb cannot hold NUL, and no drone id, serial, slug, name or note
can contain one: a NUL in a field that is looked up (an organisation, a drone, a pack's
serial) would otherwise fail inside the query as a server error. One walk of the parsed
body, bounded by its size limit (config/bodylimits.py); files are not looked into.
"""

from __future__ import annotations

from typing import Any

from rest_framework import parsers
from rest_framework.exceptions import ParseError

from config.urlchars import value_holds_nul

REFUSAL = "The request body holds a NUL character; nothing was done."


def _checked(parsed: Any) -> Any:
    data = parsed.data if isinstance(parsed, parsers.DataAndFiles) else parsed
    if value_holds_nul(data):
        raise ParseError(REFUSAL)
    return parsed


class JSONParser(parsers.JSONParser):
    def parse(self, stream, media_type=None, parser_context=None):  # type: ignore[no-untyped-def]
        return _checked(super().parse(stream, media_type, parser_context))


class FormParser(parsers.FormParser):
    def parse(self, stream, media_type=None, parser_context=None):  # type: ignore[no-untyped-def]
        return _checked(super().parse(stream, media_type, parser_context))


class MultiPartParser(parsers.MultiPartParser):
    def parse(self, stream, media_type=None, parser_context=None):  # type: ignore[no-untyped-def]
        return _checked(super().parse(stream, media_type, parser_context))
