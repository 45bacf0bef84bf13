"""Personas shared by the suite: an owner, a viewer of the same organisation, an outsider.

Django is imported inside fixtures only, so pure-Python tests run without it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import pytest

from onboard.live_video import NICE_ENV

# The live-video publisher stands aside for the agent's threads (niceness 10). Here the
# busy processes beside it are the other tests', which a drone does not have: beside them
# it once sent no frame in 30 s. The default itself is tested (tests/livevideo/test_units.py).
os.environ.setdefault(NICE_ENV, "0")


@dataclass
class World:
    org: object
    other_org: object
    owner: object
    operator: object
    viewer: object
    outsider: object
    drone: object
    other_drone: object


def build_world() -> World:
    from fleet.models import Role

    from . import factories

    org = factories.organisation("acme")
    other = factories.organisation("globex")
    return World(
        org=org,
        other_org=other,
        owner=factories.person(org, Role.ADMIN, "owner"),
        operator=factories.person(org, Role.OPERATOR, "operator"),
        viewer=factories.person(org, Role.VIEWER, "viewer"),
        outsider=factories.person(other, Role.ADMIN, "outsider"),
        drone=factories.drone(org, "ACME_1"),
        other_drone=factories.drone(other, "GLOBEX_1"),
    )


# Tests whose assertions hold only with a core to spare (simulated flights in real time,
# frame rates, a deadline after a kill, ticks on time): marked `realtime`, which a
# parallel run (scripts/test.sh) runs after the workers, alone (with TEST_REALTIME_BESIDE=1,
# beside them in a pytest of its own at ten times their CPU weight).
REAL_TIME = (
    "tests/missions/test_experiments.py",
    "tests/airspace/test_e2e.py",
    "tests/airspace/test_traffic_e2e.py",
    # The alarming drone hovers one second of the test's time while the ground plans the
    # split: the plan's geometry (and so whether both parts meet in the air) holds only
    # while the ground answers within it.
    "tests/airspace/test_split_e2e.py",
    # A drone's height over a rising slope, at 20x time: the simulator's physics and the
    # agent's paced target each need the CPU on time.
    "tests/terrain/test_following_flight.py",
    "tests/missions/test_services.py::test_replacement_with_no_drone_available",
    "tests/pastview/test_e2e.py",
    "tests/workers/test_faults.py",
    "tests/workers/test_loaddrone.py::test_two_hundred_load_drones",
    # Live video encoded at its frame rate through a shaped link: command round trips and
    # telemetry ages are judged against the link's 2 s buffer, with 1 s for everything else.
    "tests/livevideo/test_throttled_link.py",
)
# Tests that need the machine to themselves for a moment: marked `alone`, which a parallel
# run runs in one worker once the workers have finished (and the real-time tests too,
# when those run beside the workers).
ALONE = (
    # More commands in one second than the limit allows, one at a time: beside the
    # real-time tests, even at ten times the workers' weight, it sent 17 where it needs 31.
    "tests/fleet/test_command_rate.py::test_a_thousand_commands_in_a_second",
)
# Markers of the tests that take seconds to minutes each (pyproject.toml).
LONG_MARKS = ("e2e", "browser", "slow")
# The tests outside the RabbitMQ worker that take about a minute or more each (setup, call
# and teardown in a lone run of `make test`, the real-time tests beside them): started
# before the other long ones, since one of them started last would hold the run's end.
LONGEST = (
    "tests/workers/test_outage.py",  # two outages of a minute: 78 and 89 s
    "tests/config/test_offline_browser.py",  # every page, once per size: 67-110 s each
    "tests/config/test_csp_browser.py",  # every page under the policy: 72 and 89 s
    "tests/airspace/test_landing_e2e.py::test_ten_drones_sent_home",  # 100 s
    "tests/batteries/test_uavtalk_flight.py",  # 57 s
)


def _start_rank(item: pytest.Item) -> int:
    """0 for the longest tests, 1 for the other long ones, 2 for the rest."""
    if item.nodeid.startswith(LONGEST):
        return 0
    return 1 if any(item.get_closest_marker(m) for m in LONG_MARKS) else 2


def _rabbitmq_user(item: pytest.Item) -> bool:
    """Whether the test runs on the session's RabbitMQ cluster."""
    callspec = getattr(item, "callspec", None)
    params = callspec.params if callspec else {}
    return (
        "rabbit_cluster" in getattr(item, "fixturenames", ())
        or params.get("broker_kind") == "rabbitmq"
    )


