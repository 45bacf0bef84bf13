"""Fixtures of the scale-out tests: a real two-node RabbitMQ cluster for the session."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.support.rabbitmq import RabbitCluster, available, cluster_for_this_run


@pytest.fixture(scope="session")
def rabbit_cluster() -> Iterator[RabbitCluster]:
    """Two clustered RabbitMQ nodes (scripts/rabbitmq.sh), stopped after the session."""
    assert available(), "rabbitmq-server is not installed: run scripts/bootstrap.sh test"
    cluster = cluster_for_this_run(nodes=2)
    try:
        cluster.start()  # a node that did not come up is stopped with the rest
        yield cluster
    finally:
        cluster.stop()
