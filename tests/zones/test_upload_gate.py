"""The admin's zone file upload is judged from its headers: only staff with the right to
add zones may send a body; anyone else is answered before a megabyte is read
(config/uploadgate.py, docs/security.md "Published zones")."""

from __future__ import annotations

import pytest
from django.contrib.auth import get_user_model
from django.contrib.auth.models import Permission

from tests.logs.test_upload_gate import MB, MULTIPART, _session, stream_upload
from zones.admin import ZONES_UPLOAD_PATH


def _staff(username: str, *, may_add: bool):  # type: ignore[no-untyped-def]
    user = get_user_model().objects.create_user(username, password="x", is_staff=True)
    rights = ["view_zone", "add_zone"] if may_add else ["view_zone"]
    user.user_permissions.add(*Permission.objects.filter(codename__in=rights))
    return user


@pytest.mark.parametrize("chunked", [False, True], ids=["content-length", "chunked"])
def test_only_staff_who_may_add_zones_send_a_zone_file(live_asgi, world_tx, chunked):
    outcome = stream_upload(live_asgi.url, ZONES_UPLOAD_PATH, MULTIPART, chunked=chunked)
    assert outcome.status == 401 and outcome.taken < MB, outcome
    # A viewer, an organisation's admin (no staff) and staff without the right.
    for user in (world_tx.viewer, world_tx.owner, _staff("zones-looker", may_add=False)):
        headers = {**MULTIPART, **_session(user)}
        outcome = stream_upload(live_asgi.url, ZONES_UPLOAD_PATH, headers, chunked=chunked)
        assert outcome.status == 403 and outcome.taken < MB, (user.username, outcome)
    # Staff with the right are admitted: the server reads what they send.
    headers = {**MULTIPART, **_session(_staff("zones-importer", may_add=True))}
    part = b'--x\r\nContent-Disposition: form-data; name="file"; filename="z.geojson"\r\n\r\n'
    outcome = stream_upload(
        live_asgi.url,
        ZONES_UPLOAD_PATH,
        headers,
        chunked=False,
        limit=4 * MB,
        prefix=part,
        announced=8 * MB,
    )
    assert outcome.taken >= 4 * MB - 256 * 1024, outcome
