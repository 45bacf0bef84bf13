"""The missions tests' outbox fixture: what would be sent to drones, in a Redis database
of the tests' own."""

from tests.missions.conftest import outbox  # noqa: F401
