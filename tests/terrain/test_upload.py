"""The admin's terrain upload: staff with the right to add terrain tiles only, refused
before its body is read otherwise, bounded in size, and checked whole before anything is
kept."""

from __future__ import annotations

import pytest
from django.contrib.auth import get_user_model
from django.contrib.auth.models import Permission
from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client

from terrain.models import TerrainTile
from tests.logs.test_upload_gate import MB, MULTIPART, _session, stream_upload

from .conftest import stored_files
from .dem import hgt_name

PATH = "/admin/terrain/terraintile/add/"


def staff(username: str = "terrain-staff", may_add: bool = True):  # type: ignore[no-untyped-def]
    user = get_user_model().objects.create_user(username, password="x", is_staff=True)
    rights = ["view_terraintile", "add_terraintile"] if may_add else ["view_terraintile"]
    user.user_permissions.add(*Permission.objects.filter(codename__in=rights))
    return user


def client_of(user) -> Client:  # type: ignore[no-untyped-def]
    client = Client()
    client.force_login(user)
    return client


@pytest.mark.django_db
def test_staff_upload_an_srtm_tile_and_see_what_was_imported(terrain_dir, hill):
    page = client_of(staff()).get(PATH)
    assert page.status_code == 200 and b"terrain-import" in page.content
    upload = SimpleUploadedFile(hgt_name(hill), hill.samples.astype(">i2").tobytes())
    response = client_of(staff("second")).post(PATH, {"file": upload}, follow=True)
    assert response.status_code == 200
    tile = TerrainTile.objects.get()
    assert (tile.name, tile.source) == ("N40W009.hgt", "N40W009.hgt")
    assert f"Imported {tile}" in response.content.decode()
    assert stored_files(terrain_dir) == [f"tiles/{tile.pk}.npy"]


@pytest.mark.django_db
def test_a_bad_or_oversized_upload_is_refused_and_changes_nothing(terrain_dir, hill, settings):
    client = client_of(staff())
    truncated = SimpleUploadedFile("N40W009.hgt", hill.samples.astype(">i2").tobytes()[:-2])
    response = client.post(PATH, {"file": truncated})
    assert response.status_code == 200
    assert "holds 2884800 bytes; an SRTM .hgt file holds" in response.content.decode()
    settings.TERRAIN_UPLOAD_MAX_BYTES = 1000
    whole = SimpleUploadedFile("N40W009.hgt", hill.samples.astype(">i2").tobytes())
    response = client.post(PATH, {"file": whole})
    assert "larger than the limit of 1000 bytes" in response.content.decode()
    assert not TerrainTile.objects.exists() and stored_files(terrain_dir) == []


@pytest.mark.django_db
def test_staff_without_the_right_and_members_cannot_import(terrain_dir, hill, world):
    upload = SimpleUploadedFile("N40W009.hgt", hill.samples.astype(">i2").tobytes())
    assert client_of(staff(may_add=False)).post(PATH, {"file": upload}).status_code == 403
    # An organisation's admin is no staff: the admin site sends them to its login.
    response = client_of(world.owner).post(PATH, {"file": upload})
    assert response.status_code == 302 and "/login/" in response["Location"]
    assert not TerrainTile.objects.exists()


@pytest.mark.parametrize("chunked", [False, True], ids=["content-length", "chunked"])
def test_strangers_are_refused_before_a_megabyte_is_read(live_asgi, world_tx, chunked):
    outcome = stream_upload(live_asgi.url, PATH, MULTIPART, chunked=chunked)
    assert outcome.status == 401, outcome
    assert outcome.taken < MB, f"the server took {outcome.taken} bytes"
    headers = {**MULTIPART, **_session(world_tx.owner)}  # an organisation admin, not staff
    outcome = stream_upload(live_asgi.url, PATH, headers, chunked=chunked)
    assert outcome.status == 403 and outcome.taken < MB, outcome


def test_a_body_over_the_limit_is_refused_before_it_is_read(live_asgi, world_tx):
    headers = {**MULTIPART, **_session(staff("big"))}
    outcome = stream_upload(live_asgi.url, PATH, headers, chunked=False)
    assert outcome.status == 413 and outcome.body["code"] == "too_large", outcome
    assert outcome.taken < MB


@pytest.mark.django_db
def test_deleting_a_tile_in_the_admin_removes_its_grid(terrain_dir, hill, tmp_path):
    from terrain.importer import import_path

    from .dem import write_hgt

    tile = import_path(write_hgt(tmp_path, hill)).tiles[0]
    user = staff()
    user.user_permissions.add(Permission.objects.get(codename="delete_terraintile"))
    response = client_of(user).post(
        f"/admin/terrain/terraintile/{tile.pk}/delete/", {"post": "yes"}
    )
    assert response.status_code == 302
    assert not TerrainTile.objects.exists() and stored_files(terrain_dir) == []
