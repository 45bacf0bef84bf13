"""Private Mosquitto brokers for tests and benchmarks that need their own (bridges,
restarts, ACLs, a measured broker nobody else loads).

The shared broker is started by scripts/services.sh; these are extra, throw-away
instances on free ports, configured the same way (no anonymous access, TCP_NODELAY).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from onboard.processes import free_port, port_open, wait_for
from workers.dispatch import MAX_PAYLOAD_BYTES

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
MOSQUITTO_PASSWD = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"
# The broker forwards no payload larger than the gateway keeps (pictures); the shared
# broker's config (scripts/services.sh) says the same.
MESSAGE_SIZE_LIMIT = max(MAX_PAYLOAD_BYTES.values())


@dataclass
class Broker:
    directory: Path
    port: int
    users: dict[str, str]
    acl: str
    extra_config: str = ""
    process: subprocess.Popen | None = None
    log: Path = field(init=False)

    def __post_init__(self) -> None:
        self.log = self.directory / "mosquitto.log"

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def url_for(self, user: str) -> str:
        return f"mqtt://{user}:{self.users[user]}@127.0.0.1:{self.port}"

    def write_config(self) -> Path:
        self.directory.mkdir(parents=True, exist_ok=True)
        passwd = self.directory / "passwd"
        # Plain text hashed in place by one call (a thousand users take a second, not
        # minutes); that format cannot hold a password with a colon: those one by one.
        plain = {user: password for user, password in self.users.items() if ":" not in password}
        passwd.write_text("".join(f"{user}:{password}\n" for user, password in plain.items()))
        if plain:
            subprocess.run([MOSQUITTO_PASSWD, "-U", str(passwd)], check=True)
        for user, password in self.users.items():
            if user not in plain:
                subprocess.run([MOSQUITTO_PASSWD, "-b", str(passwd), user, password], check=True)
        acl = self.directory / "acl"
        acl.write_text(self.acl)
        conf = self.directory / "mosquitto.conf"
        lines = [
            f"listener {self.port} 127.0.0.1",
            "allow_anonymous false",
            "set_tcp_nodelay true",
            f"message_size_limit {MESSAGE_SIZE_LIMIT}",
            f"password_file {passwd}",
            f"acl_file {acl}",
            "persistence false",
            f"log_dest file {self.log}",
            "log_type error",
            "log_type warning",
            "log_type notice",
        ]
        if os.geteuid() == 0:
            lines.append("user root")
        conf.write_text("\n".join(lines) + "\n" + self.extra_config)
        return conf

    def start(self, timeout: float = 10.0) -> Broker:
        conf = self.write_config()
        self.process = subprocess.Popen(
            [MOSQUITTO, "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        process = self.process
        if wait_for(lambda: port_open(self.port) or process.poll() is not None, timeout):
            if process.poll() is None:
                return self
            raise RuntimeError(f"mosquitto exited: {self.log.read_text()}")
        raise RuntimeError("mosquitto did not start")

    def stop(self) -> None:
        if self.process and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None

    def restart(self, down_for: float = 0.0) -> None:
        import time

        self.stop()
        time.sleep(down_for)
        self.start()


GROUND_AND_DRONES_ACL = """\
user ground
topic readwrite #
topic read $SYS/#

pattern write %u/+/out
pattern read %u/+/in
"""


def start_broker(
    directory: Path, users: dict[str, str], acl: str = GROUND_AND_DRONES_ACL, extra_config: str = ""
) -> Broker:
    """A running broker with those users and the project's drone ACL pattern."""
    return Broker(directory, free_port(), users, acl, extra_config).start()
