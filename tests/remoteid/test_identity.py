"""Identity numbers against their published rules: ANSI/CTA-2063-A serial numbers and
EN 4709-002 operator registration numbers (the standard's own example,
FIN87astrdge12k8-xyz), plus FAA registration numbers."""

from __future__ import annotations

import pytest

from fleet.identity import IdentityError, luhn_mod36, parse_operator_id, parse_serial_number

# The serial number InterUSS's ASTM F3411 test data uses, then the shortest and the
# longest a length character allows.
VALID_SERIALS = ["MFR1C123456789ABC", "1581F5FKD229400ABC12", "ABCD1Z", "0000F123456789ABCDEF"]


@pytest.mark.parametrize("serial", VALID_SERIALS)
def test_valid_serial_numbers_are_kept(serial):
    assert parse_serial_number(serial) == serial


def test_a_serial_number_is_upper_cased_and_trimmed():
    assert parse_serial_number("  mfr1c123456789abc ") == "MFR1C123456789ABC"


def test_an_empty_serial_number_clears_it():
    assert parse_serial_number("") == ""


@pytest.mark.parametrize(
    ("serial", "why"),
    [
        ("MFR1C123456789AB", "says 12 characters follow, but 11 do"),  # one short
        ("MFR1C123456789ABCD", "says 12 characters follow, but 13 do"),  # one long
        ("MFO1C123456789ABC", "not an ANSI/CTA-2063-A"),  # O in the manufacturer code
        ("MFR1C12345678IABC", "not an ANSI/CTA-2063-A"),  # I in the serial
        ("MFR10123456789ABC", "not an ANSI/CTA-2063-A"),  # length character 0
        ("MFR1G123456789ABC", "not an ANSI/CTA-2063-A"),  # length character beyond F
        ("MFR", "not an ANSI/CTA-2063-A"),
        ("MFR1C12345-789ABC", "not an ANSI/CTA-2063-A"),
    ],
)
def test_malformed_serial_numbers_are_refused(serial, why):
    with pytest.raises(IdentityError) as raised:
        parse_serial_number(serial)
    assert raised.value.field == "serial_number"
    assert why in raised.value.message


def test_the_standard_example_checks_with_luhn_mod_36():
    # EN 4709-002's example: FIN, base 87astrdge12k, checksum 8, secret xyz.
    assert luhn_mod36("87astrdge12k" + "xyz") == "8"


@pytest.mark.parametrize(
    "given", ["FIN87astrdge12k8-xyz", "FIN87astrdge12k8xyz", "fin87ASTRDGE12K8-XYZ"]
)
def test_the_eu_example_is_accepted_and_kept_without_its_secret(given):
    assert parse_operator_id(given) == "FIN87astrdge12k8"


@pytest.mark.parametrize(
    "wrong",
    [
        "FIN87astrdge12k9-xyz",  # checksum changed
        "FIN87astrdge12k8-xyy",  # a secret character mistyped
        "FIN78astrdge12k8-xyz",  # two base characters swapped
        "FIN87astrdge12k8-xzy",  # two secret characters swapped
    ],
)
def test_a_wrong_checksum_is_refused(wrong):
    with pytest.raises(IdentityError) as raised:
        parse_operator_id(wrong)
    assert raised.value.field == "operator_id"
    assert "checksum" in raised.value.message


def test_a_number_for_another_country_gets_its_own_checksum():
    base, secret = "0a1b2c3d4e5f", "q7r"
    number = f"DEU{base}{luhn_mod36(base + secret)}-{secret}"
    assert parse_operator_id(number) == number[:16]


def test_the_public_part_alone_cannot_be_checked():
    with pytest.raises(IdentityError, match="3 secret characters"):
        parse_operator_id("FIN87astrdge12k8")


def test_a_state_outside_easa_is_refused():
    with pytest.raises(IdentityError, match="USA is not an EASA state"):
        parse_operator_id("USA87astrdge12k8-xyz")


def test_faa_registration_numbers():
    assert parse_operator_id("FA3ABCDE12") == "FA3ABCDE12"
    assert parse_operator_id("fa3abcde12") == "FA3ABCDE12"
    with pytest.raises(IdentityError):
        parse_operator_id("FA3ABCDE1")


@pytest.mark.parametrize("value", [None, 5, ["FIN87astrdge12k8-xyz"], "x" * 65])
def test_non_text_and_overlong_input_is_refused(value):
    with pytest.raises(IdentityError) as raised:
        parse_operator_id(value)
    assert raised.value.field == "operator_id"
