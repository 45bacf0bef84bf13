"""A web server of the ground's processes whose chosen port another process took before
it bound it starts again on another free port."""

from __future__ import annotations

import socket

import pytest
import requests
from django.db import connection

from tests.support.ground import ground_processes
from workers.ground import web_argv

pytestmark = pytest.mark.django_db(transaction=True)


def test_a_web_server_whose_port_was_taken_starts_on_another(tmp_path):
    ground = ground_processes(tmp_path, connection.settings_dict["NAME"])
    web = ground.add_web()
    with socket.socket() as squatter:
        # Bound, not listening: as a client's connection holds its local port.
        squatter.bind(("127.0.0.1", 0))
        taken = squatter.getsockname()[1]
        web.port, web.argv = taken, web_argv(taken)
        try:
            ground.start(timeout=90)
            assert web.port != taken
            assert requests.get(f"{web.url}/health", timeout=10).status_code in (200, 503)
        finally:
            ground.stop()
