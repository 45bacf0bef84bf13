"""The shared rate machinery (config/throttling.py): the rate format and the client's
address every throttle counts by. The people's sign-in limits built on them are tested in
tests/accounts/test_throttling.py, the drones' in tests/logs/test_collection_signin.py."""

import threading
import time
import uuid
from concurrent.futures import ThreadPoolExecutor

import pytest
from django.test import RequestFactory

from config.throttling import client_address, parse_rate


@pytest.mark.parametrize("rate", ["10", "ten/min", "10/fortnight"])
def test_a_malformed_rate_is_named(rate):
    with pytest.raises(ValueError, match="a rate is like 10/min"):
        parse_rate(rate)


def test_rates_read_as_counts_per_window():
    assert parse_rate("10/min") == (10, 60)
    assert parse_rate("5/hour") == (5, 3600)


def test_the_client_address_is_the_connections_not_a_forged_header():
    # NUM_PROXIES is 0: no hop of X-Forwarded-For is trusted.
    request = RequestFactory().get(
        "/", REMOTE_ADDR="2001:db8::7", HTTP_X_FORWARDED_FOR="2001:db8::9"
    )
    assert client_address(request) == "2001:db8::7"


def _window_throttle(rate: str):  # type: ignore[no-untyped-def]
    """A command-like throttle with its own scope and `rate`, counting one caller."""
    from config.throttling import ActionRateThrottle

    scope = f"probe{uuid.uuid4().hex[:8]}"
    kind = type(
        "ProbeThrottle", (ActionRateThrottle,), {"scope": scope, "get_rate": lambda self: rate}
    )
    return kind, f"rate:{scope}:user:1"


def test_requests_at_once_never_share_the_last_places_of_a_window():
    """Twenty web threads asking at the same moment for five places: five get one. A read
    of the count and a later write of it, as DRF's cached list does, lets several through."""
    from config.throttling import count_in_windows

    kind, key = _window_throttle("5/min")
    start = threading.Barrier(20)

    def ask() -> bool:
        start.wait()
        return count_in_windows([(kind(), key)])[0]

    with ThreadPoolExecutor(20) as pool:
        answers = list(pool.map(lambda _: ask(), range(20)))
    assert answers.count(True) == 5


def test_a_refused_request_waits_until_the_oldest_leaves_the_window():
    from config.throttling import count_in_windows

    kind, key = _window_throttle("2/s")
    first = time.time()
    assert count_in_windows([(kind(), key), (kind(), key + "x")]) == [True, True]
    assert count_in_windows([(kind(), key)]) == [True]
    refused = kind()
    assert count_in_windows([(refused, key), (kind(), key + "x")]) == [False, True]
    assert refused.count == 2
    # DRF's wait: the window's time left since the oldest, shared among the places it frees.
    assert 1 - (refused.now - first) - 1e-6 <= refused.wait() <= 1
    time.sleep(1.05)  # both have left the one-second window
    assert count_in_windows([(kind(), key)]) == [True]
