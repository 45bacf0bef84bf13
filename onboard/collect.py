"""Logs collected by themselves: after each landing the agent uploads the flight's logs to
the ground (`POST /api/v1/logs/collect/`, docs/protocol.md "Logs collected by themselves").

Each log to send is a manifest in `<log dir>/collect/` (the file, its kind, size, SHA-256
and flight span), written when the flight ends, so an agent restarted mid-upload goes on
where it was. Uploads run on a thread of their own over HTTP, never on the broker
connection that carries commands and telemetry, and only while the drone is disarmed.
Bytes go out in chunks of CHUNK_BYTES at no more than `rate` bytes per second on average
(a token bucket: the chunk waits until the bucket holds its size). After a lost link the
offer is repeated and the ground's answer (`received`) says where to go on.

Whether to collect is the operator's, per drone, one of three modes:

    always          every link (the default)
    ground_links    only while the uplink is Wi-Fi or wired ground
    off             nothing is queued, fetched or sent

The operator sets it on the ground (the drone's page or its REST resource); the ground
sends it with the drone's flight envelope (`log_collection` on `<id>/envelope/in`, at
every connection and at every change) and the agent keeps the last one received in
`policy_file` across restarts, as it keeps the envelope. Once the ground has said, its
mode is the one in force; the gear folder's `collect.json` ({"collect": "off"}) decides
only for a drone that has never heard its mode from the ground.

The uplink's type is `--uplink` (how the drone is fitted: wifi, ground, cellular, radio),
overridden by the gear folder's `uplink.json` ({"type": "cellular"}), which whatever
manages the drone's network rewrites when the route changes; gear files are read again
before every upload, so a change takes effect at the next chunk.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

log = logging.getLogger(__name__)

COLLECT_FILE = "collect.json"
UPLINK_FILE = "uplink.json"
MODES = ("always", "ground_links", "off")
GROUND_LINKS = ("wifi", "ground")
CHUNK_BYTES = 256 * 1024
DEFAULT_RATE = 512 * 1024  # bytes per second
HTTP_TIMEOUT_S = 15.0
RETRY_S = (1.0, 30.0)  # first and longest wait after a failed attempt


@dataclass(frozen=True)
class Pending:
    """One log waiting to be uploaded (the manifest's content)."""

    path: str
    kind: str  # "onboard" | "fc"
    size: int
    sha256: str
    flight_start: float
    flight_end: float


def file_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1024 * 1024):
            digest.update(block)
    return digest.hexdigest()


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


@dataclass(frozen=True)
class Policy:
    mode: str
    uplink: str

    @property
    def queue(self) -> bool:
        """Whether a finished flight's logs are kept for upload at all."""
        return self.mode != "off"

    @property
    def send_now(self) -> bool:
        """Whether bytes may go out on the uplink the drone is on now."""
        if self.mode == "always":
            return True
        return self.mode == "ground_links" and self.uplink in GROUND_LINKS


def read_policy(gear_dir: Path | None, default_uplink: str, mode: str | None = None) -> Policy:
    """The mode (the ground's when given, else collect.json) and the current uplink
    (uplink.json, else the flag); an unreadable or unknown mode counts as "always"."""
    if mode is None:
        settings = _read_json(gear_dir / COLLECT_FILE) if gear_dir else {}
        mode = settings.get("collect", "always")
    uplink = _read_json(gear_dir / UPLINK_FILE).get("type") if gear_dir else None
    return Policy(
        mode if mode in MODES else "always",
        str(uplink or default_uplink or "unknown").lower(),
    )


class GroundMode:
    """The mode the ground last sent, kept in `path` (written atomically) across restarts;
    None until the ground has sent one."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.mode: str | None = None
        stored = _read_json(path).get("log_collection") if path is not None else None
        if stored in MODES:
            self.mode = stored

    def set(self, mode: str) -> bool:
        """Adopt the ground's mode; True when it changed."""
        if mode not in MODES:
            raise ValueError(f"log_collection: {mode!r} is not one of {', '.join(MODES)}")
        changed = mode != self.mode
        self.mode = mode
        if changed and self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            partial = self.path.with_suffix(".partial")
            partial.write_text(json.dumps({"log_collection": mode}), encoding="utf-8")
            partial.replace(self.path)
        return changed


class Refused(Exception):
    """The ground will not take this log (too large, unsupported): it is dropped."""


