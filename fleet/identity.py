"""Remote ID identity numbers: a drone's serial number and its operator's registration.

- The UAS serial number follows ANSI/CTA-2063-A [CTA 2063-A]: a 4-character manufacturer
  code (digits and upper-case letters but O and I), one length character (1-9, A-F: the
  manufacturer's serial is 1 to 15 characters long), then that serial, of digits and
  upper-case letters but O and I. At most 20 characters: the `uas_id` of an Open Drone ID
  Basic ID message [ASTM F3411].
- An EU operator registration number follows EN 4709-002 [EN 4709-002]: the registering
  state's ISO 3166 alpha-3 code, 12 base characters, one checksum character and 3 secret
  characters that are never broadcast (written `FIN87astrdge12k8-xyz`). The checksum is
  the Luhn mod N algorithm with N = 36 over the 12 base characters followed by the 3
  secret ones, characters valued by their place in `0-9a-z` [Luhn mod N]; QGroundControl
  checks it the same way [QGC RemoteIDManager]. Only the 16 public characters are kept.
- A US (FAA) registration number is `FA` followed by 8 letters or digits [14 CFR 48].

Each parser returns the number as it is stored and broadcast, or raises IdentityError
naming what is wrong.
"""

from __future__ import annotations

import re
from typing import Any

from django.conf import settings

from onboard.protocol import RemoteIdentity

SERIAL_ALPHABET = "0-9A-HJ-NP-Z"  # ANSI/CTA-2063-A: no O, no I
LENGTH_CODES = "123456789ABCDEF"  # length code → 1..15 characters
SERIAL_RE = re.compile(f"^[{SERIAL_ALPHABET}]{{4}}[{LENGTH_CODES}][{SERIAL_ALPHABET}]{{1,15}}$")
LUHN_ALPHABET = "0123456789abcdefghijklmnopqrstuvwxyz"
EU_OPERATOR_RE = re.compile(r"^([A-Z]{3})([0-9a-z]{12})([0-9a-z])-?([0-9a-z]{3})$")
EU_PUBLIC_RE = re.compile(r"^[A-Z]{3}[0-9a-z]{13}$")
FAA_RE = re.compile(r"^FA[0-9A-Z]{8}$")
# The states that register operators under Regulation (EU) 2019/947 and so use
# EN 4709-002 numbers: the EU members and the other EASA states (ISO 3166 alpha-3).
EASA_STATES = frozenset(
    "AUT BEL BGR HRV CYP CZE DNK EST FIN FRA DEU GRC HUN IRL ITA LVA LTU LUX MLT NLD POL "
    "PRT ROU SVK SVN ESP SWE ISL LIE NOR CHE".split()
)
MAX_INPUT = 64  # longer text is refused before any parsing
# What the broadcast declares of the aircraft, by the API's names: the UA type
# (MAV_ODID_UA_TYPE, ASTM F3411's list) and, in the EU, the operation's category and the
# aircraft's class mark (MAV_ODID_CATEGORY_EU, MAV_ODID_CLASS_EU) [EU 2019/945].
UA_TYPES = {
    "none": 0,
    "aeroplane": 1,
    "helicopter_or_multirotor": 2,
    "gyroplane": 3,
    "hybrid_lift": 4,
    "ornithopter": 5,
    "glider": 6,
    "kite": 7,
    "free_balloon": 8,
    "captive_balloon": 9,
    "airship": 10,
    "free_fall_parachute": 11,
    "rocket": 12,
    "tethered_powered_aircraft": 13,
    "ground_obstacle": 14,
    "other": 15,
}
EU_CATEGORIES = {"undeclared": 0, "open": 1, "specific": 2, "certified": 3}
EU_CLASSES = {"undeclared": 0, **{f"C{n}": n + 1 for n in range(7)}}
# Class marks C5 and C6 are for the standard scenarios of the specific category; the
# certified category flies no class-marked aircraft [EU 2019/945, Parts 16 and 17].
SPECIFIC_ONLY_CLASSES = {"C5", "C6"}