# What a test that reads or writes the worker's test database asks for (every test's
# fixtures include pytest-django's `django_db_blocker`, which alone gives no access).
DATABASE_FIXTURES = frozenset(("db", "transactional_db", "django_db_setup", "live_server"))


def _needs_test_database(item: pytest.Item) -> bool:
    return item.get_closest_marker("django_db") is not None or not DATABASE_FIXTURES.isdisjoint(
        getattr(item, "fixturenames", ())
    )


def _uses_a_module_fixture(item: pytest.Item) -> bool:
    info = getattr(item, "_fixtureinfo", None)
    definitions = info.name2fixturedefs.values() if info is not None else ()
    return any(defs and defs[-1].scope == "module" for defs in definitions)


@pytest.hookimpl(wrapper=True)
def pytest_collection_modifyitems(config, items):  # type: ignore[no-untyped-def]
    """Under pytest-xdist (--dist loadgroup) every RabbitMQ test runs in one worker: the
    session's two-node cluster then starts once, on the one port base of this run
    (RABBIT_PORT_BASE), and two clusters never compete for the cores. The real-time tests
    share another (and are marked `realtime`), except in a run of their own. Every worker
    collects the same order, as xdist requires."""
    for item in items:
        if _rabbitmq_user(item):
            item.add_marker(pytest.mark.xdist_group("rabbitmq"))
        elif item.nodeid.startswith(ALONE):
            item.add_marker(pytest.mark.alone)
        elif item.nodeid.startswith(REAL_TIME):
            item.add_marker(pytest.mark.realtime)
            # One at a time beside other tests; a run of them alone (TEST_REALTIME_SPREAD,
            # scripts/test.sh) spreads them over its workers, a core each.
            if not os.environ.get("TEST_REALTIME_SPREAD"):
                item.add_marker(pytest.mark.xdist_group("real-time"))
        elif item.nodeid.startswith("tests/firmware/test_arming_switch.py"):
            # They build and run one firmware binary in the checkout: one worker at a time.
            item.add_marker(pytest.mark.xdist_group("firmware-build"))
        elif _uses_a_module_fixture(item):
            # In one worker, a module's browser, server, virtualenv or outage stack is
            # built once for all its tests, not once in each worker a test lands in.
            item.add_marker(pytest.mark.xdist_group(item.nodeid.split("::")[0]))
    parallel = bool(os.environ.get("PYTEST_XDIST_WORKER"))
    if parallel:
        # The long tests first, the longest before them (a stable sort: modules stay
        # together), so that none of them starts last while the other workers have run out
        # of work. pytest-django then puts the tests that use the database in its order
        # (in a transaction, committed, none), which this sort survives within each.
        items.sort(key=_start_rank)
    result = yield
    if parallel:
        # Where the test database's order does not matter, the long tests go before all.
        items.sort(key=lambda item: _needs_test_database(item) or _start_rank(item) == 2)
    return result


@pytest.fixture
def world(db) -> World:  # type: ignore[no-untyped-def]
    return build_world()


@pytest.fixture
def world_tx(transactional_db) -> World:  # type: ignore[no-untyped-def]
    """The same personas, committed, for tests where other threads or processes read them."""
    return build_world()


@pytest.fixture(scope="session", autouse=True)
def _close_stray_database_sessions(request):  # type: ignore[no-untyped-def]
    """Worker threads (Channels, gateway) keep connections open; end them before the test
    database is dropped, or the drop fails."""
    if not request.config.pluginmanager.hasplugin("django"):
        yield
        return
    request.getfixturevalue("django_db_setup")
    blocker = request.getfixturevalue("django_db_blocker")
    yield
    from django.db import connection

    with blocker.unblock(), connection.cursor() as cursor:
        cursor.execute(
            "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
            "WHERE datname = current_database() AND pid <> pg_backend_pid()"
        )


