"""Serial transport for a real flight controller (USB VCP or UART) through pyserial."""

from __future__ import annotations

from typing import Any

from bfsitl.errors import ExtraMissingError, LinkError
from bfsitl.link.base import DEFAULT_TIMEOUT_S, Link

DEFAULT_BAUD = 115200


def _import_pyserial() -> Any:
    try:
        import serial  # type: ignore[import-untyped]
    except ImportError as exc:
        raise ExtraMissingError("serial links need pyserial: pip install 'bfsitl[serial]'") from exc
    return serial


class SerialLink(Link):
    """A serial port (``/dev/ttyACM0``, a pty from ``bfsitl serial-bridge``, ...)."""

    #: Below a real UART's 256-byte receive buffer.
    max_in_flight_bytes = 192

    def __init__(
        self, device: str, baud: int = DEFAULT_BAUD, timeout_s: float = DEFAULT_TIMEOUT_S
    ) -> None:
        super().__init__(f"serial://{device}?baud={baud}", timeout_s)
        serial = _import_pyserial()
        self.device = device
        self.baud = baud
        try:
            # exclusive: a second program on the same port would steal half of the replies.
            self._port = serial.Serial(
                device,
                baudrate=baud,
                timeout=timeout_s,
                write_timeout=timeout_s,
                exclusive=True,
            )
        except (OSError, serial.SerialException) as exc:
            raise LinkError(
                f"{self.uri}: cannot open {device}: {exc}. Check the cable, the device name "
                f"(ls /dev/ttyACM* /dev/ttyUSB*) and that your user may open it (group dialout)."
            ) from exc
        self._serial_exception = serial.SerialException

    def _write_bytes(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except self._serial_exception as exc:
            raise OSError(str(exc)) from exc

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        try:
            self._port.timeout = timeout_s
            first = self._port.read(1)
            if not first:
                return b""
            waiting = min(self._port.in_waiting, max_bytes - 1)
            return first + (self._port.read(waiting) if waiting else b"")
        except self._serial_exception as exc:
            raise OSError(str(exc)) from exc

    def _close(self) -> None:
        self._port.close()
