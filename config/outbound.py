"""Where the server may connect on a user's behalf, and the one connection that does it.

Used for alert webhooks (alerts/delivery.py, checked on save in accounts/organisation.py).
A webhook URL is typed by an organisation admin, so the server must not become their
way into what only the server can reach: its own loopback (Redis, PostgreSQL, the web
server), the cloud's link-local metadata address, the site's private network. The rule:
every address the URL's host resolves to must be a public unicast address (IPv4 and
IPv6, an IPv4-mapped IPv6 address judged as the IPv4 it carries). It is checked when
the recipients are saved and again at each delivery, and the delivery connects to the
very address it checked (no second DNS lookup a rebinding name could answer
differently), with the Host header and TLS server name of the URL. Redirects are never
followed: a 3xx is a failed attempt.

`ALERT_WEBHOOK_ALLOW_PRIVATE` lets a site whose receiver is on its own network reach
loopback and private addresses (RFC 1918, RFC 4193, RFC 6598); link-local, multicast,
unspecified and reserved addresses stay refused.
"""

from __future__ import annotations

import http.client
import ipaddress
import re
import socket
import ssl
from dataclasses import dataclass
from urllib.parse import urlsplit

from django.conf import settings

Address = ipaddress.IPv4Address | ipaddress.IPv6Address

# Shown to members below admin in place of a webhook URL (its path and query often hold
# the receiver's secret).
HIDDEN = "(webhook URL, shown to admins)"
_URL = re.compile(r"https?://[^\s\"'<>,]+")


class Refused(Exception):
    """The destination is not one alerts may be sent to; the message says why."""


class Unresolved(Refused):
    """The host has no address (now): nothing can be sent to it."""


@dataclass(frozen=True)
class Destination:
    """A webhook URL with the addresses its host resolved to, once."""

    scheme: str
    host: str
    port: int
    target: str  # path and query, as sent in the request line
    addresses: tuple[str, ...]  # every one checked, tried in turn


def _plain(raw: str) -> Address:
    address = ipaddress.ip_address(raw.split("%", 1)[0])
    if isinstance(address, ipaddress.IPv6Address) and address.ipv4_mapped:
        return address.ipv4_mapped
    return address


def refusal(address: Address) -> str | None:
    """Why alerts may not go to this address, or None when they may."""
    if address.is_multicast or address.is_unspecified or address.is_link_local:
        return "a multicast, unspecified or link-local address"
    if address.is_global:
        return None
    private = address.is_private or address in ipaddress.ip_network("100.64.0.0/10")
    if settings.ALERT_WEBHOOK_ALLOW_PRIVATE and (address.is_loopback or private):
        if not address.is_reserved:
            return None
    return "a loopback, private or reserved address"


def resolve(url: str) -> Destination:
    """The URL's host resolved once; Refused unless every address it has is allowed."""
    parts = urlsplit(url)
    if parts.scheme not in ("http", "https") or not parts.hostname:
        raise Refused("a webhook is an http(s) URL with a host")
    try:
        port = parts.port or (443 if parts.scheme == "https" else 80)
        found = socket.getaddrinfo(parts.hostname, port, type=socket.SOCK_STREAM)
    except (ValueError, OSError):
        raise Unresolved(f"{parts.hostname} does not resolve") from None
    addresses = [_plain(str(info[4][0])) for info in found]
    for address in addresses:
        reason = refusal(address)
        if reason:
            raise Refused(f"{parts.hostname} resolves to {address}, {reason}")
    target = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
    checked = tuple(dict.fromkeys(str(address) for address in addresses))
    return Destination(parts.scheme, parts.hostname, port, target, checked)


def check(url: str) -> None:
    """Refused when the URL leads where alerts may not go. A name that does not resolve
    yet is let through: each delivery checks again before it connects."""
    try:
        resolve(url)
    except Unresolved:
        return


def _connect(destination: Destination, timeout: float) -> socket.socket:
    """A socket to the first checked address that answers; no name is looked up here."""
    failure: OSError = OSError(f"no address for {destination.host}")
    for address in destination.addresses:
        try:
            return socket.create_connection((address, destination.port), timeout)
        except OSError as exc:
            failure = exc
    raise failure


class _Pinned(http.client.HTTPConnection):
    """Connects to the checked addresses, whatever the host name resolves to now; the
    Host header still names the URL's host."""

    def __init__(self, destination: Destination, timeout: float) -> None:
        super().__init__(destination.host, destination.port, timeout=timeout)
        self.destination = destination

    def connect(self) -> None:
        self.sock = _connect(self.destination, self.timeout)


class _PinnedTLS(http.client.HTTPSConnection):
    """The same over TLS, the certificate checked against the URL's host (SNI)."""

    def __init__(self, destination: Destination, timeout: float) -> None:
        super().__init__(destination.host, destination.port, timeout=timeout)
        self.destination = destination
        self.tls = ssl.create_default_context()

    def connect(self) -> None:
        raw = _connect(self.destination, self.timeout)
        self.sock = self.tls.wrap_socket(raw, server_hostname=self.host)


def post(url: str, body: bytes, headers: dict[str, str], *, timeout: float) -> int:
    """POST `body` to the URL's checked address; the answer's status (never followed)."""
    destination = resolve(url)
    kind = _PinnedTLS if destination.scheme == "https" else _Pinned
    connection = kind(destination, timeout)
    try:
        connection.request("POST", destination.target, body=body, headers=headers)
        return connection.getresponse().status
    finally:
        connection.close()


def hide_urls(text: str) -> str:
    """The text with every http(s) URL replaced, for members who may not see them."""
    return _URL.sub(HIDDEN, text)
