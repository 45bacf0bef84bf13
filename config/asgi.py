"""ASGI entry point: HTTP through Django, websockets through Channels with auth and origin checks."""

import os

import django

# Production unless told otherwise: `make run` and the tests name their settings module.
os.environ.setdefault("DJANGO_SETTINGS_MODULE", "config.settings.production")
# Build Django's app before importing anything that touches models (Channels docs); what
# get_asgi_application() does, with the handler that runs middleware in the event loop.
django.setup(set_prefix=False)

from config.middleware import EventLoopASGIHandler  # noqa: E402

django_asgi_app = EventLoopASGIHandler()

from channels.auth import AuthMiddlewareStack  # noqa: E402
from channels.routing import ProtocolTypeRouter, URLRouter  # noqa: E402
from channels.security.websocket import AllowedHostsOriginValidator  # noqa: E402

from config.bodylimits import BodyLimitASGI  # noqa: E402
from config.lifespan import InstanceLifespan  # noqa: E402
from config.routing import websocket_urlpatterns  # noqa: E402
from config.urlchars import NulInUrlASGI  # noqa: E402
from logs.asgi import UploadLimitMiddleware  # noqa: E402
from tiles.admin import TILE_UPLOAD_PATH, tile_upload_limit  # noqa: E402

# Each server process is listed on the operations page while it runs.
application = InstanceLifespan(
    ProtocolTypeRouter(
        {
            # Oversized bodies (log and map-tile uploads: their own limits) are refused
            # before Django spools them to disk (config/bodylimits.py).
            "http": BodyLimitASGI(
                UploadLimitMiddleware(
                    UploadLimitMiddleware(django_asgi_app),
                    path=TILE_UPLOAD_PATH,
                    limit=tile_upload_limit,
                )
            ),
            # A handshake whose address holds NUL is refused (config/urlchars.py).
            "websocket": AllowedHostsOriginValidator(
                AuthMiddlewareStack(NulInUrlASGI(URLRouter(websocket_urlpatterns)))
            ),
        }
    )
)
