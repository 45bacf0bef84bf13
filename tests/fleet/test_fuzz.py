"""Fuzz `/control` and the drone API from their OpenAPI schema: no answer is a 5xx.

Schemathesis 3.39 cannot generate here: its hypothesis-jsonschema 0.23.1 calls a
Hypothesis internal (`many.more`) that Hypothesis 6.170 removed, for every object schema.
So this walks the same drf-spectacular schema itself and lets Hypothesis generate each
operation's path, query and body: values of the declared type, anything else, and
unknown extra fields, against the real ASGI server.
"""

from __future__ import annotations

import json
import math

import pytest
import requests
from django.db import connection
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

pytestmark = [pytest.mark.django_db(transaction=True)]

EXAMPLES_PER_OPERATION = 25
SELECTED = ("/control", "/api/v1/drones/")

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20),
    lambda inner: (
        st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)


def _typed(schema: dict) -> st.SearchStrategy:
    """A value of the declared type, or (sometimes) anything at all."""
    if "enum" in schema:
        declared = st.sampled_from(schema["enum"])
    elif schema.get("type") in ("number", "integer"):
        declared = st.floats(allow_nan=False, allow_infinity=False) | st.integers()
    elif schema.get("type") == "boolean":
        declared = st.booleans()
    elif schema.get("type") == "object":
        declared = st.dictionaries(
            st.sampled_from(["value", "lat", "lon", "force", "altitude", "mission"]),
            json_values,
            max_size=3,
        )
    else:
        declared = st.text(max_size=30)
    return declared | json_values


def _as_text(value: object) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value if isinstance(value, str) else json.dumps(value)


def _body_schema(operation: dict, components: dict) -> tuple[str | None, dict]:
    content = operation.get("requestBody", {}).get("content", {})
    for media_type, body in content.items():
        schema = body.get("schema", {})
        if "$ref" in schema:
            schema = components[schema["$ref"].rsplit("/", 1)[1]]
        return media_type, schema
    return None, {}


def request_strategy(path: str, method: str, operation: dict, components: dict):  # type: ignore[no-untyped-def]
    query = {
        p["name"]: _typed(p.get("schema", {}))
        for p in operation.get("parameters", [])
        if p["in"] == "query"
    }
    media_type, body = _body_schema(operation, components)
    fields = {name: _typed(schema) for name, schema in body.get("properties", {}).items()}
    drone_ids = st.sampled_from(["ACME_1", "GLOBEX_1", "NOPE"]) | st.text(max_size=70)
    return st.fixed_dictionaries(
        {
            "drone_id": drone_ids,
            "query": st.fixed_dictionaries({}, optional=query),
            "body": st.fixed_dictionaries({}, optional=fields)
            | st.dictionaries(st.text(max_size=10), json_values, max_size=4),
            "media_type": st.just(media_type),
        }
    )


@pytest.fixture
def fuzz_server(tmp_path):  # type: ignore[no-untyped-def]
    from tests.support.live import LiveServer

    server = LiveServer(
        connection.settings_dict["NAME"],
        # Provisioning during the fuzz writes here, not to the suite's broker.
        extra_env={"MOSQUITTO_DIR": str(tmp_path / "mosquitto"), "COMMAND_TIMEOUT_S": "0.5"},
    )
    yield server
    server.stop()


def test_control_and_the_drone_api_never_answer_5xx(world_tx, fuzz_server):
    from drf_spectacular.generators import SchemaGenerator
    from rest_framework.authtoken.models import Token

    token = Token.objects.create(user=world_tx.owner).key
    spec = SchemaGenerator().get_schema(request=None, public=True)
    components = spec["components"]["schemas"]
    operations = [
        (path, method, op)
        for path, item in spec["paths"].items()
        if path.startswith(SELECTED)
        for method, op in item.items()
    ]
    assert len(operations) >= 8
    session = requests.Session()
    session.headers["Authorization"] = f"Token {token}"
    failures: list[str] = []

    for path, method, operation in operations:
        fuzz_operation(fuzz_server.url, session, path, method, operation, components, failures)
    assert failures == []


def fuzz_operation(base_url, session, path, method, operation, components, failures):  # type: ignore[no-untyped-def]
    @settings(
        max_examples=EXAMPLES_PER_OPERATION,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )
    @given(case=request_strategy(path, method, operation, components))
    def call(case: dict) -> None:
        url = base_url + path.replace("{drone_id}", requests.utils.quote(case["drone_id"], safe=""))
        kwargs: dict = {"params": {k: _as_text(v) for k, v in case["query"].items()}, "timeout": 10}
        if case["media_type"] == "application/json":
            kwargs["data"] = json.dumps(case["body"])
            kwargs["headers"] = {"Content-Type": "application/json"}
        elif case["media_type"]:
            kwargs["data"] = {k: _as_text(v) for k, v in case["body"].items()}
        response = session.request(method.upper(), url, **kwargs)
        if response.status_code >= 500:
            failures.append(f"{method.upper()} {url} {kwargs} → {response.status_code}")

    call()
