"""Is the simulation faithful?  Firmware clock, PID loop and packet exchange, measured live.

* ``fc_clock_ratio``: firmware time / simulated time since :meth:`HealthMonitor.reset`.  The
  firmware's RTC is set over MSP (MSP_SET_RTC) and read back (MSP_RTC); it advances with the
  firmware's own millis(), i.e. with the SITL's estimated clock rate.  Each reading is paired
  with the simulated time at the middle of its MSP round trip.  Target 1.00 +/- 0.02.
* ``fc_cycle_us``: median of a few MSP_STATUS cycle times: the firmware's last PID period in its
  own microseconds.  125 us when 4.6.0's 8 kHz gyro/PID loop keeps up (1000 us for master's
  1 kHz); more means it starves
  (each scheduler pass costs a real sleep, so running faster than the host allows shows here).
* ``answered_ratio`` and ``speed``: from the bridge's counters over the sampling window.

The CLI is never used for this: entering it would block arming (and ``exit`` ends a SITL).
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, FirmwareProfile
from bfsitl.sim.bridge import BridgeStats, SitlBridge

#: Any fixed instant will do; far from the epoch so no field under- or overflows.
RTC_REFERENCE_UNIX_S = 1_700_000_000
CYCLE_POLLS = 5


#: The physics issue's targets for a faithful simulation (4.6.0's 8 kHz PID loop).
CLOCK_RATIO_TOLERANCE = 0.02
MAX_CYCLE_US = 150.0
MIN_ANSWERED_RATIO = 0.99
#: A PID cycle this much longer than the firmware's own period means the loop starves.
CYCLE_MARGIN = 1.2
#: Master's PID runs at 1 kHz, the rate the bridge sends fdm packets: the firmware answers at
#: most one packet per PID run, so when the two phases drift a packet goes unanswered (90-94 %
#: answered measured at 1x on a healthy run). 4.6.0 runs its PID eight times per packet.
MIN_ANSWERED_RATIO_SAME_RATE = 0.85


def targets_for(profile: FirmwareProfile) -> tuple[float, float]:
    """(max PID cycle us, min share of fdm answered) for a firmware generation."""
    max_cycle_us = max(MAX_CYCLE_US, profile.expected_cycle_us * CYCLE_MARGIN)
    min_answered = (
        MIN_ANSWERED_RATIO if profile.gyro_rate_hz > 1000 else MIN_ANSWERED_RATIO_SAME_RATE
    )
    return max_cycle_us, min_answered


def meets_targets(
    fc_clock_ratio: float | None,
    fc_cycle_us: float | None,
    answered_ratio: float,
    profile: FirmwareProfile = DEFAULT_PROFILE,
) -> bool:
    """Firmware time / sim time 1.00 +/- 0.02, the PID cycle near the firmware's own period
    (<= 150 us for 4.6.0's 8 kHz), and the fdm packets answered (>= 99 % on 4.6.0)."""
    max_cycle_us, min_answered = targets_for(profile)
    return (
        fc_clock_ratio is not None
        and abs(fc_clock_ratio - 1.0) <= CLOCK_RATIO_TOLERANCE
        and fc_cycle_us is not None
        and fc_cycle_us <= max_cycle_us
        and answered_ratio >= min_answered
    )


@dataclass(frozen=True, slots=True)
class HealthSample:
    sim_time_s: float
    fc_clock_ratio: float | None
    fc_cycle_us: float | None
    answered_ratio: float
    speed: float
    misses: int
    late_replies: int
    skipped: int = 0
    profile: FirmwareProfile = DEFAULT_PROFILE

    @property
    def faithful(self) -> bool:
        return meets_targets(
            self.fc_clock_ratio, self.fc_cycle_us, self.answered_ratio, self.profile
        )

    def as_dict(self) -> dict[str, object]:
        record = asdict(self)
        record["profile"] = self.profile.name
        record["faithful"] = self.faithful
        return record


class HealthMonitor:
    """Samples the health of a running bridge over an MSP client to the same SITL."""

    def __init__(self, bridge: SitlBridge, client: MspClient) -> None:
        self.bridge = bridge
        self.client = client
        self._fc_reference_s: float | None = None
        self._sim_reference_s = 0.0
        self._last_stats: BridgeStats | None = None

    def _timed(self, request: msg.SetRtc | None) -> tuple[bytes, float]:
        """One RTC exchange and the simulated time at the middle of its round trip."""
        before_s = self.bridge.sim_time_s
        if request is None:
            payload = self.client.request(msg.Rtc.COMMAND)
        else:
            payload = self.client.send(request)
        return payload, (before_s + self.bridge.sim_time_s) / 2

    def reset(self) -> None:
        """Start a new measurement (and after a SITL restart: the new FC has no RTC)."""
        _, self._sim_reference_s = self._timed(msg.SetRtc(RTC_REFERENCE_UNIX_S, 0))
        self._fc_reference_s = float(RTC_REFERENCE_UNIX_S)
        self._last_stats = self.bridge.stats()

    def fc_clock_ratio(self) -> float | None:
        if self._fc_reference_s is None:
            self.reset()
            return None
        payload, sim_now_s = self._timed(None)
        rtc = msg.Rtc.decode(payload)
        if rtc.datetime_utc is None:
            return None
        fc_elapsed_s = rtc.datetime_utc.timestamp() - self._fc_reference_s
        sim_elapsed_s = sim_now_s - self._sim_reference_s
        if sim_elapsed_s <= 0.05:
            return None  # too short to mean anything at millisecond resolution
        return fc_elapsed_s / sim_elapsed_s

    def fc_cycle_us(self, polls: int = CYCLE_POLLS) -> float:
        return statistics.median(self.client.status().cycle_time_us for _ in range(polls))

    def sample(self) -> HealthSample:
        ratio = self.fc_clock_ratio()
        cycle_us = self.fc_cycle_us()
        stats = self.bridge.stats()
        window = stats.minus(self._last_stats) if self._last_stats else stats
        self._last_stats = stats
        return HealthSample(
            sim_time_s=round(stats.sim_time_s, 3),
            fc_clock_ratio=None if ratio is None else round(ratio, 4),
            fc_cycle_us=cycle_us,
            answered_ratio=round(window.answered_ratio, 4),
            speed=round(window.speed, 4),
            misses=window.misses,
            late_replies=window.late_replies,
            skipped=window.skipped,
            profile=self.bridge.profile,
        )


def lock_clock(
    monitor: HealthMonitor,
    *,
    tolerance: float = 0.01,
    window_s: float = 1.5,
    attempts: int = 6,
    sleep: Callable[[float], None] = time.sleep,
) -> float | None:
    """At speed != 1, re-send calibration pairs until firmware/sim time is within tolerance.

    Measured: the pair sent while the SITL is still booting comes out 9-15 % fast, fresh
    pairs sent during steady stepping land within about 1.5 %.  So the boot-time pair is only
    measured, then fresh pairs follow, each aimed with the median error of the steady pairs
    so far (a pair's error is the measured ratio times the correction it was sent with, so
    corrections do not compound).  Returns the last measured ratio (None if never measured).
    At speed 1 there is nothing to do: the SITL's clock rate starts at 1.0.
    """
    bridge = monitor.bridge
    if bridge.speed == 1.0 or bridge.timestamps != "frozen":
        return None
    ratio: float | None = None
    correction = 1.0
    steady_errors: list[float] = []
    for attempt in range(attempts):
        monitor.reset()
        sleep(window_s)
        ratio = monitor.fc_clock_ratio()
        if ratio is None:
            continue
        if abs(ratio - 1.0) <= tolerance:
            return ratio
        if attempt > 0:  # the first pair was sent during boot: not representative
            steady_errors.append(ratio * correction)
        correction = statistics.median(steady_errors) if steady_errors else 1.0
        bridge.recalibrate(correction)
        sleep(0.1)  # let the pair go out before the next measurement starts
    return ratio
