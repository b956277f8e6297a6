"""RC input for the flight controller: UDP rc_packets for a SITL, MSP_SET_RAW_RC for a board.

Facts that shape it (``docs/firmware-findings.md``):

* The first UDP rc_packet permanently replaces MSP as the SITL's RC source, and from then on
  the SITL holds the last channels forever when packets stop: no RXLOSS, no failsafe.  So a
  link must send disarm and low throttle before it goes quiet, on every way out (normal stop,
  exception, Ctrl-C, garbage collection).
* An RC packet that reaches the SITL while it boots leaves 4.6.0 in RXLOSS forever: start a
  link only once the FC answers MSP (``SitlProcess.start`` returns then).
* Channels are sent in the receiver map order, AETR by default, then AUX1...; values outside
  1000-2000 us are clamped here (the firmware treats < 885 or > 2115 as invalid).
* On a real board RC goes over MSP_SET_RAW_RC, which takes one MSP packet per serial tick from
  the same budget as telemetry: :class:`MspRcLink` sends at 25 Hz by default.
"""

from __future__ import annotations

import math
import random
import socket
import statistics
import threading
import time
from collections import deque
from dataclasses import dataclass, field, replace
from typing import Protocol

from bfsitl.errors import BfsitlError
from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import messages as msg
from bfsitl.protocol.sitl_packets import RcPacket

RC_MIN_US = 1000
RC_MAX_US = 2000
RC_MID_US = 1500
RC_PORT = 9004
DEFAULT_UDP_RATE_HZ = 100.0
DEFAULT_MSP_RATE_HZ = 25.0
#: Disarm/low-throttle packets sent on close, so one lost datagram cannot leave it armed.
_FAREWELL_PACKETS = 3


def _check_numbers(values: tuple[float, ...]) -> None:
    """Raise naming the first channel value that is not a finite number.  One sum is
    checked first: every channel is looked at only when it is not finite."""
    if math.isfinite(sum(values)):
        return
    for value in values:
        if not math.isfinite(value):
            raise BfsitlError(f"RC channel value {value!r} is not a number")


@dataclass(frozen=True, slots=True)
class RcCommand:
    """Sticks and switches in microseconds; clamped to 1000-2000 when sent."""

    roll_us: float = RC_MID_US
    pitch_us: float = RC_MID_US
    throttle_us: float = RC_MIN_US
    yaw_us: float = RC_MID_US
    aux_us: tuple[float, ...] = field(default=(RC_MIN_US,))

    def channels_aetr(self) -> tuple[int, ...]:
        """Roll, pitch, throttle, yaw, AUX1... (the default receiver map), clamped."""
        self.check()
        return self.checked_channels_aetr()

    def check(self) -> None:
        """Raise :class:`BfsitlError` naming the first channel that is not a finite number."""
        _check_numbers((self.roll_us, self.pitch_us, self.throttle_us, self.yaw_us, *self.aux_us))

    def checked_channels_aetr(self) -> tuple[int, ...]:
        """:meth:`channels_aetr` of a command that has passed :meth:`check` (a control step
        packs one every step: rounded, then clamped, without a call per bound)."""
        values = (self.roll_us, self.pitch_us, self.throttle_us, self.yaw_us, *self.aux_us)
        return tuple(
            [
                RC_MIN_US if us < RC_MIN_US else RC_MAX_US if us > RC_MAX_US else us
                for us in map(round, values)
            ]
        )

    def with_throttle(self, throttle_us: float) -> RcCommand:
        """The same sticks and switches with another throttle (what a control step changes;
        built directly, as ``dataclasses.replace`` costs several times more)."""
        return RcCommand(self.roll_us, self.pitch_us, throttle_us, self.yaw_us, self.aux_us)

    def disarmed(self) -> RcCommand:
        """Centred sticks, throttle low, every AUX switch low (ARM off)."""
        return RcCommand(aux_us=(RC_MIN_US,) * len(self.aux_us))

    def with_aux(self, index: int, value_us: float) -> RcCommand:
        aux = list(self.aux_us) + [RC_MIN_US] * max(0, index + 1 - len(self.aux_us))
        aux[index] = value_us
        return replace(self, aux_us=tuple(aux))


#: What every link starts with and falls back to when it stops.
SAFE_COMMAND = RcCommand()


