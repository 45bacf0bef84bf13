"""Static files served by WhiteNoise without taking every request out of the event loop.

WhiteNoise's middleware is synchronous only, so under ASGI Django would run it in a worker
thread for every request (a command's round trip included) just to learn that most paths
are not static files. This one answers that question in the event loop and goes to a
thread only to serve a file.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from asgiref.sync import iscoroutinefunction, markcoroutinefunction, sync_to_async
from django.http import HttpRequest, HttpResponse
from whitenoise.middleware import WhiteNoiseMiddleware


class StaticFilesMiddleware(WhiteNoiseMiddleware):
    sync_capable = True
    async_capable = True

    def __init__(self, get_response: Callable) -> None:
        super().__init__(get_response)
        self.is_async = iscoroutinefunction(get_response)
        if self.is_async:
            markcoroutinefunction(self)

    def __call__(self, request: HttpRequest) -> Any:
        if self.is_async:
            return self._acall(request)
        return super().__call__(request)

    def may_be_static(self, path: str) -> bool:
        """False only when no file could answer `path` (no disk access)."""
        if not self.autorefresh:
            return path in self.files
        prefixes = [prefix for _root, prefix in self.directories]
        if self.use_finders:
            prefixes.append(self.static_prefix)
        return any(path.startswith(prefix) for prefix in prefixes)

    async def _acall(self, request: HttpRequest) -> HttpResponse:
        if self.may_be_static(request.path_info):
            response = await sync_to_async(self._static_response)(request)
            if response is not None:
                return response
        return await self.get_response(request)

    def _static_response(self, request: HttpRequest) -> HttpResponse | None:
        found = (
            self.find_file(request.path_info)
            if self.autorefresh
            else self.files.get(request.path_info)
        )
        return self.serve(found, request) if found is not None else None
