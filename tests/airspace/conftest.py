"""The separation tests fly with the production minima (the suite's own are 0 m,
config/settings/test.py), and use the missions tests' outbox: what would be sent to
drones, in a Redis database of the tests' own."""

import pytest

from tests.missions.conftest import outbox  # noqa: F401


@pytest.fixture(autouse=True)
def production_minima(settings):  # type: ignore[no-untyped-def]
    settings.AIRSPACE_HORIZONTAL_MIN_M = 30.0
    settings.AIRSPACE_VERTICAL_MIN_M = 10.0
