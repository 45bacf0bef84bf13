"""Private Mosquitto brokers for tests and benchmarks that need their own (bridges,
restarts, ACLs, a measured broker nobody else loads).

The shared broker is started by scripts/services.sh; these are extra, throw-away
instances on free ports, configured the same way (no anonymous access, TCP_NODELAY).
"""

from __future__ import annotations

import os
import pwd
import shutil
import signal
import stat
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from runtime.processes import free_port, port_open, wait_for
from workers.dispatch import MAX_PAYLOAD_BYTES

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
MOSQUITTO_PASSWD = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"
# The broker forwards no payload larger than the gateway keeps (pictures); the shared
# broker's config (scripts/services.sh) says the same.
MESSAGE_SIZE_LIMIT = max(MAX_PAYLOAD_BYTES.values())


def broker_user() -> str:
    """Whom Mosquitto runs as when started as root: Debian's `mosquitto`, else `nobody`."""
    try:
        return pwd.getpwnam("mosquitto").pw_name
    except KeyError:
        return "nobody"


def written_folders(config: str) -> list[Path]:
    """Folders the broker writes to that a configuration names (persistence, pid file)."""
    folders = []
    for line in config.splitlines():
        key, _, value = line.strip().partition(" ")
        if key == "persistence_location" and value:
            folders.append(Path(value.strip()))
        elif key == "pid_file" and value:
            folders.append(Path(value.strip()).parent)
    return folders


def own_files(directory: Path, elsewhere: list[Path] = ()) -> None:  # type: ignore[assignment]
    """Root: the broker's files belong to its user, and files rewritten later as root
    (passwd and acl, by provisioning) stay readable by its group: a setgid directory and
    mode 0640 (workers.broker.credentials keeps a file's mode when it rewrites it).
    Folders `elsewhere` it writes to become its own too."""
    if os.geteuid() != 0:
        return
    user = pwd.getpwnam(broker_user())
    # It must reach the directory: folders above it that others may not enter (pytest's
    # 0700 temporary roots) get the execute bit only, so nothing in them can be listed.
    for parent in directory.resolve().parents:
        mode = parent.stat().st_mode
        if not mode & stat.S_IXOTH:
            parent.chmod(stat.S_IMODE(mode) | stat.S_IXOTH)
    for folder in elsewhere:
        if folder.is_dir() and folder.resolve() != directory.resolve():
            os.chown(folder, user.pw_uid, user.pw_gid)
    for path in [directory, *directory.rglob("*")]:
        os.chown(path, user.pw_uid, user.pw_gid)
        if path.is_file() and path.name != "mosquitto.conf":
            path.chmod(0o640)
    directory.chmod(0o2770)


@dataclass
class Broker:
    directory: Path
    port: int
    users: dict[str, str]
    acl: str
    extra_config: str = ""
    # (certificate, key) PEM files: a TLS listener on tls_port besides the plain one.
    tls: tuple[Path, Path] | None = None
    tls_port: int = 0
    process: subprocess.Popen | None = None
    log: Path = field(init=False)

    def __post_init__(self) -> None:
        self.log = self.directory / "mosquitto.log"

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def url_for(self, user: str) -> str:
        return f"mqtt://{user}:{self.users[user]}@127.0.0.1:{self.port}"

    def tls_url_for(self, user: str) -> str:
        return f"mqtts://{user}:{self.users[user]}@127.0.0.1:{self.tls_port}"

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
        # Started as root, it runs as an unprivileged user once its ports are open.
        lines.append(f"user {broker_user()}")
        lines += self._tls_lines()
        text = "\n".join(lines) + "\n" + self.extra_config
        conf.write_text(text)
        own_files(self.directory, written_folders(text))
        return conf

    def _tls_lines(self) -> list[str]:
        """A TLS listener on `tls_port` with copies of the certificate and key that the
        broker's user may read."""
        if self.tls is None:
            return []
        tls = self.directory / "tls"
        tls.mkdir(exist_ok=True)
        cert, key = tls / "cert.pem", tls / "key.pem"
        shutil.copyfile(self.tls[0], cert)
        shutil.copyfile(self.tls[1], key)
        return [f"listener {self.tls_port} 127.0.0.1", f"certfile {cert}", f"keyfile {key}",
                "tls_version tlsv1.2"]  # fmt: skip

    def start(self, timeout: float = 10.0) -> Broker:
        conf = self.write_config()
        self.process = subprocess.Popen(
            [MOSQUITTO, "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
        )
        process = self.process
        ports = [self.port, *([self.tls_port] if self.tls is not None else [])]

        def up_or_gone() -> bool:
            return process.poll() is not None or all(port_open(port) for port in ports)

        if wait_for(up_or_gone, timeout):
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
    directory: Path,
    users: dict[str, str],
    acl: str = GROUND_AND_DRONES_ACL,
    extra_config: str = "",
    tls: tuple[Path, Path] | None = None,
) -> Broker:
    """A running broker with those users and the project's drone ACL pattern, and with a
    TLS listener too when given a (certificate, key) pair."""
    broker = Broker(directory, free_port(), users, acl, extra_config, tls=tls)
    broker.tls_port = free_port() if tls is not None else 0
    return broker.start()
