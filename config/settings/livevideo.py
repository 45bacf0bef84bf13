"""Live video (docs/video.md): where the media server listens, its viewer tickets and
what bounds its cost."""

from __future__ import annotations

from config.env import env

# The media server's ground-side HTTP (viewers through the portal, stream state, stills):
# loopback only. Drones publish on LIVE_VIDEO_DRONE_PORT, bound to LIVE_VIDEO_DRONE_BIND.
LIVE_VIDEO_PORT = env.int("LIVE_VIDEO_PORT", 8890)
LIVE_VIDEO_URL = env.str("LIVE_VIDEO_URL", f"http://127.0.0.1:{LIVE_VIDEO_PORT}")
LIVE_VIDEO_DRONE_PORT = env.int("LIVE_VIDEO_DRONE_PORT", 8891)
LIVE_VIDEO_DRONE_BIND = env.str("LIVE_VIDEO_DRONE_BIND", "127.0.0.1")
# The UDP ports the media server's WebRTC sessions use (ICE and media), "first-last", so a
# firewall opens only these (livevideo/ports.py); empty: ephemeral ports. Each session
# takes one port per network interface: size the range for LIVE_VIDEO_MAX_STREAMS +
# LIVE_VIDEO_MAX_VIEWERS sessions on every interface.
LIVE_VIDEO_UDP_PORTS = env.str("LIVE_VIDEO_UDP_PORTS", "")
# What drones are told to publish to (their provisioning and `make run`'s simulated ones).
LIVE_VIDEO_PUBLIC_URL = env.str(
    "LIVE_VIDEO_PUBLIC_URL", f"http://127.0.0.1:{LIVE_VIDEO_DRONE_PORT}"
)
# The key viewer tickets are signed with (scripts/services.sh keeps it in the secrets
# folder); empty: derived from SECRET_KEY, which every ground process shares too.
LIVE_VIDEO_TICKET_KEY = env.str("LIVE_VIDEO_TICKET_KEY", "")
LIVE_VIDEO_TICKET_TTL_S = env.float("LIVE_VIDEO_TICKET_TTL_S", 60.0)
# The relay's bounds (livevideo.relay.Limits).
LIVE_VIDEO_MAX_STREAMS = env.int("LIVE_VIDEO_MAX_STREAMS", 32)
LIVE_VIDEO_MAX_VIEWERS = env.int("LIVE_VIDEO_MAX_VIEWERS", 64)
LIVE_VIDEO_MAX_VIEWERS_PER_STREAM = env.int("LIVE_VIDEO_MAX_VIEWERS_PER_STREAM", 8)
LIVE_VIDEO_MAX_BITRATE_BPS = env.int("LIVE_VIDEO_MAX_BITRATE_BPS", 4_000_000)
LIVE_VIDEO_MAX_WIDTH = env.int("LIVE_VIDEO_MAX_WIDTH", 1280)
LIVE_VIDEO_MAX_HEIGHT = env.int("LIVE_VIDEO_MAX_HEIGHT", 720)
# Teleoperation shows the live video while it is at most this old (glass to glass) and
# switches to the past view, saying so, when it is older or stops: a picture later than
# this is one the drone has already flown out of at teleoperation speeds (docs/video.md).
LIVE_VIDEO_TELEOP_MAX_DELAY_MS = env.float("LIVE_VIDEO_TELEOP_MAX_DELAY_MS", 500.0)
# Every stream is recorded on the ground (livevideo/recording.py) under MEDIA_ROOT, each
# recording at most this many bytes (it stops growing there and is kept, truncated).
LIVE_VIDEO_RECORD = env.bool("LIVE_VIDEO_RECORD", True)
LIVE_VIDEO_RECORDING_MAX_BYTES = env.int("LIVE_VIDEO_RECORDING_MAX_BYTES", 200 * 1024 * 1024)
# Recordings are deleted when older than this many days, and an organisation's oldest
# ones beyond this many bytes in all (livevideo/retention.py, hourly), unless the
# organisation chose its own period or cap (livevideo.models.VideoRetention).
LIVE_VIDEO_RECORDING_KEEP_DAYS = env.float("LIVE_VIDEO_RECORDING_KEEP_DAYS", 30.0)
LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG = env.int(
    "LIVE_VIDEO_RECORDINGS_MAX_BYTES_PER_ORG", 20 * 1024**3
)
LIVE_VIDEO_PRUNE_INTERVAL_S = env.float("LIVE_VIDEO_PRUNE_INTERVAL_S", 3600.0)
