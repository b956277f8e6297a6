"""Supervise one Betaflight SITL process: start, probe until ready, restart, tear down.

Facts that shape it (``docs/firmware-findings.md``):

* The SITL writes ``eeprom.bin`` into its working directory, so the run directory *is* the
  configuration.  A fresh temporary one by default; a given one persists between runs.
* Every reboot path (CLI ``save``/``exit``, MSP_REBOOT) ends the process with ``exit(0)``;
  :meth:`SitlProcess.restart_after_reboot` brings it back on the same run directory.
* Readiness is probed with MSP_API_VERSION, never assumed after a sleep.
* The ports are bound with SO_REUSEADDR: a second SITL would share them silently, so they are
  checked before the start, in the network the SITL will run in.
* One TCP client per UART: the probe's connection is kept and handed out as :attr:`client`.
* Once it answers, the firmware says who it is and :attr:`profile` holds the conventions of its
  generation (:mod:`bfsitl.protocol.firmware_profile`), which the physics bridge, the RC link
  and the commands follow.
"""

from __future__ import annotations

import os
import shutil
import signal
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

from bfsitl.errors import (
    BfsitlError,
    LinkError,
    SitlError,
    SitlExitedError,
    SitlLockedOutError,
    SitlNotReadyError,
)
from bfsitl.fc.firmware_detect import detect_profile
from bfsitl.fc.msp_client import DEFAULT_RETRIES, DEFAULT_TIMEOUT_S, MspClient
from bfsitl.link.base import Link
from bfsitl.link.tcp_link import TcpLink
from bfsitl.owned_temp import owned_temp_dir
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, BuildOptions, FirmwareProfile
from bfsitl.protocol.messages import ApiVersion
from bfsitl.sitl.firmware import FirmwareBinary, find_firmware
from bfsitl.sitl.network import HostNetwork, IsolatedNetwork, Network, ProcessHandle
from bfsitl.sitl.ports import SITL_TCP_PORTS, SITL_UDP_PORTS, check_ports_free
from bfsitl.sitl.tcp_server_check import TcpServerCheck
from bfsitl.sitl.timer_slack import SITL_TIMER_SLACK_NS

SITL_HOST = "127.0.0.1"
SITL_MSP_PORT = 5761
LOG_NAME = "sitl.log"
#: A run directory bfsitl makes is named for its process, so a killed run's is removed by the
#: next (:mod:`bfsitl.owned_temp`).
RUN_DIR_PREFIX = "bfsitl-run-"
#: A healthy start answers in well under a second; see start() for why there is a retry.
DEFAULT_READY_TIMEOUT_S = 10.0
#: Launches before giving up.  A boot race hits a few % of launches on a loaded 2-core
#: machine, but in runs: three launches in a row (a restart after `save`) ended one CI run
#: and five in a row another, so the retries wait longer each time (_retry_wait_s) to outlast
#: a busy spell.  A lockstep build has no such race (its scheduler passes land on the gyro
#: grid).
_START_ATTEMPTS = 8
#: The first retry's wait; it doubles per retry up to _RETRY_WAIT_MAX_S (about 10 s in all).
_RETRY_WAIT_S = 0.25
_RETRY_WAIT_MAX_S = 2.0
_PROBE_INTERVAL_S = 0.05
#: A healthy SITL has run its PID task many times by the time MSP first answers.
PID_LOOP_TIMEOUT_S = 0.5
_TERM_GRACE_S = 3.0


def _retry_wait_s(attempt: int) -> float:
    """The wait before launch ``attempt + 1``: doubling from _RETRY_WAIT_S, capped."""
    return min(_RETRY_WAIT_S * 2.0 ** (attempt - 1), _RETRY_WAIT_MAX_S)


def _load_average() -> str:
    """The machine's 1-minute load for a failed launch's message (the races need a busy one)."""
    try:
        return f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs"
    except OSError:
        return "load average unknown"


@dataclass(frozen=True, slots=True)
class SitlHooks:
    """What a backend does to a SITL process, given when the process is made."""

    #: Called right after each launch, before the SITL is probed (a lockstep bridge locks
    #: the booting FC to the simulator's clock here).
    on_spawn: Callable[[], None] | None = None
    #: Wraps every MSP link this process opens (lockstep: a link whose waits step the
    #: simulation).
    link_wrapper: Callable[[Link], Link] | None = None
    #: The clock its MSP clients time out on (lockstep: simulation time).
    client_clock: Callable[[], float] | None = None


