"""The fleet tests' private Mosquitto and in-process gateway, for commands to a drone; the
past-view tests' clean snapshot store, for teleoperation."""

from tests.fleet.conftest import _shared_broker, broker, fresh_redis, gateway  # noqa: F401
from tests.fleet.test_commands import online  # noqa: F401
from tests.pastview.conftest import no_snapshots_from_earlier_tests  # noqa: F401
