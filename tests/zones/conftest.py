"""The fleet's broker, gateway and flying drone fixtures and the missions' outbox, for
zone tests."""

from tests.fleet.conftest import _shared_broker, broker, fresh_redis, gateway  # noqa: F401
from tests.fleet.test_envelope import flying  # noqa: F401
from tests.missions.conftest import outbox  # noqa: F401
