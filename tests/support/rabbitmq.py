"""A RabbitMQ cluster for tests, started and stopped by the project's own script.

`scripts/rabbitmq.sh start <profile> <nodes>` runs real RabbitMQ nodes (MQTT and
management plugins) clustered on one machine. Tests get a `RabbitCluster` that knows every
node's URLs and can stop, kill and restart single nodes for fault tests.

Each pytest process uses its own profile and port base (RABBIT_PROFILE, RABBIT_PORT_BASE),
so parallel runs do not share nodes.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
import urllib.error
import urllib.parse
import urllib.request
from dataclasses import dataclass, field

from .paths import ROOT

SCRIPT = str(ROOT / "scripts" / "rabbitmq.sh")


def available() -> bool:
    return os.path.exists("/usr/lib/rabbitmq/bin/rabbitmq-server")


def _run(*args: str, env: dict[str, str] | None = None, timeout: float = 240) -> str:
    result = subprocess.run(
        [SCRIPT, *args],
        env={**os.environ, **(env or {})},
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    if result.returncode != 0:
        raise RuntimeError(
            f"rabbitmq.sh {' '.join(args)} failed:\n{result.stdout}\n{result.stderr}"
        )
    return result.stdout


@dataclass
class RabbitCluster:
    profile: str
    nodes: int
    port_base: int
    env: dict[str, str] = field(default_factory=dict)

    @property
    def _script_env(self) -> dict[str, str]:
        # DATA_DIR from the test env file (.data/test) would put every profile's nodes in
        # one directory: each profile keeps its own.
        return {
            "RABBIT_PORT_BASE": str(self.port_base),
            "DATA_DIR": str(ROOT / ".data" / self.profile),
        }

    def start(self) -> RabbitCluster:
        _run("start", self.profile, str(self.nodes), env=self._script_env)
        out = _run("env", self.profile, str(self.nodes), env=self._script_env)
        self.env = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
        return self

    def stop(self) -> None:
        _run("stop", self.profile, env=self._script_env)

    def stop_node(self, i: int) -> None:
        _run("stop-node", self.profile, str(i), env=self._script_env)

    def kill_node(self, i: int) -> None:
        _run("kill-node", self.profile, str(i), env=self._script_env)

    def start_node(self, i: int) -> None:
        _run("start-node", self.profile, str(i), env=self._script_env)

    # -- addresses ------------------------------------------------------------------------

    def mqtt_port(self, i: int) -> int:
        return self.port_base + i

    def amqp_port(self, i: int) -> int:
        return self.port_base + 10 + i

    def api_port(self, i: int) -> int:
        return self.port_base + 20 + i

    @property
    def mqtt_urls(self) -> list[str]:
        return self.env["MQTT_URLS"].split(",")

    @property
    def amqp_urls(self) -> list[str]:
        return self.env["AMQP_URLS"].split(",")

    @property
    def api_urls(self) -> list[str]:
        return self.env["RABBITMQ_API_URLS"].split(",")

    def settings_env(self, first: int = 1) -> dict[str, str]:
        """What a ground process needs in its environment to use this cluster, trying node
        `first` before the others."""
        env = {"MQTT_BROKER": self.env["MQTT_BROKER"]}
        for key in ("MQTT_URLS", "AMQP_URLS", "RABBITMQ_API_URLS"):
            env[key] = ",".join(self.node_order(self.env[key].split(","), first))
        env["MQTT_URL"] = env["MQTT_URLS"].split(",")[0]
        return env

    def node_order(self, per_node: list[str], first: int = 1) -> list[str]:
        """`per_node` (one entry per node, node 1's first) from node `first` on, in turn."""
        return per_node[first - 1 :] + per_node[: first - 1]

    # -- management API ---------------------------------------------------------------------

    def api(self, method: str, path: str, body: object | None = None, node: int = 1) -> object:
        """Call node `node`'s management API as the admin user; JSON in, JSON out."""
        parts = urllib.parse.urlsplit(self.api_urls[node - 1])
        auth = base64.b64encode(
            f"{urllib.parse.unquote(parts.username or '')}:{urllib.parse.unquote(parts.password or '')}".encode()
        ).decode()
        url = f"http://{parts.hostname}:{parts.port}{parts.path}/{path.lstrip('/')}"
        request = urllib.request.Request(
            url,
            method=method,
            data=None if body is None else json.dumps(body).encode(),
            headers={"content-type": "application/json", "authorization": f"Basic {auth}"},
        )
        with urllib.request.urlopen(request, timeout=10) as response:
            raw = response.read()
        return json.loads(raw) if raw else None


def cluster_for_this_run(nodes: int = 2) -> RabbitCluster:
    """The cluster of this pytest process: profile and port base from the environment."""
    profile = os.environ.get("RABBIT_PROFILE", "test-rabbitmq")
    base = int(os.environ.get("RABBIT_PORT_BASE", "18900"))
    return RabbitCluster(profile=profile, nodes=nodes, port_base=base)
