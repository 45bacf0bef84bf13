"""Whether a message gets through a broker: for tests of broker set-ups (users, TLS)."""

from __future__ import annotations

import threading
import uuid

from onboard.mqtt import MqttLink


def _link(url: str, topics: list[str], on_message) -> MqttLink:  # type: ignore[no-untyped-def]
    link = MqttLink(url, client_id=f"check-{uuid.uuid4().hex[:8]}", subscriptions=topics,
                    on_message=on_message)  # fmt: skip
    link.start()
    return link


def round_trip(subscriber: str, topic: str, publisher: str | None = None) -> bool:
    """`subscriber` subscribes to `topic`, `publisher` (the same by default) publishes on
    it: True once the message came back."""
    got = threading.Event()
    listening = _link(subscriber, [topic], lambda t, p: got.set())
    talking = _link(publisher, [], lambda t, p: None) if publisher else listening
    try:
        if not (listening.wait_connected(10) and talking.wait_connected(10)):
            return False
        # Again until it arrives: the subscription may still be on its way to the broker.
        for _ in range(20):
            talking.publish(topic, b"hello")
            if got.wait(0.5):
                return True
        return False
    finally:
        for link in {id(listening): listening, id(talking): talking}.values():
            link.stop()
