"""Domain exceptions of the RF gateway (the HTTP layer maps them to status codes)."""

from __future__ import annotations


class RfGatewayError(Exception):
    """Base class of every error the gateway raises on purpose."""


class RadioTimeout(RfGatewayError):  # noqa: N818 (name fixed by the contract)
    """A remote radio did not answer a command within the per-command timeout.

    Attributes:
        address: the remote's 64-bit address (16 uppercase hex digits).
    """

    def __init__(self, address: str, message: str = "") -> None:
        super().__init__(message or f"radio {address} did not answer")
        self.address = address


class RemoteCommandError(RfGatewayError):
    """A remote radio (or the coordinator on its behalf) rejected a command.

    Attributes:
        address: the remote's 64-bit address.
        status: the remote AT command status (1 error, 2 invalid command, 3 invalid
            parameter, 4 transmission failure), or None when unknown.
    """

    def __init__(self, address: str, status: int | None, message: str = "") -> None:
        super().__init__(message or f"radio {address} answered with status {status}")
        self.address = address
        self.status = status

    @property
    def retryable(self) -> bool:
        """True for a transmission failure (status 4 or unknown): a retry may succeed."""
        return self.status is None or self.status == 4


class TransportUnavailable(RfGatewayError):  # noqa: N818 (name fixed by the contract)
    """The transport is not open (serial port gone and being reopened, or closed)."""


class UnknownLandmarkError(KeyError, RfGatewayError):
    """A landmark ID the gateway has no radio address for."""

    def __init__(self, landmark_id: int) -> None:
        super().__init__(f"unknown landmark id {landmark_id}: it has no radio address")
        self.landmark_id = landmark_id

    def __str__(self) -> str:
        return str(self.args[0])


class LandmarkUnreachableError(RfGatewayError):
    """A landmark did not confirm a command after every retry (the server answers 504).

    Attributes:
        landmark_id: the landmark.
        address: its radio address.
        tries: how many times the command was sent.
    """

    def __init__(self, landmark_id: int, address: str, tries: int, cause: str = "") -> None:
        detail = f": {cause}" if cause else ""
        super().__init__(
            f"landmark {landmark_id} (radio {address}) did not answer after {tries} tries{detail}"
        )
        self.landmark_id = landmark_id
        self.address = address
        self.tries = tries
