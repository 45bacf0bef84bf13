import pytest

from firmware.sim.camera import render_view


@pytest.fixture(scope="session")
def jpeg() -> bytes:
    """A small real JPEG from the simulator's camera."""
    return render_view((0.0, 0.0, -3.0), (0.0, 0.0, 0.0, 1.0), width=48, height=36)