class IdentityError(ValueError):
    """A refused identity number; `field` names the API field, `message` says why."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


def required_by_default() -> bool:
    """Whether a new organisation must fly with Remote ID (REMOTE_ID_REQUIRED_DEFAULT)."""
    return bool(getattr(settings, "REMOTE_ID_REQUIRED_DEFAULT", True))


def _text(value: object, field: str) -> str:
    if not isinstance(value, str):
        raise IdentityError(field, "must be a string")
    if len(value) > MAX_INPUT:
        raise IdentityError(field, f"at most {MAX_INPUT} characters")
    return "".join(value.split())


def parse_serial_number(value: object, field: str = "serial_number") -> str:
    """An ANSI/CTA-2063-A serial number (upper-cased), or "" to clear it."""
    text = _text(value, field).upper()
    if not text:
        return ""
    if not SERIAL_RE.match(text):
        raise IdentityError(
            field,
            "not an ANSI/CTA-2063-A serial number: 4 characters of manufacturer code, "
            "1 length character (1-9, A-F), then that many characters; digits and "
            "letters but O and I",
        )
    declared = LENGTH_CODES.index(text[4]) + 1
    if len(text) - 5 != declared:
        raise IdentityError(
            field,
            f"the length character {text[4]!r} says {declared} characters follow, "
            f"but {len(text) - 5} do",
        )
    return text


def luhn_mod36(payload: str) -> str:
    """The Luhn mod 36 check character of `payload` (characters of 0-9a-z): from the
    right, every other value doubled starting with the rightmost, the base-36 digits of
    each product summed; the check character makes the sum a multiple of 36."""
    total = 0
    for position, char in enumerate(reversed(payload)):
        addend = LUHN_ALPHABET.index(char) * (2 if position % 2 == 0 else 1)
        total += addend // 36 + addend % 36
    return LUHN_ALPHABET[(36 - total % 36) % 36]


def parse_operator_id(value: object, field: str = "operator_id") -> str:
    """An EU (EN 4709-002, with its 3 secret characters) or FAA registration number, as
    broadcast: the EU number's 16 public characters, the FAA number as given; "" clears."""
    text = _text(value, field)
    if not text:
        return ""
    if FAA_RE.match(text.upper()):
        return text.upper()
    eu = EU_OPERATOR_RE.match(text[:3].upper() + text[3:].lower())
    if eu is None:
        if EU_PUBLIC_RE.match(text[:3].upper() + text[3:].lower()):
            raise IdentityError(
                field,
                "give the full EU number with its 3 secret characters "
                "(like FIN87astrdge12k8-xyz): the checksum covers them",
            )
        raise IdentityError(
            field,
            "not an operator registration number: EU (EN 4709-002, like "
            "FIN87astrdge12k8-xyz) or FAA (FA and 8 letters or digits)",
        )
    country, base, check, secret = eu.groups()
    if country not in EASA_STATES:
        raise IdentityError(field, f"{country} is not an EASA state's ISO 3166 code")
    expected = luhn_mod36(base + secret)
    if check != expected:
        raise IdentityError(
            field, "wrong checksum: the number or its secret characters are mistyped"
        )
    return f"{country}{base}{check}"


def parse_declared(value: object, field: str, names: dict[str, int]) -> int:
    """One of `names` (the API's words for an Open Drone ID enum) → its number."""
    if not isinstance(value, str) or value not in names:
        raise IdentityError(field, "must be one of " + ", ".join(names))
    return names[value]


def declared_name(number: int, names: dict[str, int]) -> str:
    return next(name for name, n in names.items() if n == number)


def check_eu_declaration(category: int, class_mark: int) -> None:
    """A class mark must fit the category it is flown in; IdentityError names eu_class."""
    category_name = declared_name(category, EU_CATEGORIES)
    class_name = declared_name(class_mark, EU_CLASSES)
    if class_name in SPECIFIC_ONLY_CLASSES and category_name != "specific":
        raise IdentityError("eu_class", f"{class_name} is flown in the specific category only")
    if category_name == "certified" and class_name != "undeclared":
        raise IdentityError("eu_class", "the certified category flies no class-marked aircraft")


def identity_for(drone: Any) -> RemoteIdentity | None:
    """The optional `remote_id` block of a drone's envelope message: its serial number,
    its organisation's operator number and, as the operator's position, the
    organisation's envelope home (the ground station's place); None without a serial."""
    if not drone.serial_number:
        return None
    organisation = drone.organisation
    home = (organisation.envelope or {}).get("home")
    location = (float(home[0]), float(home[1])) if home else None
    return RemoteIdentity(
        serial_number=drone.serial_number,
        operator_id=organisation.operator_id,
        ua_type=drone.ua_type,
        description=(drone.name or drone.drone_id)[:23],
        operator_location=location,
        eu_category=drone.eu_category,
        eu_class=drone.eu_class,
    )
