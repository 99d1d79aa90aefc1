from __future__ import annotations

import pytest

from rf_gateway.transport import (
    SimRadioSpec,
    XBeeRadioSpec,
    normalize_address,
    parse_radio_spec,
)


@pytest.mark.parametrize(
    "text",
    ["0013A20041B2C3D4", "0013a20041b2c3d4", "0x0013A20041B2C3D4", "00:13:A2:00:41:B2:C3:D4"],
)
def test_addresses_normalise_to_16_uppercase_hex_digits(text: str) -> None:
    assert normalize_address(text) == "0013A20041B2C3D4"


@pytest.mark.parametrize("text", ["0013A20041B2C3", "0013A20041B2C3D4FF", "0013A20041B2C3DG", ""])
def test_bad_addresses_are_named(text: str) -> None:
    with pytest.raises(ValueError, match="landmark 5 radio"):
        normalize_address(text, source="landmark 5 radio")


def test_radio_specs_parse() -> None:
    assert parse_radio_spec("sim") == SimRadioSpec()
    assert parse_radio_spec("xbee:/dev/ttyUSB0") == XBeeRadioSpec("/dev/ttyUSB0", 9600)
    assert parse_radio_spec("xbee:/dev/ttyUSB0@115200") == XBeeRadioSpec("/dev/ttyUSB0", 115200)


@pytest.mark.parametrize("spec", ["zigbee:/dev/x", "xbee:", "xbee:/dev/x@fast", "xbee:/dev/x@0"])
def test_bad_radio_specs_are_named(spec: str) -> None:
    with pytest.raises(ValueError, match="radio spec"):
        parse_radio_spec(spec)
