"""When the lockstep RC link sends a receiver frame: at its own rate, on simulation time.

A real radio link sends frames at a fixed rate (ELRS 250 or 500 Hz, CRSF 150 Hz), each with
the latest sticks, whatever the pilot does between them.  The firmware measures that rate: 4.6.0
and master size their RC smoothing from it and scale feedforward by it, and they call the link
lost when frames stop.  The lockstep bridge therefore puts the RC trailer into the first fdm
datagram at or after each frame time, not into every datagram (1 kHz).

The compiled loop (``kernel/lockstep_loop.c``, ``rc_frame_due``) makes the same decision with
the same arithmetic on the same three numbers, which the bridge hands over and takes back
around each call, so a flight is the same whichever of the two stepped it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError

#: The RC link's frame rate when none is given: an ELRS link's 250 Hz.
DEFAULT_RC_RATE_HZ = 250.0
#: The rates a link may have: 4.6.0 measures a receiver's frames 950 us to 65.5 ms apart
#: (RX_INTERVAL_MIN_US and _MAX_US in fc/rc.c; outside that its RC smoothing stays off).
MIN_RC_RATE_HZ = 16.0
MAX_RC_RATE_HZ = 1000.0
#: Frame times are compared with this slack: the simulated time is a sum of steps.
RC_FRAME_SLACK_S = 1e-9
#: A stamp this fraction of a period below a grid point counts as at it.
RC_FRAME_GRID_EPS = 1e-6


def check_rc_rate(rate_hz: float | None) -> None:
    """Raise :class:`~bfsitl.errors.SimInputError` (a ValueError) unless ``rate_hz`` is None
    (a frame in every packet) or a rate the firmware measures as a receiver's."""
    if rate_hz is None:
        return
    if not (math.isfinite(rate_hz) and MIN_RC_RATE_HZ <= rate_hz <= MAX_RC_RATE_HZ):
        raise SimInputError(
            f"an RC link rate of {rate_hz} Hz: give {MIN_RC_RATE_HZ:g} to "
            f"{MAX_RC_RATE_HZ:g} Hz (a receiver's frame rate the firmware measures), or none "
            f"for a frame in every packet"
        )


@dataclass(slots=True)
class RcFrameClock:
    """Which datagrams carry the RC trailer.

    Attributes:
        period_s: A frame every this many seconds of simulation time; 0 puts one in every
            datagram.
        next_s: The next frame goes into the first datagram stamped at or after this time.
        sent_s: The stamp of the last datagram that carried a frame: sent again (a resend of
            that datagram), it carries it again, and the FC still counts it once.
        sent: The frames taken so far at the link's rate (a resend not counted again).
    """

    period_s: float = 0.0
    next_s: float = 0.0
    sent_s: float = math.nan
    sent: int = 0

    @classmethod
    def at_rate(cls, rate_hz: float | None) -> RcFrameClock:
        """Frames at ``rate_hz`` (checked), or in every datagram for None."""
        check_rc_rate(rate_hz)
        return cls(0.0 if rate_hz is None else 1.0 / rate_hz)

    def due(self, stamp_s: float) -> bool:
        """Whether the datagram stamped ``stamp_s`` carries a frame (and if so, it is taken)."""
        period_s = self.period_s
        if period_s <= 0.0 or stamp_s == self.sent_s:
            return True
        if stamp_s < self.next_s - RC_FRAME_SLACK_S:
            return False
        self.sent_s = stamp_s
        self.sent += 1
        self.next_s = (math.floor(stamp_s / period_s + RC_FRAME_GRID_EPS) + 1.0) * period_s
        return True
