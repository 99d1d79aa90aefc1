"""Build the transport a radio spec names (`--radio sim` or `--radio xbee:PORT[@BAUD]`)."""

from __future__ import annotations

from rf_gateway.sim_transport import SimRadioLike, SimTransport
from rf_gateway.transport import RadioSpec, SimRadioSpec, Transport, parse_radio_spec
from rf_gateway.xbee_transport import XBeeTransport, XBeeTransportConfig


def make_transport(
    spec: RadioSpec | str,
    *,
    sim_radio: SimRadioLike | None = None,
    pin: str = "D4",
    xbee_config: XBeeTransportConfig | None = None,
) -> Transport:
    """The transport for `spec` (a parsed spec or its text).

    Args:
        spec: "sim", "xbee:/dev/ttyUSB0", "xbee:/dev/ttyUSB0@115200" or a parsed spec.
        sim_radio: the virtual site's radio, required for "sim".
        pin: the landmarks' LED pin for XBee ("D4" by default).
        xbee_config: XBee timeouts and backoff.

    Raises:
        ValueError: a bad spec, or "sim" without `sim_radio`.
    """
    parsed = parse_radio_spec(spec) if isinstance(spec, str) else spec
    if isinstance(parsed, SimRadioSpec):
        if sim_radio is None:
            raise ValueError("radio spec 'sim' needs the simulated site's radio (sim_radio)")
        return SimTransport(sim_radio)
    return XBeeTransport(parsed.port, parsed.baud, pin=pin, config=xbee_config)
