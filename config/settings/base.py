"""Settings shared by every environment, one module per concern; values come from the
environment (config/env.py). A new concern gets a module of its own, imported here."""

from __future__ import annotations

from .accounts import *  # noqa: F403
from .airspace import *  # noqa: F403
from .alerts import *  # noqa: F403
from .broker import *  # noqa: F403
from .checklists import *  # noqa: F403
from .core import *  # noqa: F403
from .fleet import *  # noqa: F403
from .livevideo import *  # noqa: F403
from .logchecks import *  # noqa: F403
from .logcollect import *  # noqa: F403
from .logs import *  # noqa: F403
from .maintenance import *  # noqa: F403
from .missions import *  # noqa: F403
from .operations import *  # noqa: F403
from .pastview import *  # noqa: F403
from .records import *  # noqa: F403
from .remoteid import *  # noqa: F403
from .security import *  # noqa: F403
from .tasks import *  # noqa: F403
from .telemetry import *  # noqa: F403
from .terrain import *  # noqa: F403
from .tiles import *  # noqa: F403
from .traffic import *  # noqa: F403
from .zones import *  # noqa: F403