class GroundClient:
    """The collect endpoints, signed in as the drone (HTTP Basic, its broker password)."""

    def __init__(self, base_url: str, drone_id: str, password: str) -> None:
        self.base = base_url.rstrip("/") + "/api/v1/logs/collect/"
        token = base64.b64encode(f"{drone_id}:{password}".encode()).decode()
        self.auth = f"Basic {token}"

    def _call(self, method: str, url: str, body: bytes, content_type: str) -> dict:
        request = urllib.request.Request(url, data=body, method=method)
        request.add_header("Authorization", self.auth)
        request.add_header("Content-Type", content_type)
        try:
            with urllib.request.urlopen(request, timeout=HTTP_TIMEOUT_S) as response:
                return json.loads(response.read() or b"{}")
        except urllib.error.HTTPError as exc:
            answer = _json_of(exc)
            if exc.code == 409 and "received" in answer:
                return answer  # the ground holds another offset: go on from there
            if exc.code in (413, 422) and answer.get("code") != "hash_mismatch":
                raise Refused(answer.get("detail") or str(exc)) from None
            raise

    def offer(self, pending: Pending) -> dict:
        body = {
            "kind": pending.kind,
            "name": Path(pending.path).name,
            "size": pending.size,
            "sha256": pending.sha256,
            "flight_start": pending.flight_start,
            "flight_end": pending.flight_end,
        }
        return self._call("POST", self.base, json.dumps(body).encode(), "application/json")

    def chunk(self, upload_id: str, offset: int, data: bytes) -> dict:
        url = f"{self.base}{upload_id}/?offset={offset}"
        return self._call("PUT", url, data, "application/octet-stream")


def _json_of(exc: urllib.error.HTTPError) -> dict:
    try:
        data = json.loads(exc.read() or b"{}")
    except ValueError:
        return {}
    return data if isinstance(data, dict) else {}


class TokenBucket:
    """At most `rate` bytes per second on average, bursts up to `burst` bytes."""

    def __init__(self, rate: float, burst: float, clock: Callable[[], float] = time.monotonic):
        self.rate = rate
        self.burst = burst
        self.clock = clock
        self.tokens = burst
        self.at = clock()

    def wait_time(self, size: int) -> float:
        now = self.clock()
        self.tokens = min(self.burst, self.tokens + (now - self.at) * self.rate)
        self.at = now
        if self.tokens >= size:
            self.tokens -= size
            return 0.0
        return (size - self.tokens) / self.rate


