"""Record a flight to MCAP and serve it live to Foxglove, from the same channels.

The Foxglove SDK writes both: an MCAP writer and a WebSocket server are two sinks of one
``foxglove.Context``, so what the live viewer shows and what the file holds are the same
messages.  Each recorder has its own context (not the SDK's global one), so two flights in one
process never mix.  Why the SDK: it is Foxglove's maintained library, carries the well-known
schemas (FrameTransform, Log) with their protobuf encodings, and writes indexed, compressed
MCAP through the ``mcap`` crate; files read back with the ``mcap`` Python reader.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bfsitl.bridges.origin_policy import OriginPolicy
from bfsitl.errors import BfsitlError, ExtraMissingError

if TYPE_CHECKING:
    from bfsitl.mission.flight_row import FlightRow
    from bfsitl.mission.vehicle import FlightSample
    from bfsitl.records.foxglove.channels import FlightChannels

#: The only subprotocol the SDK's server (0.30) accepts.
FOXGLOVE_SUBPROTOCOLS = ("foxglove.sdk.v1",)
INSTALL_HINT = "pip install 'bfsitl[foxglove]'"


def _import_foxglove() -> Any:
    try:
        import foxglove
    except ImportError as exc:
        raise ExtraMissingError(
            f"--mcap and --foxglove need the Foxglove SDK: {INSTALL_HINT}"
        ) from exc
    return foxglove


class FoxgloveRecorder:
    """A flight's MCAP file (``mcap_path``) and/or live server (``live_port``; 0: any port).

    ``start()`` opens them, :meth:`write` logs a row, :meth:`event` an event, ``close()``
    finishes the file (its summary and index) on every way out.
    """

    def __init__(
        self,
        *,
        mcap_path: Path | None = None,
        live_port: int | None = None,
        allow_origins: Iterable[str] = (),
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        self.mcap_path = mcap_path
        self.live_port = live_port
        self.origins = OriginPolicy.with_extra(allow_origins)
        self._on_event = on_event or (lambda _line: None)
        self.channels: FlightChannels | None = None
        self.live_url: str | None = None
        self.rows_written = 0
        self._writer: Any = None
        self._server: Any = None
        self._context: Any = None
        self._stack = contextlib.ExitStack()

    def start(self) -> FoxgloveRecorder:
        foxglove = _import_foxglove()
        from bfsitl.records.foxglove.channels import FlightChannels

        # Held for the recorder's life: channels of a dropped context are closed.
        context = self._context = foxglove.Context()
        try:
            if self.mcap_path is not None:
                self._open_mcap(foxglove, context, self.mcap_path)
            if self.live_port is not None:
                self._serve_live(foxglove, context, self.live_port)
            self.channels = FlightChannels(context)
        except BaseException:
            self.close()
            raise
        return self

    def _open_mcap(self, foxglove: Any, context: Any, path: Path) -> None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._writer = foxglove.open_mcap(path, allow_overwrite=True, context=context)
        except (OSError, RuntimeError, ValueError) as exc:
            raise BfsitlError(f"cannot write the MCAP file {path}: {exc}") from exc

    def _serve_live(self, foxglove: Any, context: Any, port: int) -> None:
        from bfsitl.bridges.websocket_guard import OriginGuard

        # No capabilities: viewers may subscribe, nothing else (no publishing into the flight).
        self._server = foxglove.start_server(
            host="127.0.0.1", port=0, context=context, name="bfsitl", capabilities=[]
        )
        guard = OriginGuard(
            f"ws://127.0.0.1:{self._server.port}",
            port=port,
            subprotocols=FOXGLOVE_SUBPROTOCOLS,
            origins=self.origins,
            on_event=self._on_event,
            port_option="--foxglove-port",
        )
        self.live_url = self._stack.enter_context(guard.running())

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        if self.channels is None:
            raise BfsitlError("the Foxglove recorder is not started")
        self.channels.log_row(row, sample)
        self.rows_written += 1

    def event(self, time_s: float, text: str) -> None:
        if self.channels is not None:
            self.channels.log_event(time_s, text)

    def close(self) -> None:
        """Finish the MCAP file and stop the server; idempotent."""
        self.channels = None
        writer, self._writer = self._writer, None
        server, self._server = self._server, None
        try:
            if writer is not None:
                writer.close()
        finally:
            self._stack.close()
            if server is not None:
                server.stop()
            self._context = None

    def __enter__(self) -> FoxgloveRecorder:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()
