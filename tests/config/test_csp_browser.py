"""Every portal page under its Content-Security-Policy, in a real browser: nothing it
needs is refused (no violation reported, no script error), so the policy can stay
strict. The pages are found the way a user finds them: from the fleet page, following
every link of the portal, plus the pages no link leads to (sign-in, the API reference)."""

from __future__ import annotations

from urllib.parse import urljoin, urlsplit

import pytest
from playwright.sync_api import TimeoutError as PlaywrightTimeout

from missions.models import Mission, MissionStatus
from tests.conftest import login

pytestmark = [pytest.mark.browser, pytest.mark.django_db(transaction=True)]

MAX_PAGES = 60
# Links followed that lead to no page: downloads, the JSON API, signing out.
NOT_PAGES = (
    "/api/v1/",
    "/accounts/logout/",
    ".csv",
    ".json",
    "/media/",
    "/static/",
    "/admin/",
    "/health",
)

RECORD_VIOLATIONS = """
window.__csp = [];
document.addEventListener("securitypolicyviolation", (event) => {
  window.__csp.push(`${event.violatedDirective} ${event.blockedURI} ${event.sourceFile}:${event.lineNumber}`);
});
"""


class Visits:
    """What the browser reported on each page: CSP violations and script errors."""

    def __init__(self, page) -> None:  # type: ignore[no-untyped-def]
        self.page = page
        self.problems: list[str] = []
        page.context.add_init_script(RECORD_VIOLATIONS)
        page.on("console", self._console)
        page.on("pageerror", lambda error: self.problems.append(f"{page.url}: {error}"))

    def _console(self, message) -> None:  # type: ignore[no-untyped-def]
        if "Content Security Policy" in message.text or "Content-Security-Policy" in message.text:
            self.problems.append(f"{self.page.url}: {message.text}")

    def open(self, url: str) -> list[str]:
        """The page's own links (same origin)."""
        response = self.page.goto(url, wait_until="load")
        assert response is not None and response.status < 500, url
        assert "default-src 'self'" in response.headers["content-security-policy"], url
        try:
            self.page.wait_for_load_state("networkidle", timeout=15_000)
        except PlaywrightTimeout:
            # Its scripts ran at load, so what they did is checked; on a loaded host a
            # request may keep the network from idling, which is not what this test asks.
            pass
        for violation in self.page.evaluate("window.__csp || []"):
            self.problems.append(f"{url}: {violation}")
        hrefs = self.page.eval_on_selector_all("a[href]", "links => links.map(a => a.href)")
        return [urljoin(url, href) for href in hrefs]


def _portal_links(origin: str, links: list[str]) -> list[str]:
    found = []
    for link in links:
        parts = urlsplit(link)
        if f"{parts.scheme}://{parts.netloc}" != origin or any(n in parts.path for n in NOT_PAGES):
            continue
        if "format=" in parts.query:  # an export (CSV, PDF) of the page, a download
            continue
        found.append(f"{origin}{parts.path}" + (f"?{parts.query}" if parts.query else ""))
    return found


@pytest.fixture
def page(browser):  # type: ignore[no-untyped-def]
    """A page that keeps the policy (the suite's own page fixture bypasses it)."""
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    yield context.new_page()
    context.close()


def test_every_portal_page_loads_and_runs_under_the_policy_without_a_violation(
    page, live_asgi, world_tx
):
    Mission.objects.create(
        organisation=world_tx.org, name="Campus survey", status=MissionStatus.COMPLETED
    )
    visits = Visits(page)
    for path in ("/accounts/login/", "/api/docs/", "/api/redoc/", "/api/v1/"):
        visits.open(f"{live_asgi.url}{path}")
    login(page, live_asgi, "owner")
    seen: set[str] = set()
    queue = [f"{live_asgi.url}/"]
    while queue and len(seen) < MAX_PAGES:
        url = queue.pop(0)
        if url.split("#")[0] in seen:
            continue
        seen.add(url.split("#")[0])
        queue += _portal_links(live_asgi.url, visits.open(url))
    assert len(seen) >= 15, sorted(seen)  # the crawl reached the portal's pages
    assert visits.problems == []


def test_an_inline_script_put_into_a_page_is_refused(page, live_asgi, world_tx):
    """The attacker's side: markup that slipped into a page cannot run code."""
    visits = Visits(page)
    visits.open(f"{live_asgi.url}/accounts/login/")
    ran = page.evaluate(
        """() => {
          window.__ran = false;
          const div = document.createElement("div");
          div.innerHTML = '<img src="x" onerror="window.__ran = true">';
          document.body.append(div);
          const script = document.createElement("script");
          script.textContent = "window.__ran = true";
          document.body.append(script);
          return new Promise((done) => setTimeout(() => done(window.__ran), 300));
        }"""
    )
    assert ran is False
    assert any("script-src" in problem for problem in visits.problems)


def test_the_admin_pages_run_under_the_policy_without_a_violation(page, live_asgi, world_tx):
    from django.contrib.auth import get_user_model

    get_user_model().objects.create_superuser(
        "staff", "staff@example.org", "correct horse battery staple"
    )
    visits = Visits(page)
    login(page, live_asgi, "staff")
    seen: set[str] = set()
    queue = [f"{live_asgi.url}/admin/"]
    while queue and len(seen) < 25:
        url = queue.pop(0).split("#")[0]
        if url in seen or "/logout/" in url:
            continue
        seen.add(url)
        links = visits.open(url)
        queue += [link for link in links if link.startswith(f"{live_asgi.url}/admin/")]
    assert len(seen) >= 10, sorted(seen)
    assert visits.problems == []
