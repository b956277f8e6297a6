"""Background telemetry: a thread polls the FC and always holds the latest snapshot.

Controllers want the newest state, not a queue of old ones, so the poller keeps exactly one
snapshot and a sequence number.  At ``rate_hz=None`` it polls as fast as the FC answers
(optionally with several requests pipelined).  It releases the client's lock between short batches
so that other users of the same client (RC over MSP, a CLI command) get their turn.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from bfsitl.errors import BfsitlError, LinkClosedError, MspTimeoutError
from bfsitl.fc.msp_client import MspClient, MspRequest, Telemetry

#: Requests per pipelined batch before the client's lock is released.
_BATCH_REQUESTS = 20


@dataclass(frozen=True, slots=True)
class PollerStats:
    updates: int
    #: Requests that got no (intact) reply; the next poll simply carries on.
    missed: int
    #: Replies that could not be decoded, and other failures.
    errors: int
    elapsed_s: float
    last_error: str | None

    @property
    def rate_hz(self) -> float:
        return self.updates / self.elapsed_s if self.elapsed_s > 0 else 0.0


class TelemetryPoller:
    """Polls :meth:`MspClient.telemetry` on a thread; read :meth:`latest` any time."""

    def __init__(self, client: MspClient, rate_hz: float | None = 50.0, depth: int = 1) -> None:
        """``depth``: requests in flight at ``rate_hz=None``.  1 gives the freshest snapshots
        and, thanks to the client's wake byte, as many per second as the FC serves at its
        default 100 Hz serial rate; 3 adds about 10 % at 1000 Hz (benchmarks/telemetry.py)."""
        if rate_hz is not None and rate_hz <= 0:
            raise ValueError("rate_hz must be positive, or None for as fast as possible")
        self.client = client
        self.rate_hz = rate_hz
        self.depth = depth
        self._latest: Telemetry | None = None
        self._sequence = 0
        self._errors = 0
        self._missed = 0
        self._last_error: str | None = None
        self._changed = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started_at_s = 0.0
        self._stopped_at_s: float | None = None
        self.fatal_error: BaseException | None = None
        self._finished = False  # the thread has ended: no snapshot can come any more

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> TelemetryPoller:
        if self._thread is not None:
            raise RuntimeError("poller already started")
        self.client.box_ids()  # fetched once here, so snapshots can name flight modes
        self._started_at_s = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="bfsitl-telemetry", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._stopped_at_s is None:
            self._stopped_at_s = time.monotonic()
        with self._changed:
            self._changed.notify_all()

    def __enter__(self) -> TelemetryPoller:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    # -- reading ---------------------------------------------------------------------------
    def latest(self) -> Telemetry | None:
        return self._latest

    @property
    def sequence(self) -> int:
        """How many snapshots have arrived so far."""
        return self._sequence

    def wait_next(self, after_sequence: int, timeout_s: float = 1.0) -> Telemetry | None:
        """Block until a snapshot newer than ``after_sequence`` arrives (or timeout)."""
        with self._changed:
            self._changed.wait_for(
                lambda: self._sequence > after_sequence or self._stop.is_set() or self._finished,
                timeout_s,
            )
            return self._latest if self._sequence > after_sequence else None

    def stats(self) -> PollerStats:
        end_s = self._stopped_at_s or time.monotonic()
        return PollerStats(
            self._sequence, self._missed, self._errors, end_s - self._started_at_s, self._last_error
        )

    # -- the thread ------------------------------------------------------------------------
    def _publish(self, _request: MspRequest, payload: bytes) -> None:
        try:
            snapshot = self.client.decode_telemetry(payload)
        except BfsitlError as exc:
            self._errors += 1
            self._last_error = str(exc)
            return
        with self._changed:
            self._latest = snapshot
            self._sequence += 1
            self._changed.notify_all()

    def _requests(self, count: int) -> Iterator[MspRequest]:
        request = self.client.telemetry_request()
        for _ in range(count):
            if self._stop.is_set():
                return
            yield request

    def _run(self) -> None:
        period_s = None if self.rate_hz is None else 1.0 / self.rate_hz
        next_due_s = time.monotonic()
        try:
            while not self._stop.is_set():
                if period_s is None:
                    results = self.client.pipeline(
                        self._requests(_BATCH_REQUESTS),
                        depth=self.depth,
                        retries=0,
                        on_reply=self._publish,
                    )
                else:
                    results = self.client.pipeline(
                        self._requests(1), depth=1, retries=0, on_reply=self._publish
                    )
                    next_due_s += period_s
                    now_s = time.monotonic()
                    if next_due_s < now_s:  # fell behind: do not try to catch up in a burst
                        next_due_s = now_s
                    self._stop.wait(next_due_s - now_s)
                for result in results:
                    if isinstance(result, MspTimeoutError):
                        self._missed += 1  # stale telemetry is not worth a retry
                        self._last_error = str(result)
                    elif isinstance(result, Exception):
                        self._errors += 1
                        self._last_error = str(result)
        except LinkClosedError as exc:
            self.fatal_error = exc
            self._last_error = str(exc)
        except BaseException as exc:  # noqa: BLE001 - surfaced through fatal_error
            self.fatal_error = exc
            self._last_error = repr(exc)
        finally:
            self._stopped_at_s = time.monotonic()
            with self._changed:
                self._finished = True
                self._changed.notify_all()