class Collector:
    """Queues each finished flight's logs and uploads them, one at a time, in order."""

    def __init__(
        self,
        folder: Path,
        client: GroundClient | None,
        *,
        gear_dir: Path | None = None,
        uplink: str = "unknown",
        rate: float = DEFAULT_RATE,
        may_send: Callable[[], bool] = lambda: True,
        fetch: Callable[[str], Path | None] | None = None,
        chunk: int = CHUNK_BYTES,
        policy_file: Path | None = None,
    ) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.client = client
        self.gear_dir = gear_dir
        self.uplink = uplink
        self.chunk = chunk
        self.bucket = TokenBucket(rate, max(rate, chunk))
        self.may_send = may_send
        # The flight controller's log of the last flight, by a stem naming the flight
        # (onboard.fc.mavlink_logs); None when the flight controller keeps none to fetch.
        self.fetch = fetch
        self.ground_mode = GroundMode(policy_file)
        self.uploaded: list[dict] = []
        self.sent_bytes = 0
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._retry = RETRY_S[0]
        # A flight during which collection was off at any moment stays on the drone, even
        # when collection is back on by the time the landing is seen.
        self._in_flight = False
        self._off_in_flight = False

    # -- the queue ------------------------------------------------------------------------

    def policy(self) -> Policy:
        return read_policy(self.gear_dir, self.uplink, self.ground_mode.mode)

    def set_mode(self, mode: str) -> None:
        """The ground's mode for this drone (with its envelope); a change wakes the uploader."""
        if self.ground_mode.set(mode):
            log.info("log collection: %s (from the ground)", mode)
            self._wake.set()
        if self._in_flight and not self.policy().queue:
            self._off_in_flight = True

    def flight_started(self) -> None:
        """An arming: the flight's logs are collected only if collection stays on until
        its landing."""
        self._in_flight = True
        self._off_in_flight = not self.policy().queue

    def add(self, path: Path, kind: str, flight_start: float, flight_end: float) -> bool:
        """Queue a finished log; False when the operator turned collection off."""
        if not self.policy().queue:
            log.info("log collection is off: %s stays on the drone", path.name)
            return False
        pending = Pending(
            str(path), kind, path.stat().st_size, file_digest(path), flight_start, flight_end
        )
        manifest = self.folder / f"{path.name}.{kind}.json"
        temporary = manifest.with_suffix(".tmp")
        temporary.write_text(json.dumps(asdict(pending)), encoding="utf-8")
        temporary.replace(manifest)
        self._wake.set()
        return True

    def flight_ended(self, archive: Path | None, flight_start: float, flight_end: float) -> None:
        """A landing: job files for the onboard recording and for the flight controller's
        log, so a restart still sends them. Called from the agent's supervisor, which
        must not wait: the uploader's thread hashes and queues them (`_landed`)."""
        off_in_flight, self._in_flight = self._off_in_flight, False
        if off_in_flight or not self.policy().queue:
            log.info("log collection was off during the flight: its logs stay on the drone")
            return
        stem = self.folder / f"flight_{round(flight_start * 1000)}"
        if archive is not None:
            job = [str(archive), flight_start, flight_end]
            stem.with_suffix(".landed").write_text(json.dumps(job), encoding="utf-8")
        if self.fetch is not None:
            stem.with_suffix(".fetch").write_text(
                json.dumps([flight_start, flight_end]), encoding="utf-8"
            )
        self._wake.set()

    def _landed(self) -> None:
        """Queue the onboard recordings of the flights ended (or drop them: collection off)."""
        for job in sorted(self.folder.glob("*.landed")):
            try:
                path, start, end = json.loads(job.read_text("utf-8"))
                self.add(Path(path), "onboard", float(start), float(end))
            except (OSError, ValueError, TypeError) as exc:
                log.warning("could not queue the recording of %s: %s", job.stem, exc)
            job.unlink(missing_ok=True)

    def _fetch_jobs(self) -> bool:
        """Fetch the flight controller's logs still owed; True when one must wait."""
        for job in sorted(self.folder.glob("*.fetch")):
            if not self.policy().queue:
                job.unlink(missing_ok=True)  # collection off: not fetched either
                continue
            if self._stop.is_set() or not self.may_send():
                return True
            try:
                start, end = json.loads(job.read_text("utf-8"))
                assert self.fetch is not None
                path = self.fetch(job.stem)
            except (ValueError, TypeError):
                job.unlink(missing_ok=True)
                continue
            except Exception as exc:  # noqa: BLE001 - link lost, armed, no answer: later
                log.info("fetching the flight controller's log paused: %s", exc)
                return True
            if path is not None:
                self.add(path, "fc", float(start), float(end))
            job.unlink(missing_ok=True)
        return False

    def pending(self) -> list[tuple[Path, Pending]]:
        found = []
        for manifest in sorted(self.folder.glob("*.json"), key=lambda p: p.stat().st_mtime):
            try:
                found.append((manifest, Pending(**json.loads(manifest.read_text("utf-8")))))
            except (OSError, ValueError, TypeError):
                log.warning("dropping unreadable upload manifest %s", manifest.name)
                manifest.unlink(missing_ok=True)
        return found

    # -- the uploader thread --------------------------------------------------------------

    def start(self) -> None:
        if self.client is None:
            return
        self._thread = threading.Thread(target=self._run, name="log-collect", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(5)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.clear()
            waiting = self.pass_once()
            self._wake.wait(self._retry if waiting else 5.0)

    def pass_once(self) -> bool:
        """Fetch, then upload, what may go now; True when something is still waiting."""
        self._landed()
        if self.fetch is not None and self._fetch_jobs():
            return True
        for manifest, pending in self.pending():
            if not Path(pending.path).is_file():
                log.warning("%s is gone from the drone: not uploaded", pending.path)
                manifest.unlink(missing_ok=True)
                continue
            if self._stop.is_set() or not self._may_send():
                return True
            try:
                self._upload(manifest, pending)
                self._retry = RETRY_S[0]
            except Refused as exc:
                log.warning("the ground refused %s: %s", pending.path, exc)
                manifest.unlink(missing_ok=True)
            except (OSError, urllib.error.URLError, ValueError) as exc:
                log.info("log upload of %s paused: %s", Path(pending.path).name, exc)
                self._retry = min(RETRY_S[1], self._retry * 2)
                return True
        return False

    def _may_send(self) -> bool:
        return self.policy().send_now and self.may_send()

    def _upload(self, manifest: Path, pending: Pending) -> None:
        assert self.client is not None
        answer = self.client.offer(pending)
        upload_id = answer["id"]
        with open(pending.path, "rb") as f:
            while answer.get("status") != "stored":
                if self._stop.is_set() or not self._may_send():
                    raise OSError("uploads paused (armed, link type or stopping)")
                offset = int(answer["received"])
                f.seek(offset)
                data = f.read(self.chunk)
                if not data:
                    raise ValueError(f"{pending.path} is shorter than the {pending.size} offered")
                self._pace(len(data))
                answer = self.client.chunk(upload_id, offset, data)
                self.sent_bytes += len(data)
        self.uploaded.append(answer)
        log.info("uploaded %s (%s): log %s", Path(pending.path).name, pending.kind, answer["log"])
        manifest.unlink(missing_ok=True)

    def _pace(self, size: int) -> None:
        while (wait := self.bucket.wait_time(size)) > 0:
            if self._stop.wait(wait):
                raise OSError("stopping")
