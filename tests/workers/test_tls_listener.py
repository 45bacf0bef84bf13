"""The optional TLS listener of Mosquitto (workers/mosquitto.py and scripts/services.sh):
a client that trusts the broker's certificate connects over mqtts:// (the onboard agent's
own link) and publishes and receives; a plain MQTT client gets nowhere on that port."""

from __future__ import annotations

import datetime
import ipaddress
import os
import subprocess
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID

from onboard.mqtt import MqttLink
from runtime.processes import free_port, wait_for
from tests.support.mqtt_check import round_trip
from tests.support.paths import ROOT
from workers.mosquitto import start_broker

SERVICES = str(ROOT / "scripts" / "services.sh")


def self_signed(directory: Path) -> tuple[Path, Path]:
    """A certificate for 127.0.0.1 signed by its own key: (certificate, key) PEM files."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "skyhive test broker")])
    now = datetime.datetime.now(datetime.UTC)
    cert = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(
            x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
            critical=False,
        )
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .sign(key, hashes.SHA256())
    )
    directory.mkdir(parents=True, exist_ok=True)
    cert_path, key_path = directory / "cert.pem", directory / "key.pem"
    cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    key_path.write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    key_path.chmod(0o600)
    return cert_path, key_path


def connects(url: str, timeout: float = 3.0) -> bool:
    link = MqttLink(
        url, client_id=f"probe-{os.getpid()}", subscriptions=[], on_message=lambda t, p: None
    )
    link.start()
    try:
        return link.wait_connected(timeout)
    finally:
        link.stop()


@pytest.fixture
def trusted(tmp_path, monkeypatch) -> tuple[Path, Path]:  # type: ignore[no-untyped-def]
    """A self-signed pair, its certificate trusted by this process's TLS clients (the
    standard SSL_CERT_FILE, which paho's default context reads, as a drone would be given)."""
    pair = self_signed(tmp_path / "pki")
    monkeypatch.setenv("SSL_CERT_FILE", str(pair[0]))
    return pair


def test_a_trusting_client_talks_over_tls_and_a_plain_client_cannot(tmp_path, trusted):
    broker = start_broker(tmp_path / "mq", {"ground": "ground-pw"}, tls=trusted)
    try:
        tls = broker.tls_url_for("ground")
        assert tls.startswith("mqtts://")
        assert round_trip(tls, "DRONE_T/telemetry/out")
        # Over TLS to the plain listener's peer: both ways work, the listeners share users.
        assert round_trip(broker.url_for("ground"), "DRONE_T/command/in", tls)
        assert not connects(f"mqtt://ground:ground-pw@127.0.0.1:{broker.tls_port}")
        assert not connects(f"mqtts://ground:wrong@127.0.0.1:{broker.tls_port}")
    finally:
        broker.stop()


def test_a_client_that_does_not_trust_the_certificate_is_refused(tmp_path):
    pair = self_signed(tmp_path / "pki")
    broker = start_broker(tmp_path / "mq", {"ground": "ground-pw"}, tls=pair)
    try:
        assert not connects(broker.tls_url_for("ground"))
    finally:
        broker.stop()


def test_the_services_script_adds_the_tls_listener_when_asked(tmp_path, trusted):
    plain, drones, tls_port = free_port(), free_port(), free_port()
    env = dict(os.environ, DATA_DIR=str(tmp_path / "data"), TEST_MQTT_PORT=str(plain),
               TEST_MQTT_DRONE_PORT=str(drones), MQTT_TLS_PORT=str(tls_port), MQTT_TLS_CERT=str(trusted[0]),
               MQTT_TLS_KEY=str(trusted[1]))  # fmt: skip
    subprocess.run([SERVICES, "mosquitto-start", "test"], env=env, check=True, timeout=60)
    try:
        password = (tmp_path / "data" / "secrets" / "mqtt_ground_password").read_text()
        assert round_trip(f"mqtts://ground:{password}@127.0.0.1:{tls_port}", "a/b/c")
        assert not connects(f"mqtt://ground:{password}@127.0.0.1:{tls_port}")
    finally:
        subprocess.run([SERVICES, "mosquitto-stop", "test"], env=env, timeout=60)


def test_the_services_script_refuses_a_tls_port_without_its_certificate(tmp_path):
    env = dict(os.environ, DATA_DIR=str(tmp_path / "data"), TEST_MQTT_PORT=str(free_port()),
               MQTT_TLS_PORT=str(free_port()), MQTT_TLS_CERT="", MQTT_TLS_KEY="")  # fmt: skip
    started = subprocess.run([SERVICES, "mosquitto-start", "test"], env=env, capture_output=True,
                             text=True, timeout=60)  # fmt: skip
    assert started.returncode != 0
    assert "MQTT_TLS_CERT" in started.stderr


@pytest.mark.django_db
def test_a_drone_provisioned_for_tls_connects_with_the_url_it_was_given(
    tmp_path, trusted, settings, world
):
    """Provisioning rewrites the (unprivileged) broker's files and hands the drone an
    mqtts:// URL; the drone's own link uses it, and the ground hears it on loopback."""
    from fleet.credentials import provision

    directory = tmp_path / "mq"
    broker = start_broker(directory, {"ground": "ground-pw"}, tls=trusted,
                          extra_config=f"pid_file {directory / 'mosquitto.pid'}\n")  # fmt: skip
    settings.MQTT_BROKER = "mosquitto"
    settings.MOSQUITTO_DIR = str(directory)
    settings.MQTT_URL = broker.url_for("ground")
    settings.MQTT_PUBLIC_HOST, settings.MQTT_PUBLIC_PORT = "127.0.0.1", broker.tls_port
    settings.MQTT_PUBLIC_TLS = True
    try:
        credentials = provision("ACME_TLS", world.org.slug)
        [url] = credentials.urls
        assert url.startswith("mqtts://ACME_TLS:") and url.endswith(f":{broker.tls_port}")
        assert wait_for(
            lambda: round_trip(broker.url_for("ground"), "ACME_TLS/telemetry/out", url), 20
        )
    finally:
        broker.stop()


@pytest.mark.django_db
def test_the_ground_gateway_connects_over_tls(tmp_path, trusted):
    from workers.gateway import Gateway

    broker = start_broker(tmp_path / "mq", {"ground": "ground-pw"}, tls=trusted)
    try:
        gateway = Gateway(broker.tls_url_for("ground"), dispatch={}, client_id="gateway-tls-test")
        gateway.start()
        try:
            assert gateway.wait_connected(10), "the gateway did not connect over mqtts://"
        finally:
            gateway.stop()
    finally:
        broker.stop()