@dataclass(frozen=True, slots=True)
class RcFault:
    """An injected RC fault: what a link sends instead of its command while it lasts.

    Attributes:
        silent: Send nothing at all (master's UDP receiver, and a lockstep 4.6.0 flown at an
            RC link rate, raise RXLOSS 150 ms later; a stock 4.6.0 holds the last channels
            forever, so this is no fault there).
        pulses_us: (channel index, pulse in microseconds) pairs sent as they are,
            unclamped: a pulse below ``rx_min_usec`` (885) or above ``rx_max_usec`` (2115)
            is what a receiver reports for a lost channel: a flight channel (AETR) invalid
            for 300 ms starts the failsafe on every generation, but in stage 2 the firmware
            counts the frames as valid again and recovers (rx/rx.c), so the loss comes and
            goes (measured on both).  Channel indexes are 0 to 15, pulses 0 to 65535.
        delay_s: Send the command that was set this many seconds ago, as a slow radio link
            delivers it.
        jitter_s: Up to this many seconds more delay, uniformly at random, per packet.

    Raises:
        BfsitlError: A channel or pulse the RC packet cannot carry, or a negative delay or
            jitter.
    """

    silent: bool = False
    pulses_us: tuple[tuple[int, int], ...] = ()
    delay_s: float = 0.0
    jitter_s: float = 0.0

    def __post_init__(self) -> None:
        for index, pulse in self.pulses_us:
            if not (0 <= index < 16 and 0 <= pulse <= 0xFFFF):
                raise BfsitlError(
                    f"RC fault: channel {index + 1} = {pulse} us is not a "
                    f"pulse the rc_packet can carry (16 channels, 0-65535)"
                )
        if not (self.delay_s >= 0 and self.jitter_s >= 0):
            raise BfsitlError(
                f"RC fault: delay {self.delay_s} s and jitter {self.jitter_s} s must be >= 0"
            )


class RcFaultState:
    """Applies an :class:`RcFault` to the commands a link sends; the link's one helper for
    it, on its own time base (wall time for a UDP link, simulation time in lockstep)."""

    #: How much command history a delay may reach back into.
    HISTORY_S = 5.0

    def __init__(self, seed: int = 0) -> None:
        self.fault: RcFault | None = None
        self._history: deque[tuple[float, RcCommand]] = deque()
        #: What went out when the fault began: where a delay starts from.
        self._last_sent: tuple[float, RcCommand] | None = None
        self._rng = random.Random(f"bfsitl.rc.jitter:{seed}")

    def inject(self, fault: RcFault | None, current: RcCommand) -> None:
        """``fault`` from now on (None ends it); ``current`` is what the link was sending, so
        a delay holds it until newer commands are old enough."""
        self.fault = fault
        self._history.clear()
        self._last_sent = (-math.inf, current)

    def note(self, time_s: float, command: RcCommand) -> None:
        """Remember what was commanded when (while a delay is in force); the history starts
        with what went out before the delay, so a command set just after it waits too."""
        if not self._history and self._last_sent is not None:
            self._history.append(self._last_sent)
        if not self._history or self._history[-1][1] is not command:
            self._history.append((time_s, command))
        while len(self._history) > 1 and self._history[1][0] < time_s - self.HISTORY_S:
            self._history.popleft()

    def channels(self, time_s: float, command: RcCommand) -> tuple[int, ...] | None:
        """The channels to send at ``time_s`` for ``command`` (None: send nothing)."""
        fault = self.fault
        if fault is None:
            return command.channels_aetr()
        if fault.silent:
            return None
        late_s = fault.delay_s + (
            self._rng.uniform(0.0, fault.jitter_s) if fault.jitter_s > 0 else 0.0
        )
        if late_s > 0:
            self.note(time_s, command)
            for stamp_s, past in reversed(self._history):
                if stamp_s <= time_s - late_s:
                    command = past
                    break
            else:
                command = self._history[0][1]
        channels = list(command.channels_aetr())
        for index, pulse in fault.pulses_us:
            channels.extend([RC_MIN_US] * (index + 1 - len(channels)))
            channels[index] = pulse
        return tuple(channels)


@dataclass(frozen=True, slots=True)
class RcLinkStats:
    """Send timing of the link's thread: how steady the stream is."""

    packets: int
    period_mean_ms: float
    period_p99_ms: float
    period_max_ms: float
    send_errors: int


class RcSender(Protocol):
    """What sends the RC command (a UDP, lockstep or MSP link): the latest is repeated."""

    @property
    def command(self) -> RcCommand: ...

    def set(self, command: RcCommand) -> None: ...

    def start(self) -> object: ...

    def stats(self) -> RcLinkStats: ...

    def close(self) -> None: ...

    #: An injected RC fault (scenarios), None when the link is healthy.
    fault: RcFault | None


class _SocketFactory(Protocol):
    def socket(self, family: int, kind: int) -> socket.socket: ...


