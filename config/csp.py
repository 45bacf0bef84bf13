"""The Content-Security-Policy of every answer: everything a page runs or shows comes
from this server (the vendored map, chart and 3-D libraries included), so an injected
`<script>`, inline handler or outside origin is refused by the browser even if some
page ever lets one through.

- Scripts: files from the server only, plus an inline block carrying the request's
  nonce (the one import map a module page needs; browsers load no external import
  map). No `unsafe-inline`, no `unsafe-eval`.
- Styles: style sheets from the server, and `<style>` elements with the nonce; no style
  attributes (the pages set colours, widths and turns through the DOM, which the policy
  does not govern). The API's own pages (Swagger UI, Redoc, DRF's browsable API), which
  insert `<style>` elements and style attributes, alone allow inline styles.
- Images: the server, and `data:`/`blob:` (map markers, rendered charts, camera frames);
  workers: the server and `blob:`; connections: the server, its websockets included.
- No plugins, no foreign `<base>`, forms post to the server only, framed by the server
  only.

The header is built per answer (the nonce is new each time, 128 random bits); a view
that sets its own Content-Security-Policy keeps it.
"""

from __future__ import annotations

import secrets
from collections.abc import Callable

from asgiref.sync import iscoroutinefunction, markcoroutinefunction
from django.core.exceptions import DisallowedHost
from django.http import HttpRequest, HttpResponse

HEADER = "Content-Security-Policy"
# The API's own pages (Swagger UI, Redoc, DRF's browsable API) insert <style> elements.
INLINE_STYLE_PATHS = ("/api/",)


def policy(nonce: str, *, host: str, inline_styles: bool) -> str:
    styles = "'unsafe-inline'" if inline_styles else f"'nonce-{nonce}'"
    # CSP Level 3 lets 'self' match the page's own ws:/wss:; older browsers need them named.
    sockets = f" ws://{host} wss://{host}" if host else ""
    directives = {
        "default-src": "'self'",
        "script-src": f"'self' 'nonce-{nonce}'",
        "style-src": f"'self' {styles}",
        "img-src": "'self' data: blob:",
        "font-src": "'self' data:",
        "connect-src": "'self'" + sockets,
        "worker-src": "'self' blob:",
        "object-src": "'none'",
        "base-uri": "'self'",
        "form-action": "'self'",
        "frame-ancestors": "'self'",
    }
    return "; ".join(f"{name} {value}" for name, value in directives.items())


class ContentSecurityPolicyMiddleware:
    """Gives each request its `csp_nonce` (templates: `nonce="{{ request.csp_nonce }}"`)
    and each answer the policy. Header work only: it runs as is under ASGI and WSGI."""

    sync_capable = True
    async_capable = True

    def __init__(self, get_response: Callable) -> None:
        self.get_response = get_response
        self._async = iscoroutinefunction(get_response)
        if self._async:
            markcoroutinefunction(self)

    def __call__(self, request: HttpRequest):  # type: ignore[no-untyped-def]
        if self._async:
            return self._acall(request)
        request.csp_nonce = secrets.token_urlsafe(16)  # type: ignore[attr-defined]
        return self._finish(request, self.get_response(request))

    async def _acall(self, request: HttpRequest) -> HttpResponse:
        request.csp_nonce = secrets.token_urlsafe(16)  # type: ignore[attr-defined]
        return self._finish(request, await self.get_response(request))

    def _finish(self, request: HttpRequest, response: HttpResponse) -> HttpResponse:
        if HEADER not in response:
            response[HEADER] = policy(
                request.csp_nonce,  # type: ignore[attr-defined]
                host=_host(request),
                inline_styles=request.path.startswith(INLINE_STYLE_PATHS),
            )
        return response


def _host(request: HttpRequest) -> str:
    try:
        return request.get_host()
    except DisallowedHost:
        return ""