@pytest.fixture(scope="session", autouse=True)
def _transactional_tests_empty_what_they_wrote():  # type: ignore[no-untyped-def]
    """A transactional test's teardown empties the tables that hold rows and keeps what
    `migrate` wrote, tried again if it loses a deadlock (tests/support/flush.py)."""
    try:
        from django.test import TransactionTestCase
    except ImportError:  # a run without Django
        yield
        return
    from functools import partial

    from tests.support.flush import empty_database, tried_again_after_a_deadlock

    def _fixture_teardown(self):  # type: ignore[no-untyped-def]
        for alias in self._databases_names(include_mirrors=False):
            tried_again_after_a_deadlock(partial(empty_database, alias))

    patch = pytest.MonkeyPatch()
    patch.setattr(TransactionTestCase, "_fixture_teardown", _fixture_teardown)
    yield
    patch.undo()


@pytest.fixture(scope="session")
def live_asgi(request):  # type: ignore[no-untyped-def]
    """The real ASGI app under uvicorn, reading the test database (commit your data with
    `world_tx` / `transactional_db`)."""
    request.getfixturevalue("django_db_setup")
    from django.db import connection

    from tests.support.live import LiveServer

    server = LiveServer(connection.settings_dict["NAME"])
    yield server
    server.stop()


@pytest.fixture(scope="module")
def browser():  # type: ignore[no-untyped-def]
    """Headless Debian Chromium through Playwright (its own browser download does not work
    here). Module-scoped: Playwright's sync API holds an event loop in the main thread
    while it runs, which asyncio tests elsewhere must not inherit."""
    import os

    from playwright.sync_api import sync_playwright

    from tests.support.live import launch_chromium

    # Playwright's sync API keeps an event loop in this thread; Django would then refuse
    # the tests' own (synchronous) database work. The server under test is unaffected.
    previous = os.environ.get("DJANGO_ALLOW_ASYNC_UNSAFE")
    os.environ["DJANGO_ALLOW_ASYNC_UNSAFE"] = "true"
    try:
        with sync_playwright() as playwright:
            chromium = launch_chromium(playwright)
            yield chromium
            chromium.close()
    finally:
        if previous is None:
            os.environ.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)
        else:
            os.environ["DJANGO_ALLOW_ASYNC_UNSAFE"] = previous


@pytest.fixture
def page(browser, request):  # type: ignore[no-untyped-def]
    # The page closes before a transactional test's database is flushed: a page still
    # polling the live server holds locks the flush waits for, while its
    # request waits for a table the flush holds (PostgreSQL ends one as a deadlock).
    if "transactional_db" in request.fixturenames:
        request.getfixturevalue("transactional_db")
    # Playwright's wait_for_function compiles its predicate with eval inside the page,
    # which the pages' Content-Security-Policy refuses; the policy itself is tried by
    # tests/config/test_csp_browser.py and test_offline_browser.py, whose contexts keep it.
    context = browser.new_context(viewport={"width": 1280, "height": 800}, bypass_csp=True)
    page = context.new_page()
    # What the page's scripts threw or logged as errors: printed at teardown, so that a
    # failing test's report shows it (pytest shows a test's captured output when it fails).
    said: list[str] = []
    page.on("pageerror", lambda error: said.append(f"uncaught: {error}"))
    page.on(
        "console",
        lambda m: said.append(f"console.{m.type}: {m.text}") if m.type == "error" else None,
    )
    yield page
    context.close()
    if said:
        print("The page said:\n" + "\n".join(said[-20:]))


def login(page, live_asgi, username: str, password: str = "correct horse battery staple"):  # type: ignore[no-untyped-def]
    page.goto(f"{live_asgi.url}/accounts/login/")
    page.fill("input[name=username]", username)
    page.fill("input[name=password]", password)
    page.click("button[type=submit]")
    page.wait_for_load_state()
