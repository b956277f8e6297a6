"""What bfsitl's asyncio WebSocket servers share: serving from a thread, and a clear error
when their port is taken."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import threading
from collections.abc import Awaitable, Callable, Coroutine, Iterator
from typing import Any

from bfsitl.bridges import describe_listener
from bfsitl.errors import BridgeError, ListenAddressInUseError

#: ``serve(started)``: a coroutine that listens, calls ``started(url)``, and serves until told.
Serve = Callable[[Callable[[str], None]], Coroutine[Any, Any, None]]


def listen_error(host: str, port: int, option: str, exc: OSError) -> BridgeError:
    """The error for a server that could not listen: a taken port names its holder and the
    option that moves it."""
    if exc.errno == errno.EADDRINUSE:
        return ListenAddressInUseError(
            f"cannot listen on {host}:{port}: {describe_listener(port)}. Stop it, or pick "
            f"another port with {option}."
        )
    return BridgeError(f"cannot listen on {host}:{port}: {exc}")


@contextlib.contextmanager
def serving_in_thread(
    serve: Serve, stop: Callable[[], None], *, name: str, start_timeout_s: float = 10.0
) -> Iterator[str]:
    """Run ``serve`` on its own event loop in a daemon thread while the block runs; yields
    the URL it listens on.  A failure to start (a taken port) is raised here, in the caller's
    thread; on the way out ``stop()`` is called and the thread joined."""
    listening = threading.Event()
    urls: list[str] = []
    failure: list[BaseException] = []

    def started(url: str) -> None:
        urls.append(url)
        listening.set()

    def run() -> None:
        try:
            asyncio.run(serve(started))
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            failure.append(exc)
            listening.set()

    thread = threading.Thread(target=run, name=name, daemon=True)
    thread.start()
    listening.wait(start_timeout_s)
    if failure:
        thread.join()
        raise failure[0]
    if not urls:
        raise BridgeError(f"the WebSocket server did not start within {start_timeout_s} s")
    try:
        yield urls[0]
    finally:
        stop()
        thread.join(timeout=15.0)
    if failure:  # it failed while the block ran (reached only if the block did not raise)
        raise failure[0]


class StoppableServer:
    """The life of each of bfsitl's WebSocket servers: listen (a taken port is a clear
    error), say where, serve until :meth:`stop` from any thread, or serve in a thread of its
    own while a block runs (:meth:`running`).  A subclass sets ``host``, ``port``,
    ``port_option`` and ``thread_name``, and its ``serve`` opens its server through
    :meth:`_serve_until_stopped`."""

    host: str
    port: int
    #: The command-line option that moves the port, named when the port is taken.
    port_option: str
    thread_name: str = "bfsitl-server"

    def __init__(self) -> None:
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None

    @property
    def url(self) -> str:
        """What a client connects to (for the relay: what to type into the Configurator's
        manual connection field)."""
        return f"ws://{self.host}:{self.port}"

    async def serve(self, started: Callable[[str], None] | None = None) -> None:
        raise NotImplementedError

    async def _serve_until_stopped(
        self, open_server: Callable[[], Awaitable[Any]], started: Callable[[str], None] | None
    ) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        try:
            server = await open_server()
        except OSError as exc:
            raise listen_error(self.host, self.port, self.port_option, exc) from exc
        async with server:
            self.port = server.sockets[0].getsockname()[1]  # the one picked for port 0
            if started is not None:
                started(self.url)
            await self._stop.wait()

    def stop(self) -> None:
        """Ask :meth:`serve` to finish; callable from any thread."""
        if self._loop is not None and self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)

    def running(self, start_timeout_s: float = 10.0) -> contextlib.AbstractContextManager[str]:
        """Serve from a background thread while the block runs; yields :attr:`url`."""
        return serving_in_thread(
            self.serve, self.stop, name=self.thread_name, start_timeout_s=start_timeout_s
        )