class _RcLinkBase:
    """The thread, the current command, the timing statistics and the safe shutdown."""

    def __init__(self, rate_hz: float) -> None:
        if not 1.0 <= rate_hz <= 500.0:
            raise ValueError(f"rate_hz {rate_hz} outside 1..500")
        self.rate_hz = rate_hz
        self._command = SAFE_COMMAND
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._periods_s: list[float] = []
        self._packets = 0
        self._send_errors = 0
        self.closed = False
        self._fault = RcFaultState()

    # -- the command -----------------------------------------------------------------------
    @property
    def command(self) -> RcCommand:
        return self._command

    def set(self, command: RcCommand) -> None:
        """The command the next packet carries (validated now, so errors surface here)."""
        command.channels_aetr()
        self._command = command

    @property
    def fault(self) -> RcFault | None:
        return self._fault.fault

    @fault.setter
    def fault(self, fault: RcFault | None) -> None:
        """Inject ``fault`` from the next packet on (None ends it)."""
        self._fault.inject(fault, self._command)

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> _RcLinkBase:
        if self._thread is not None:
            raise BfsitlError("RC link already started")
        self._thread = threading.Thread(target=self._run, name="bfsitl-rc", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Send disarm and low throttle, then stop.  Safe to call more than once."""
        if self.closed:
            return
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._command = self._command.disarmed()
        self._fault.fault = None  # the farewell goes out whatever was injected
        for _ in range(_FAREWELL_PACKETS):
            self._send_safely(self._command.channels_aetr())
        self.closed = True
        self._release()

    def __enter__(self) -> _RcLinkBase:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def __del__(self) -> None:  # last resort: never leave a SITL holding armed sticks
        try:
            if not self.closed:
                self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    def stats(self) -> RcLinkStats:
        periods_ms = sorted(p * 1000 for p in self._periods_s[-5000:])
        if not periods_ms:
            return RcLinkStats(self._packets, 0.0, 0.0, 0.0, self._send_errors)
        p99 = periods_ms[min(len(periods_ms) - 1, int(0.99 * len(periods_ms)))]
        return RcLinkStats(
            self._packets, statistics.fmean(periods_ms), p99, periods_ms[-1], self._send_errors
        )

    # -- the thread ------------------------------------------------------------------------
    def _run(self) -> None:
        period_s = 1.0 / self.rate_hz
        next_s = time.perf_counter()
        last_s: float | None = None
        while not self._stop.is_set():
            channels = self._fault.channels(time.monotonic(), self._command)
            if channels is not None:
                self._send_safely(channels)
            now_s = time.perf_counter()
            if last_s is not None:
                self._periods_s.append(now_s - last_s)
            last_s = now_s
            # Absolute schedule: a late packet does not shift every later one.
            next_s += period_s
            if next_s < now_s:
                next_s = now_s
            self._stop.wait(next_s - now_s)

    def _send_safely(self, channels: tuple[int, ...]) -> None:
        try:
            self._send(channels)
            self._packets += 1
        except (OSError, BfsitlError):
            self._send_errors += 1  # a restarting SITL refuses for a moment; keep going

    def _send(self, channels: tuple[int, ...]) -> None:
        raise NotImplementedError

    def _release(self) -> None:
        pass


class UdpRcLink(_RcLinkBase):
    """rc_packets to a SITL (UDP 9004), 100 Hz by default, from a thread of its own.

    ``network`` makes the socket (an isolated SITL's namespace); None = the host network.
    """

    def __init__(
        self,
        network: _SocketFactory | None = None,
        *,
        rate_hz: float = DEFAULT_UDP_RATE_HZ,
        host: str = "127.0.0.1",
        port: int = RC_PORT,
    ) -> None:
        super().__init__(rate_hz)
        self._address = (host, port)
        if network is None:
            self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        else:
            self._sock = network.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._started_s = time.monotonic()

    def _send(self, channels: tuple[int, ...]) -> None:
        packet = RcPacket(time.monotonic() - self._started_s, channels)
        self._sock.sendto(packet.pack(), self._address)

    def _release(self) -> None:
        self._sock.close()


class MspRcLink(_RcLinkBase):
    """MSP_SET_RAW_RC for a real board (receiver set to MSP), 25 Hz by default.

    Each packet takes one of the FC's ~100 MSP packets per second at the default serial rate,
    shared with telemetry; 50 Hz RC plus 40 Hz polling was measured to delay RC past 150 ms and
    trigger RXLOSS, so keep RC + telemetry well under the serial rate.
    """

    def __init__(self, client: MspClient, *, rate_hz: float = DEFAULT_MSP_RATE_HZ) -> None:
        super().__init__(rate_hz)
        self.client = client

    def _send(self, channels: tuple[int, ...]) -> None:
        self.client.send(msg.SetRawRc(channels))
