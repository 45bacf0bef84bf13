"""Remote ID and airworthiness (docs/remote-id.md)."""

from __future__ import annotations

from config.env import env

# Whether a new organisation must fly with Remote ID (serial number, operator registration
# and a working broadcast before arming); each organisation's admins can change theirs.
REMOTE_ID_REQUIRED_DEFAULT = env.bool("REMOTE_ID_REQUIRED_DEFAULT", True)
# A drone flying with a failing Remote ID raises one WARNING alert per this many seconds.
REMOTE_ID_ALERT_EVERY_S = env.int("REMOTE_ID_ALERT_EVERY_S", 600)
