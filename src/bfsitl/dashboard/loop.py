"""The I/O half of ``bfsitl top``: poll the FC, build a frame, show it, wait for a key.

One thread does everything, in this order, once per period: a synchronous MSP round trip
(MSP_MULTIPLE_MSP, the same request as :meth:`MspClient.telemetry`), the view model, the
frame, then waiting for a key until the period is over.  Polling in the loop instead of on a
background thread makes the round trip a plain measurement, keeps Ctrl-C in the main thread,
and costs nothing at a few Hz: a 4.6.0 SITL answers in about 10 ms (one serial tick).

A failed poll (timeout, error reply) is counted and shown, and the last good values stay on
screen marked stale; only a closed link (the SITL exited) ends the loop, by raising.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from bfsitl.dashboard.keys import KeySource, is_quit
from bfsitl.dashboard.link_stats import LinkMeter, LinkStats
from bfsitl.dashboard.view_model import DEFAULT_STALE_AFTER_S, DashboardView, build_view
from bfsitl.errors import BfsitlError, LinkClosedError
from bfsitl.fc.msp_client import MspClient, Telemetry

#: Frames per second when --rate is not given.
DEFAULT_RATE_HZ = 8.0

FrameSink = Callable[[DashboardView], None]


@dataclass(frozen=True, slots=True)
class DashboardResult:
    """How a dashboard run ended."""

    frames: int
    link: LinkStats
    #: "key" (q), "interrupt" (Ctrl-C) or "frames" (max_frames reached).
    ended_by: str


class DashboardPoller:
    """One telemetry round trip per :meth:`poll`, timed and counted in a :class:`LinkMeter`."""

    def __init__(
        self,
        client: MspClient,
        meter: LinkMeter,
        clock: Callable[[], float] = time.monotonic,
        retries: int = 0,
    ) -> None:
        """``retries``: re-sends of a poll that got no intact reply.  0 for a live view (the
        next frame is a fresher retry); more when a single frame must count (``--once``)."""
        self.client = client
        self.meter = meter
        self.clock = clock
        self.retries = retries
        self._have_box_ids = False

    def poll(self) -> Telemetry | None:
        """The newest snapshot, or None when this poll failed (the failure is recorded)."""
        try:
            if not self._have_box_ids:
                # Needed once to name flight modes; retried on the next poll if it fails.
                self.client.box_ids()
                self._have_box_ids = True
            request = self.client.telemetry_request()
            sent_at_s = self.clock()
            payload = self.client.request(request.command, request.payload, retries=self.retries)
            snapshot = self.client.decode_telemetry(payload)
        except LinkClosedError:
            raise
        except BfsitlError as exc:
            self.meter.record_error(str(exc), self.clock())
            return None
        now_s = self.clock()
        self.meter.record_update(now_s - sent_at_s, now_s)
        return snapshot


def run_dashboard(
    client: MspClient,
    *,
    show: FrameSink,
    keys: KeySource,
    target: str,
    rate_hz: float = DEFAULT_RATE_HZ,
    max_frames: int | None = None,
    stale_after_s: float = DEFAULT_STALE_AFTER_S,
    retries: int = 0,
    clock: Callable[[], float] = time.monotonic,
) -> DashboardResult:
    """Show frames at ``rate_hz`` until q, Ctrl-C or ``max_frames``.

    Ctrl-C is a normal way to quit here, so KeyboardInterrupt ends the loop instead of
    propagating; the caller's cleanup (stopping a SITL it started) runs as usual.
    """
    if rate_hz <= 0:
        raise ValueError("rate_hz must be positive")
    period_s = 1.0 / rate_hz
    meter = LinkMeter(started_at_s=clock())
    poller = DashboardPoller(client, meter, clock, retries)
    latest: Telemetry | None = None
    frames = 0
    try:
        while True:
            frame_started_s = clock()
            latest = poller.poll() or latest
            show(
                build_view(
                    latest,
                    meter.stats(clock()),
                    target=target,
                    rate_hz=rate_hz,
                    stale_after_s=stale_after_s,
                )
            )
            frames += 1
            if max_frames is not None and frames >= max_frames:
                return DashboardResult(frames, meter.stats(clock()), "frames")
            if _wait_for_quit(keys, frame_started_s + period_s, clock):
                return DashboardResult(frames, meter.stats(clock()), "key")
    except KeyboardInterrupt:
        return DashboardResult(frames, meter.stats(clock()), "interrupt")


def _wait_for_quit(keys: KeySource, deadline_s: float, clock: Callable[[], float]) -> bool:
    """Wait until ``deadline_s``; True as soon as a quit key is pressed.  Other keys are
    ignored without cutting the wait short, so holding a key does not speed up polling."""
    while True:
        remaining_s = deadline_s - clock()
        if remaining_s <= 0:
            return False
        pressed = keys.wait_key(remaining_s)
        if pressed is None:
            return False
        if is_quit(pressed):
            return True
