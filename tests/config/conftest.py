"""The fleet tests' private Mosquitto and in-process gateway, for /health's broker check."""

from tests.fleet.conftest import _shared_broker, broker, fresh_redis, gateway  # noqa: F401
