"""`manage.py run_simulated_drones N`: provision N simulated drones and fly them (make run DRONES=N).

Each drone gets its own broker credentials in the demo organisation (or --org), then the
simulated-fleet launcher (firmware.sim.fleet) starts a software flight controller and the
real agent per drone. On a broker cluster every agent is given every node (MQTT_URLS) and
fails over between them.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from urllib.parse import urlsplit

from django.conf import settings
from django.core.management.base import BaseCommand, CommandError

from fleet.credentials import ProvisioningError, provision


class Command(BaseCommand):
    help = "Provision N simulated drones and run them (simulator + onboard agent each)."

    def add_arguments(self, parser) -> None:  # type: ignore[no-untyped-def]
        parser.add_argument("count", type=int)
        parser.add_argument("--org", default="demo")
        parser.add_argument("--prefix", default="SIM")
        parser.add_argument(
            "--home",
            default=os.environ.get("SIM_HOME", "40.6303,-8.6575"),
            help="LAT,LON where the simulated drones stand (default: Aveiro university campus)",
        )
        parser.add_argument(
            "--time-scale", type=float, default=float(os.environ.get("SIM_TIME_SCALE", "1"))
        )
        # The past view works out of the box: every simulated drone streams its synthetic
        # camera and its pose (0 turns a stream off).
        parser.add_argument(
            "--video-rate",
            type=float,
            default=float(os.environ.get("SIM_VIDEO_RATE", "2")),
            help="camera frames per second each drone sends (default 2)",
        )
        parser.add_argument(
            "--pose-rate",
            type=float,
            default=float(os.environ.get("SIM_POSE_RATE", "30")),
            help="pose samples per second each drone sends (default 30)",
        )
        # Live video to the media server (docs/video.md); 0 turns it off.
        parser.add_argument(
            "--live-fps",
            type=float,
            default=float(os.environ.get("SIM_LIVE_FPS", "15")),
            help="live video frames per second each drone publishes (default 15, 0: none)",
        )

    def handle(self, *args, **options) -> None:  # type: ignore[no-untyped-def]
        count = options["count"]
        if not 1 <= count <= 500:
            raise CommandError("count must be between 1 and 500")
        entries = []
        for n in range(1, count + 1):
            drone_id = f"{options['prefix']}_{n:03d}"
            try:
                entry = provision(drone_id, options["org"]).to_dict()
            except ProvisioningError as exc:
                raise CommandError(str(exc)) from None
            if not entry["mqtt"].get("urls") and cluster_nodes():
                entry["mqtt"]["urls"] = cluster_nodes()
            entries.append(entry)
        workdir = Path(settings.DATA_DIR) / "fleet"
        workdir.mkdir(parents=True, exist_ok=True)
        credentials = workdir / "credentials.json"
        credentials.write_text(json.dumps(entries))
        credentials.chmod(0o600)
        argv = [
            sys.executable,
            "-m",
            "firmware.sim.fleet",
            "--count",
            str(count),
            "--home",
            options["home"],
            "--credentials-file",
            str(credentials),
            "--time-scale",
            str(options["time_scale"]),
            "--workdir",
            str(workdir),
            "--",
            *streaming_args(options["video_rate"], options["pose_rate"]),
            *live_video_args(options["live_fps"]),
            # Each flight's logs come to this ground by themselves after landing.
            *["--ground-url", settings.LOG_COLLECT_GROUND_URL, "--uplink", "wifi"],
        ]
        self.stdout.write(f"starting {count} simulated drone(s) around {options['home']}")
        self.stdout.flush()
        # Replace this process so Ctrl-C and SIGTERM from `make run` reach the launcher.
        os.execv(sys.executable, argv)


def cluster_nodes() -> list[str]:
    """Every broker node's address (no credentials), when there are several; else none."""
    if len(settings.MQTT_URLS) < 2:
        return []
    nodes = [urlsplit(url) for url in settings.MQTT_URLS]
    return [f"mqtt://{node.hostname}:{node.port or 1883}" for node in nodes]


def live_video_args(fps: float) -> list[str]:
    """The agent flags that publish its camera to the media server (none for 0 fps)."""
    if fps == 0:
        return []
    if not 1 <= fps <= 30:
        raise CommandError("--live-fps must be 0 or within 1..30")
    return ["--media-url", settings.LIVE_VIDEO_PUBLIC_URL, "--live-fps", f"{fps:g}"]


def streaming_args(video_rate: float, pose_rate: float) -> list[str]:
    """The agent flags for the camera and pose streams the past view draws from."""
    if not (0 <= video_rate <= 30 and 0 <= pose_rate <= 200):
        raise CommandError("--video-rate must be within 0..30 and --pose-rate within 0..200")
    return ["--video-rate", f"{video_rate:g}", "--pose-rate", f"{pose_rate:g}"]
