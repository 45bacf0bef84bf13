import pytest
from django.urls import reverse

PASSWORD = "correct horse battery staple"


def test_the_portal_sends_anonymous_visitors_to_the_login_page(client, world):
    response = client.get("/")
    assert response.status_code == 302
    assert response["Location"].startswith(reverse("login"))


def test_a_member_logs_in_and_sees_the_fleet_of_their_organisation(client, world):
    response = client.post(
        reverse("login"), {"username": "owner", "password": PASSWORD}, follow=True
    )
    assert response.status_code == 200
    page = response.content.decode()
    for item in ("Fleet", "Missions", "Telemetry", "Admin"):
        assert item in page
    # The fleet table is served in pages to the page's script.
    listed = [row["drone_id"] for row in client.get("/fleet/table/").json()["results"]]
    assert listed == ["ACME_1"]


def test_wrong_credentials_are_refused_with_a_message(client, world):
    response = client.post(reverse("login"), {"username": "owner", "password": "nope"})
    assert response.status_code == 200
    assert "did not match" in response.content.decode()
    assert "_auth_user_id" not in client.session


def test_logout_ends_the_session(client, world):
    client.force_login(world.owner)
    response = client.post(reverse("logout"))
    assert response.status_code == 302
    assert client.get("/").status_code == 302


def test_a_user_changes_their_password(client, world):
    client.force_login(world.owner)
    response = client.post(
        reverse("password_change"),
        {
            "old_password": PASSWORD,
            "new_password1": "a-new long passphrase",
            "new_password2": "a-new long passphrase",
        },
    )
    assert response.status_code == 302
    world.owner.refresh_from_db()
    assert world.owner.check_password("a-new long passphrase")


def test_a_login_post_without_csrf_token_is_refused(world):
    from django.test import Client

    strict = Client(enforce_csrf_checks=True)
    response = strict.post(reverse("login"), {"username": "owner", "password": PASSWORD})
    assert response.status_code == 403


@pytest.mark.django_db
def test_the_demo_bootstrap_is_idempotent_and_keeps_the_password(tmp_path, settings):
    from django.contrib.auth import authenticate
    from django.core.management import call_command

    settings.DATA_DIR = str(tmp_path)
    call_command("bootstrap_demo")
    password = (tmp_path / "admin_password").read_text().strip()
    call_command("bootstrap_demo")
    assert (tmp_path / "admin_password").read_text().strip() == password
    user = authenticate(username="admin", password=password)
    assert user is not None and user.is_superuser
    assert user.memberships.get().organisation.slug == "demo"
    assert user.memberships.get().role == "admin"
