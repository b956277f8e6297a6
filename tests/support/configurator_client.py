"""A client that speaks to a bridge the way the web Betaflight Configurator does.

What it sends comes from ``tests/data/configurator/frames.json`` (read from the app's source,
see the README there): the same WebSocket subprotocol offer (``["binary"]``), an Origin of
the app's, binary frames, the connect sequence one request at a time (each waits for its
reply, as the app's callbacks do), the CLI's ``#`` / lines / ``exit\\r``, and the app's way of
reconnecting: close the previous socket and open the next one at once, without waiting.

Replies are parsed with bfsitl's MSP parser: that is the bridge's peer, not what is tested.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from bfsitl.protocol.msp_frame import MspFrame, MspParser

FRAMES_PATH = Path(__file__).resolve().parents[1] / "data" / "configurator" / "frames.json"
APP_ORIGIN = "https://app.betaflight.com"


def frames() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(FRAMES_PATH.read_text())
    return data


@dataclass
class Reply:
    """One MSP reply as the app receives it."""

    command: int
    payload: bytes
    error: bool


@dataclass
class ConfiguratorLikeClient:
    """One WebSocket to ``url`` with the app's subprotocol offer and Origin."""

    url: str
    origin: str = APP_ORIGIN
    open_timeout_s: float = 10.0
    ws: ClientConnection | None = None
    _stack: contextlib.ExitStack = field(default_factory=contextlib.ExitStack)

    def open(self) -> ConfiguratorLikeClient:
        offered = frames()["websocket"]["subprotocols"]
        self.ws = self._stack.enter_context(
            connect(
                self.url, subprotocols=offered, origin=self.origin, open_timeout=self.open_timeout_s
            )
        )
        return self

    def __enter__(self) -> ConfiguratorLikeClient:
        return self.open()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def close(self) -> None:
        self._stack.close()

    def abandon(self) -> threading.Thread:
        """What the app does to a superseded socket: start closing it and wait for nothing
        (the closing handshake runs on in a thread while the caller opens the next one)."""
        assert self.ws is not None
        closing = threading.Thread(target=self.ws.close, daemon=True)
        closing.start()
        return closing

    @property
    def subprotocol(self) -> str | None:
        return None if self.ws is None else self.ws.subprotocol

    def request(self, frame_hex: str, command: int, timeout_s: float = 3.0) -> Reply:
        """Send one recorded request frame (binary) and wait for its reply."""
        assert self.ws is not None
        self.ws.send(bytes.fromhex(frame_hex))
        parser = MspParser()
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            data = self.ws.recv(timeout=max(0.01, deadline - time.monotonic()))
            assert isinstance(data, bytes), "the bridge sent a text frame; the app reads blobs"
            for event in parser.feed(data):
                if isinstance(event, MspFrame) and event.command == command:
                    return Reply(event.command, event.payload, event.is_error)
        raise AssertionError(f"no reply to command {command} through the bridge")

    def connect_sequence(self) -> dict[str, Reply]:
        """The app's requests on connecting, in its order; the replies by request name."""
        return {
            step["name"]: self.request(step["hex"], step["command"]) for step in frames()["connect"]
        }

    def cli_text(self, data_hex: str, until: bytes, timeout_s: float = 5.0) -> str:
        """Send CLI bytes; the text received until ``until`` shows up."""
        assert self.ws is not None
        self.ws.send(bytes.fromhex(data_hex))
        got = bytearray()
        deadline = time.monotonic() + timeout_s
        while until not in got:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no {until!r} from the CLI; got {bytes(got)!r}")
            data = self.ws.recv(timeout=remaining)
            got += data if isinstance(data, bytes) else data.encode()
        return got.decode(errors="replace")

    def wait_closed(self, timeout_s: float = 10.0) -> int | None:
        """Read until the bridge closes the socket; its close code."""
        assert self.ws is not None
        deadline = time.monotonic() + timeout_s
        try:
            while time.monotonic() < deadline:
                self.ws.recv(timeout=max(0.01, deadline - time.monotonic()))
        except ConnectionClosed:
            return self.ws.close_code
        except TimeoutError:
            pass
        raise AssertionError("the bridge did not close the socket")
