"""Without a settings module every entry point loads production, which refuses to start
until its secrets are set."""

import os
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
# What the test settings loaded into this process's environment from .data/test/env.
SECRETS = (
    "DJANGO_SETTINGS_MODULE",
    "SECRET_KEY",
    "MQTT_URL",
    "REDIS_URL",
    "DATABASE_URL",
    "DEBUG",
    "NUM_PROXIES",
    "SECURE_PROXY_SSL_HEADER",
)


def bare_env(**values: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in SECRETS}
    env.pop("DJANGO_ALLOW_ASYNC_UNSAFE", None)
    return {**env, **values}


def run(argv: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *argv], cwd=ROOT, env=env, capture_output=True, text=True, timeout=120
    )


def production_values() -> dict[str, str]:
    return {
        "SECRET_KEY": "k" * 20 + uuid.uuid4().hex,
        "MQTT_URL": "mqtt://ground:a-real-password@127.0.0.1:1883",
        "REDIS_URL": "redis://:a-redis-password@127.0.0.1:6379/0",
        "DATABASE_URL": "postgresql://skyhive:a-db-password@127.0.0.1:5432/skyhive",
    }


def test_manage_py_without_settings_or_secrets_refuses_in_one_line():
    out = run(["manage.py", "check"], bare_env())
    assert out.returncode != 0
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith("config.settings.production: production settings need SECRET_KEY")
    assert "MQTT_URL" in last and "REDIS_URL" in last and "DATABASE_URL" in last
    assert "Traceback" not in out.stderr


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("MQTT_URL", "mqtt://ground:ground@127.0.0.1:1883"),
        ("MQTT_URL", "mqtt://127.0.0.1:1883"),
        ("REDIS_URL", "redis://127.0.0.1:6379/0"),
        ("DATABASE_URL", "postgresql://skyhive:skyhive@db.internal:5432/skyhive"),
        ("DATABASE_URL", None),
    ],
)
def test_a_fallback_or_passwordless_service_url_is_refused(name, value):
    values = {**production_values(), name: value}
    out = run(["manage.py", "check"], bare_env(**{k: v for k, v in values.items() if v}))
    assert out.returncode != 0
    assert "production settings need " + name in out.stderr
    assert "SECRET_KEY" not in out.stderr


def test_with_the_secrets_set_production_loads_with_debug_off():
    env = bare_env(**production_values())
    assert run(["manage.py", "check"], env).returncode == 0
    code = "import config.asgi; from django.conf import settings; print(settings.DEBUG)"
    out = run(["-c", code], env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
    assert run(["-c", code], {**env, "DEBUG": "true"}).stdout.strip() == "True"


def test_development_settings_keep_debug_on():
    code = "import django; django.setup(); from django.conf import settings; print(settings.DEBUG)"
    out = run(["-c", code], bare_env(DJANGO_SETTINGS_MODULE="config.settings.local"))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"


# Whether a request that claims https through X-Forwarded-Proto is taken as secure.
CLAIMS_HTTPS = (
    "import django; django.setup(); from django.test import RequestFactory; "
    "request = RequestFactory().get('/', HTTP_X_FORWARDED_PROTO='https'); "
    "print(request.is_secure())"
)


def test_a_forwarded_proto_header_is_not_believed_without_a_proxy():
    env = bare_env(**production_values(), DJANGO_SETTINGS_MODULE="config.settings.production")
    out = run(["-c", CLAIMS_HTTPS], env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize(
    "proxy", [{"NUM_PROXIES": "1"}, {"SECURE_PROXY_SSL_HEADER": "X-Forwarded-Proto: https"}]
)
def test_a_site_behind_a_proxy_it_names_believes_the_proxy(proxy):
    env = bare_env(
        **production_values(), **proxy, DJANGO_SETTINGS_MODULE="config.settings.production"
    )
    out = run(["-c", CLAIMS_HTTPS], env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"
