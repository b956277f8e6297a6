"""What a lockstep session's parts see of the stepping (:mod:`bfsitl.sim.lockstep`): the
mission's clock (:class:`LockstepClock`: waiting means stepping), the RC command that rides in
the fdm packets (:class:`LockstepRc`) and the MSP link whose waits step the simulation
(:class:`SteppedLink`: the lockstep FC answers only as its time moves)."""

from __future__ import annotations

import math

from bfsitl.errors import SitlError, SitlExitedError
from bfsitl.fc.rc_link import RcCommand, RcFault, RcLinkStats
from bfsitl.link.base import Link
from bfsitl.sim.lockstep import LockstepBridge


class LockstepClock:
    """The mission clock of a lockstep session: simulation time, and waiting steps it."""

    def __init__(self, bridge: LockstepBridge) -> None:
        self.bridge = bridge

    def now_s(self) -> float:
        return self.bridge.sim_time_s

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            self.bridge.run_for(seconds)


class LockstepRc:
    """The RC command of a lockstep session: it rides in the fdm packets, a frame at the
    link's rate (:attr:`LockstepBridge.rc_frames`) or in every one.

    Offers what a session uses of an RC link (``set``, ``command``, ``stats``, ``close``);
    closing centres the sticks, lowers the throttle and drops the switches, and steps a
    tenth of a second so the FC has taken it.
    """

    FAREWELL_S = 0.1

    def __init__(self, bridge: LockstepBridge) -> None:
        self.bridge = bridge
        self.closed = False

    @property
    def command(self) -> RcCommand:
        return self.bridge.rc_command

    def set(self, command: RcCommand) -> None:
        self.bridge.set_rc_command(command)  # validated now, so errors surface here

    def start(self) -> LockstepRc:
        return self

    @property
    def fault(self) -> RcFault | None:
        return self.bridge.rc_fault.fault

    @fault.setter
    def fault(self, fault: RcFault | None) -> None:
        """Inject ``fault`` from the next fdm packet on (None ends it)."""
        self.bridge.rc_fault.inject(fault, self.bridge.rc_command)

    def stats(self) -> RcLinkStats:
        """The frames sent so far and their period, on simulation time: a frame in the
        first packet at or after each of the link's frame times, or one in every packet."""
        bridge = self.bridge
        period_s = bridge.rc_frames.period_s
        if period_s <= 0.0:
            period_ms = bridge.step_s * 1000
            return RcLinkStats(bridge.lockstep_stats().steps, period_ms, period_ms, period_ms, 0)
        # A period that is not a whole number of steps puts some frames a step later.
        longest_ms = math.ceil(period_s / bridge.step_s - 1e-6) * bridge.step_s * 1000
        return RcLinkStats(bridge.rc_frames.sent, period_s * 1000, longest_ms, longest_ms, 0)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.bridge.rc_fault.fault = None  # the farewell goes out whatever was injected
        self.bridge.rc_command = self.bridge.rc_command.disarmed()
        try:
            self.bridge.run_for(self.FAREWELL_S)
        except (SitlError, OSError):
            pass  # the SITL is gone: nothing holds the sticks any more


class SteppedLink(Link):
    """A link whose waits step the simulation: the lockstep FC answers only as time moves.

    Reads are non-blocking on the wrapped link; while nothing has come, one step at a time is
    taken until the timeout, counted in *simulation* seconds, has passed.
    """

    #: The FC reads its TCP port after the step that follows a write (the bridge marks it):
    #: waiting steps it, no wake bytes needed.
    wants_wake_bytes = False

    def __init__(self, inner: Link, bridge: LockstepBridge) -> None:
        super().__init__(inner.uri, inner.timeout_s)
        self.max_in_flight_bytes = inner.max_in_flight_bytes
        self.inner = inner
        self.bridge = bridge
        #: The bridge's step count when a read last found nothing (-1: none yet).
        self._empty_at_step = -1

    def _write_bytes(self, data: bytes) -> None:
        self.inner._write_bytes(data)
        self.bridge.wrote_to_fc()

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        # The FC writes only while it steps: a read that found nothing is not repeated before
        # the next step (a request is written and read for at once, every control step).
        bridge = self.bridge
        if bridge.steps_taken != self._empty_at_step:
            data = self.inner._read_bytes(max_bytes, 0.0)
            if data or data is None:
                return data
            self._empty_at_step = bridge.steps_taken
        if timeout_s <= 0:
            return b""
        until_s = self.bridge.sim_time_s + timeout_s
        fd = self.inner.readable_fd
        while self.bridge.sim_time_s < until_s:
            try:
                if fd < 0:
                    self.bridge.step()
                else:
                    self.bridge.step_until_readable(fd, until_s)
            except SitlExitedError:
                return None  # the SITL ended (a reboot): to the reader, the peer closed
            data = self.inner._read_bytes(max_bytes, 0.0)
            if data or data is None:
                return data
            self._empty_at_step = bridge.steps_taken
        return b""

    def pause(self, seconds: float) -> None:
        try:
            self.bridge.run_for(seconds)
        except SitlExitedError:
            pass  # nothing on the other side to wait for; the next read reports it

    def _close(self) -> None:
        self.inner.close()