class SitlProcess:
    """One SITL process in a run directory, optionally in its own network namespace.

    >>> with SitlProcess(isolate=True) as sitl:          # doctest: +SKIP
    ...     print(sitl.client.api_version())

    Nothing runs when it is made: :meth:`start` (or entering the ``with`` block) does.

    Args:
        firmware: The binary, its path or a cached build's name; None searches as
            :func:`~bfsitl.sitl.firmware.find_firmware` does.
        workdir: The run directory, where the SITL writes ``eeprom.bin`` and its log; it
            persists.  None: a fresh temporary one, removed by :meth:`stop`.
        isolate: Run it in a private network namespace, so a stale SITL cannot share its
            ports.
        network: A network to run in, made by the caller (who closes it); None makes one
            as ``isolate`` says.
        ready_timeout_s: Seconds each launch has to answer MSP before it is killed and
            launched again.
        progress: Called with one line of text at each step of the start.
        timer_slack_ns: The process's timer slack, nanoseconds; None leaves the OS default
            (50 microseconds), which starves the SITL's scheduler.
        env: Variables added to the firmware's environment; None: it inherits bfsitl's.
        hooks: What a backend does at each launch and to each MSP link.

    Raises:
        FirmwareNotFoundError: No binary by that name or anywhere searched.
    """

    def __init__(
        self,
        firmware: FirmwareBinary | str | Path | None = None,
        *,
        workdir: str | Path | None = None,
        isolate: bool = False,
        network: Network | None = None,
        ready_timeout_s: float = DEFAULT_READY_TIMEOUT_S,
        progress: Callable[[str], None] | None = None,
        timer_slack_ns: int | None = SITL_TIMER_SLACK_NS,
        env: Mapping[str, str] | None = None,
        hooks: SitlHooks | None = None,
    ) -> None:
        self.firmware = (
            firmware if isinstance(firmware, FirmwareBinary) else find_firmware(firmware)
        )
        self._owns_workdir = workdir is None
        self.workdir = Path(workdir) if workdir is not None else owned_temp_dir(RUN_DIR_PREFIX)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.log_path = self.workdir / LOG_NAME
        self.ready_timeout_s = ready_timeout_s
        #: None leaves the OS default (50 us), which starves the SITL's scheduler.
        self.timer_slack_ns = timer_slack_ns
        #: Variables added to the firmware's environment (None: it inherits bfsitl's).
        self.env = dict(env) if env is not None else None
        self._progress = progress or (lambda _message: None)
        self._owns_network = network is None
        self._isolate = isolate
        self.network: Network | None = network
        self._process: ProcessHandle | None = None
        self.client: MspClient | None = None
        #: The conventions of the running firmware, detected at every start; 4.6.0's before.
        self.profile: FirmwareProfile = DEFAULT_PROFILE
        #: Starts that came up ready (a reboot's restart counts; a retried launch does not).
        self.starts = 0
        #: Every process launched, including ones killed and retried (hung or locked out).
        self.launches = 0
        #: The readiness probe's MSP_API_VERSION reply, for the profile's detection.
        self._ready_api: ApiVersion | None = None
        #: What a backend does at each launch and to each MSP link (:class:`SitlHooks`).
        self.hooks = hooks or SitlHooks()

    # -- state -----------------------------------------------------------------------------
    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process else None

    @property
    def uri(self) -> str:
        return f"tcp://{SITL_HOST}:{SITL_MSP_PORT}"

    @property
    def isolated(self) -> bool:
        return bool(self.network and self.network.isolated)

    def poll(self) -> int | None:
        """The exit code if the process has ended, else None."""
        return self._process.poll() if self._process else None

    @property
    def running(self) -> bool:
        return self._process is not None and self._process.poll() is None

    def log_tail(self, lines: int = 15) -> str:
        """The last lines of the SITL's output, without the EEPROM write chatter.

        Args:
            lines: How many lines at most.

        Returns:
            The lines, joined; empty when there is no log yet.
        """
        try:
            text = self.log_path.read_text(errors="replace")
        except OSError:
            return ""
        kept = [ln for ln in text.splitlines() if not ln.startswith("[FLASH_ProgramWord]")]
        return "\n".join(kept[-lines:])

    # -- lifecycle -------------------------------------------------------------------------
    def prepare_network(self) -> Network:
        """The network the SITL will run in, created now if needed.

        A physics bridge binds its motor port (UDP 9002) here *before* :meth:`start`, so it
        also receives the packet the SITL sends while it boots.
        """
        if self.network is None:
            self.network = IsolatedNetwork() if self._isolate else HostNetwork()
        return self.network

    def start(self) -> SitlProcess:
        """Start the process and wait until it answers MSP; :attr:`client` is then ready.

        Returns:
            This process, started.

        Raises:
            SitlError: It is running already.
            PortInUseError: Another process holds the SITL's ports.
            SitlExitedError: It ended during start-up (the message has its log's tail).
            SitlNotReadyError: Every launch stayed silent or locked out at boot.
        """
        if self.running:
            raise SitlError(f"SITL already running (pid {self.pid})")
        self.prepare_network()
        assert self.network is not None
        check_ports_free(SITL_TCP_PORTS, SITL_UDP_PORTS, netns_pid=self.network.netns_pid)
        argv = self.firmware.command()
        self._progress(
            f"starting {self.firmware.path.name} in {self.workdir}"
            + (" (isolated network namespace)" if self.isolated else "")
        )
        for attempt in range(1, _START_ATTEMPTS + 1):
            server_check = TcpServerCheck(
                log_path=self.log_path,
                log_offset=self._log_size(),
                netns_pid=self.network.netns_pid,
                port=SITL_MSP_PORT,
            )
            self._process = self.network.spawn(
                argv,
                self.workdir,
                self.log_path,
                timer_slack_ns=self.timer_slack_ns,
                env={**os.environ, **self.env} if self.env is not None else None,
            )
            self.launches += 1
            try:
                if self.hooks.on_spawn is not None:
                    self.hooks.on_spawn()
                self._ready_api = None
                self.client = self._wait_ready(self.ready_timeout_s, server_check)
                self._check_pid_loop(self.client)
                self.profile = detect_profile(
                    self.client, self.build_options(), api=self._ready_api
                )
                self.starts += 1
                break
            except SitlNotReadyError as exc:
                # The launch's fault, not the firmware image's, and a second launch has always
                # worked: a race at boot lost the MSP port's server (tcp_server_check) or
                # locked the PID task out (_check_pid_loop), a few % of starts on a busy
                # machine; or the SITL stayed silent for another reason.
                self._terminate()
                load = _load_average()
                if attempt == _START_ATTEMPTS:
                    exc.args = (
                        f"{exc} ({attempt} launches in a row failed at boot; "
                        f"{load}; a lockstep build has no such boot race: "
                        f"bfsitl firmware build --lockstep)",
                    )
                    raise
                wait_s = _retry_wait_s(attempt)
                self._progress(f"{exc.brief}; killed it ({load}), starting again in {wait_s:.2g} s")
                time.sleep(wait_s)  # let a busy spell pass: these races come in runs
            except BaseException:
                self._terminate()
                raise
        self._progress(f"SITL ready (pid {self.pid}) on {self.uri}")
        return self

    def build_options(self) -> BuildOptions | None:
        """What the binary was built with, when bfsitl built it (its build record), as this
        process runs it: a 4.6.0 build that can count receiver frames counts them only when
        its environment asks (a session flown with an RC link rate), else its stock receiver
        never loses the link."""
        try:
            from bfsitl.build import build_options_for_binary
            from bfsitl.build.binary_scan import RX_FRAMES_ENV
        except ImportError:
            return None
        options = build_options_for_binary(self.firmware.path)
        name, value = RX_FRAMES_ENV
        asked = {**os.environ, **(self.env or {})}.get(name) == value
        if options is not None and options.receiver_frames and not asked:
            options = replace(options, receiver_frames=None)
        return options

    def _log_size(self) -> int:
        try:
            return self.log_path.stat().st_size
        except OSError:
            return 0

    def _wait_ready(self, timeout_s: float, server_check: TcpServerCheck) -> MspClient:
        deadline = time.monotonic() + timeout_s
        last_problem = "no answer yet"
        while time.monotonic() < deadline:
            server_check.check(time.monotonic())
            code = self.poll()
            if code is not None:
                raise SitlExitedError(
                    f"SITL exited with code {code} during start-up; its log "
                    f"({self.log_path}) ends with:\n{self.log_tail()}",
                    code,
                    self.log_tail(),
                )
            try:
                client = self.connect(timeout_s=0.3, retries=0)
            except LinkError as exc:
                last_problem = str(exc)
                time.sleep(_PROBE_INTERVAL_S)  # polling interval, not a readiness guess
                continue
            try:
                # Kept: the profile needs it too, and one start should ask it once.
                self._ready_api = client.get(ApiVersion)
                # Probing used short timeouts; from here on the usual ones apply.
                client.timeout_s, client.retries = DEFAULT_TIMEOUT_S, DEFAULT_RETRIES
                return client
            except BfsitlError as exc:
                last_problem = str(exc)
                client.close()
        raise SitlNotReadyError(
            f"SITL did not answer MSP within {timeout_s:.0f} s ({last_problem}); log "
            f"({self.log_path}) ends with:\n{self.log_tail()}"
        )

    def _check_pid_loop(self, client: MspClient) -> None:
        """Raise :class:`SitlLockedOutError` if the firmware's PID task has not run.

        4.6.0's ``scheduler()`` runs GYRO/FILTER/PID only from a pass that arrives at most
        one 125 us period late, or, after a longer gap, from one that lands less than
        ``schedLoopStartCycles`` before a period boundary.  In SITL a cycle is 1 us, that
        margin starts at 1 and grows only on a late run, and ``lastTargetCycles`` moves only
        when the tasks run.  So if the main thread's first passes after ``tasksInit()`` skip
        the 125..250 us window (preempted or faulting for ~100 us on a busy machine) the
        tasks never run in this process, and no fdm packet is ever answered.  MSP_STATUS
        cycleTime is the PID task's last period: 0 until the task has run.  Master's scheduler
        has the same start margin (``schedLoopStartCycles``, scheduler.c) and was seen locked
        out the same way.
        """
        deadline = time.monotonic() + PID_LOOP_TIMEOUT_S
        while not client.status().cycle_time_us:
            if time.monotonic() >= deadline:
                raise SitlLockedOutError(
                    f"the SITL (pid {self.pid}) answers MSP but its gyro/PID tasks have not "
                    f"run in {PID_LOOP_TIMEOUT_S} s (MSP_STATUS cycleTime 0): the firmware's "
                    f"scheduler locked them out at boot, for the life of the process"
                )
            time.sleep(_PROBE_INTERVAL_S)

    def connect(
        self, *, timeout_s: float = DEFAULT_TIMEOUT_S, retries: int = DEFAULT_RETRIES
    ) -> MspClient:
        """A new MSP client on a new connection (the SITL serves one client per port).

        Args:
            timeout_s: Seconds the client waits for each reply.
            retries: How many times the client repeats a read that got no reply.

        Returns:
            The client, connected to UART1.

        Raises:
            SitlError: The process has not been started.
            LinkError: Nothing accepts the connection.
        """
        if self.network is None:
            raise SitlError("SITL not started")
        link: Link = TcpLink(
            SITL_HOST, SITL_MSP_PORT, timeout_s=timeout_s, socket_factory=self.network.socket
        )
        hooks = self.hooks
        if hooks.link_wrapper is not None:
            link = hooks.link_wrapper(link)  # the link brings its own wake policy
        return MspClient(
            link, timeout_s=timeout_s, retries=retries, clock=hooks.client_clock or time.monotonic
        )

    def wait_exit(self, timeout_s: float) -> int | None:
        """Wait for the process to end by itself (after a reboot).

        Args:
            timeout_s: Seconds to wait at most.

        Returns:
            Its exit code, or None if it is still running (or was never started).
        """
        if self._process is None:
            return None
        return self._process.wait(timeout_s)

    def restart_after_reboot(self, exit_timeout_s: float = 10.0) -> SitlProcess:
        """The SITL ends on every reboot: wait for that, then start it again, same workdir.

        Args:
            exit_timeout_s: Seconds to wait for the process to end after the reboot was
                asked for.

        Returns:
            This process, started again.

        Raises:
            SitlError: It did not end in time, or the new start failed (as :meth:`start`).
        """
        if self.client is not None:
            self.client.close()
            self.client = None
        code = self.wait_exit(exit_timeout_s)
        if code is None:
            raise SitlError(
                f"SITL (pid {self.pid}) did not exit within {exit_timeout_s} s after the "
                f"reboot request"
            )
        self._progress(f"SITL exited with code {code} (reboot); restarting")
        self._process = None
        return self.start()

    def restart(self) -> SitlProcess:
        """Stop (if running) and start again on the same run directory and network."""
        self._terminate()
        return self.start()

    def _terminate(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        process, self._process = self._process, None
        if process is None or process.poll() is not None:
            return
        process.signal_group(signal.SIGTERM)
        if process.wait(_TERM_GRACE_S) is None:
            process.signal_group(signal.SIGKILL)
            process.wait(_TERM_GRACE_S)

    def stop(self) -> None:
        """Terminate the process group (TERM, then KILL), close the namespace, clean up."""
        try:
            self._terminate()
        finally:
            if self._owns_network and self.network is not None:
                self.network.close()
                self.network = None
            if self._owns_workdir:
                shutil.rmtree(self.workdir, ignore_errors=True)

    def __enter__(self) -> SitlProcess:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def __repr__(self) -> str:
        state = f"pid {self.pid}" if self.running else "stopped"
        return f"<SitlProcess {self.firmware.path.name} {state} workdir={self.workdir}>"
