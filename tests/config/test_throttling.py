"""The shared rate machinery (config/throttling.py): the rate format and the client's
address every throttle counts by. The people's sign-in limits built on them are tested in
tests/accounts/test_throttling.py, the drones' in tests/logs/test_collection_signin.py."""

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
