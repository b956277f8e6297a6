"""The one exception tree of bfsitl.

Every error the package raises on purpose derives from :class:`BfsitlError`, so
``except BfsitlError`` catches all of them.  Timeouts also derive from the builtin
:class:`TimeoutError` so generic code that already handles timeouts keeps working.
Messages are written for the person at the terminal: what went wrong, then what to do.

    BfsitlError
    ├── ProtocolError                  bytes that do not follow a wire format
    │   ├── PacketError                a SITL UDP datagram: wrong size or non-finite values
    │   ├── MspFrameError              an MSP frame that cannot be built (payload too large, bad id)
    │   │   └── MspRequestError        (also ValueError) values the FC would refuse or misread
    │   └── MspDecodeError             an MSP payload too short or inconsistent for its message
    ├── LinkError                      transport failures (TCP, serial, namespaces)
    │   ├── LinkClosedError            the peer closed the connection (SITL exited or rebooted)
    │   ├── LinkTimeoutError           (also TimeoutError) no bytes within the deadline
    │   ├── ExtraMissingError          an optional dependency is not installed
    │   └── BridgeError                a bridge (websocket, pty) could not serve
    │       ├── UpstreamUnreachableError   nothing answers at the SITL's address
    │       ├── UpstreamBusyError      another client holds the SITL's UART
    │       ├── ListenAddressInUseError    the bridge's own port is taken
    │       └── LinkPathError          the virtual port's symlink cannot be made
    ├── MspError                       the FC answered, but not with what was asked
    │   ├── MspErrorReply              the FC sent an ``!`` error frame (unknown or refused command)
    │   └── MspTimeoutError            (also TimeoutError) no reply: lost, port in CLI, FC gone
    ├── CliError                       the CLI session failed
    │   └── CliCommandError            a command answered ``###ERROR``
    ├── ProvisioningError              the FC's configuration could not be applied or verified
    │   └── BoardSetupError            a board is not ready for an autopilot (receiver, reboot)
    ├── SimInputError                  (also ValueError) a value the simulator cannot use
    │   └── VehicleProfileError        a vehicle profile: unknown name, bad fields (one line each)
    ├── ControllerConfigError          (also ValueError) an unknown controller or gain, a bad value
    ├── EnvironmentConfigError         (also ValueError) a bfsitl.gym option it cannot take
    ├── MetricsInputError              (also ValueError) series that are no step response
    ├── GazeboError                    the Gazebo backend (messages say what to install)
    │   ├── GazeboNotFoundError        ``gz`` (Gazebo Harmonic) is not installed / not on PATH
    │   │   └── GazeboPluginNotFoundError  libBetaflightPlugin.so was not found
    │   └── GazeboStartError           ``gz sim`` ended or never loaded the plugin
    ├── MissionError                   a flight did not go as planned
    │   ├── ArmingBlockedError         the FC refused to arm; ``blockers`` names why
    │   ├── CrashDetectedError         the vehicle tipped over or hit the ground too fast
    │   └── MissionTimeoutError        (also TimeoutError) a phase did not finish in time
    ├── ScenarioError                  a scenario file or suite that cannot be run as written
    │   ├── FaultNotSupportedError     a fault this firmware cannot express (says which can)
    │   └── ScenarioFailedError        a scenario run as a pytest item did not pass
    ├── DisturbanceUnavailableError    this backend cannot do that to a flight (Gazebo, a board)
    ├── BlackboxError                  a blackbox log that cannot be read
    │   ├── FitError                   a log that cannot identify a quad (too short, no motors)
    │   └── ReplayError                a log that cannot be flown again (no sticks, no flight)
    │       └── SettingNotCarriedError a header field that cannot be set on the replaying build
    ├── TrackDataMissingError          a flight record lacks what an analyser reads (it is skipped)
    ├── KernelUnavailableError         the compiled physics cannot be built here (no C compiler)
    └── SitlError                      the SITL process
        ├── FirmwareNotFoundError      no SITL binary anywhere we looked
        ├── FirmwareBuildError         `bfsitl firmware build` could not make a SITL binary
        │   ├── BuildToolMissingError  gcc or make is not installed
        │   └── FirmwareSourceError    not a Betaflight source tree, or an unsafe tarball
        ├── UnsupportedFirmwareError   a generation or build variant bfsitl cannot drive
        ├── PortInUseError             another process already holds the SITL's ports
        ├── SitlExitedError            the process ended (crash, reboot) while we needed it
        ├── AttachError                no running flight to attach to, several, or its port is held
        └── SitlNotReadyError          (also TimeoutError) it never answered MSP
            ├── SitlLockedOutError     it answers, but its gyro/PID tasks never ran
            └── SitlTcpServerLostError its MSP port's TCP server was lost at boot

Apart from the tree, one stop that is no error:

    KeyboardInterrupt
    └── Interrupted                    SIGTERM or SIGHUP, taken like Ctrl-C (bfsitl.stop_signals)
"""

from __future__ import annotations

import re


class BfsitlError(Exception):
    """Root of every error bfsitl raises on purpose."""


class ProtocolError(BfsitlError):
    """Bytes that do not follow a wire format."""


class PacketError(ProtocolError):
    """A SITL UDP datagram that cannot be decoded or encoded."""


class MspFrameError(ProtocolError):
    """An MSP frame that cannot be built."""


class MspDecodeError(ProtocolError):
    """An MSP payload that is too short or inconsistent for its message type."""


class MspRequestError(MspFrameError, ValueError):
    """A message holds values the FC would refuse, misread or crash on; nothing was sent."""


class LinkError(BfsitlError):
    """A transport (TCP, serial) failed."""


class LinkClosedError(LinkError):
    """The peer closed the connection."""


class LinkTimeoutError(LinkError, TimeoutError):
    """No bytes arrived before the deadline."""


class ExtraMissingError(LinkError):
    """An optional dependency is missing; the message names the pip extra."""


class BridgeError(LinkError):
    """A bridge could not serve: its own port, the path it should create, or the SITL."""


class UpstreamUnreachableError(BridgeError):
    """Nothing answers at the SITL's address (not running, wrong port, other namespace)."""


class UpstreamBusyError(BridgeError):
    """The SITL closed our connection at once: another client already holds its UART."""


class ListenAddressInUseError(BridgeError):
    """The port the bridge should listen on is taken; the message says by whom if visible."""


class LinkPathError(BridgeError):
    """The symlink for the virtual port cannot be made where asked."""


class MspError(BfsitlError):
    """The flight controller did not answer as expected."""


class MspErrorReply(MspError):
    """The FC answered with an MSP error frame (``$M!`` / ``$X!``)."""

    def __init__(self, command: int, message: str | None = None) -> None:
        self.command = command
        super().__init__(
            message
            or f"flight controller refused MSP command {command}: unknown to this firmware "
            f"or not allowed in its current state (armed, missing feature)"
        )


class MspTimeoutError(MspError, TimeoutError):
    """No reply arrived in time."""


class CliError(BfsitlError):
    """The CLI session failed."""


class CliCommandError(CliError):
    """A CLI command answered with ``###ERROR``."""

    def __init__(self, command: str, output: str) -> None:
        self.command = command
        self.output = output
        # The error alone, even where the firmware printed it straight after other lines'
        # echoes with no newline between ("...1000###ERROR IN set: ...###").
        found = re.search(r"###ERROR.*?###|ERR_CMD_NA[^\n]*", output)
        if found:
            reason = found.group(0)
        else:
            lines = output.strip().splitlines()
            reason = lines[-1] if lines else "no output"
        super().__init__(f"CLI command {command!r} failed: {reason.strip()}")


class ProvisioningError(BfsitlError):
    """The FC's configuration could not be applied or did not read back as written."""


class BoardSetupError(ProvisioningError):
    """A flight controller on a serial port is not ready for an autopilot: its receiver is
    not MSP, or a setting it needs takes a reboot first (the message says what to do)."""


class SimInputError(BfsitlError, ValueError):
    """A value given to the simulator is unusable: NaN motor command, wrong length, bad parameter.

    Also a :class:`ValueError`, so generic callers that validate input keep working.
    """


class VehicleProfileError(SimInputError):
    """A vehicle profile that cannot be used: an unknown name, an unreadable file, or bad
    fields (one line each)."""


class ControllerConfigError(BfsitlError, ValueError):
    """A controller name or gain that does not exist, or a gain value that cannot work.

    Also a :class:`ValueError`, so argument parsers and generic callers treat it as bad input.
    """


class MetricsInputError(BfsitlError, ValueError):
    """Series that cannot describe a step response (lengths differ, time goes back, ...)."""


class GazeboError(BfsitlError):
    """The Gazebo backend could not be used."""


class GazeboNotFoundError(GazeboError):
    """Gazebo (the ``gz`` command) or a part it needs is missing."""


class GazeboPluginNotFoundError(GazeboNotFoundError):
    """``gz`` is there, but the BetaflightPlugin library is not where Gazebo will look."""


class GazeboStartError(GazeboError):
    """``gz sim`` exited, or did not load the plugin in time."""


class EnvironmentConfigError(BfsitlError, ValueError):
    """A learning environment (:mod:`bfsitl.gym`) asked for what it cannot be: a firmware that
    is no lockstep build, an unknown mode or observation, a rate or duration out of range, an
    action of the wrong shape.  Also a :class:`ValueError`."""


class MissionError(BfsitlError):
    """A flight did not go as planned."""


class ArmingBlockedError(MissionError):
    """The FC did not arm.  ``blockers`` holds the names of what blocked it."""

    def __init__(self, message: str, blockers: tuple[str, ...] = ()) -> None:
        self.blockers = blockers
        super().__init__(message)


class CrashDetectedError(MissionError):
    """The vehicle tipped over or struck the ground."""


class MissionTimeoutError(MissionError, TimeoutError):
    """A mission phase did not finish within its time limit."""


class ScenarioError(BfsitlError):
    """A scenario file (or a suite of them) cannot be run as written: the message names the
    file, the table and the key."""


class FaultNotSupportedError(ScenarioError):
    """The firmware cannot express this fault (4.6.0 holds the last sticks through RC
    silence, and its virtual GPS never loses its fix); the message says what it can do."""


class ScenarioFailedError(ScenarioError):
    """A scenario run as a pytest item failed its expectations or could not be flown."""


class DisturbanceUnavailableError(BfsitlError):
    """A disturbance (a fault, a user's call) that this backend cannot apply: motors,
    sensors, wind and GPS loss need bfsitl's own physics, RC faults its RC link."""


class BlackboxError(BfsitlError):
    """A blackbox log that cannot be found or decoded."""


class FitError(BlackboxError):
    """A log that cannot identify a quad: too little flight, no motors or gyro, a fit that
    does not converge.  The message says what the log lacks."""


class ReplayError(BlackboxError):
    """A log that cannot be flown again through the firmware: no sticks logged, a replay that
    never armed or left no log of its own.  The message says what to do."""


class SettingNotCarriedError(ReplayError):
    """One header field that cannot become a setting of the replaying build; the message says
    why.  The replay lists it as not carried and goes on: it never ends a replay."""


class TrackDataMissingError(BfsitlError):
    """A flight's record lacks what an analyser reads (a blackbox log has no GPS track and no
    simulated truth): the analyser is listed as not watched, with this message, and the others
    run."""


class KernelUnavailableError(BfsitlError):
    """The compiled physics (:mod:`bfsitl.kernel`: the embedded physics is C, built once per
    machine) cannot be built or loaded here: no C compiler, or it failed.  The message says
    what to install."""


class SitlError(BfsitlError):
    """The SITL process could not be started, reached or kept running."""


class FirmwareNotFoundError(SitlError):
    """No SITL binary was found."""


class FirmwareBuildError(SitlError):
    """A SITL build failed; ``log_tail`` holds the last lines of the compiler's output."""

    def __init__(self, message: str, log_tail: str = "") -> None:
        self.log_tail = log_tail
        super().__init__(message)


class BuildToolMissingError(FirmwareBuildError):
    """gcc or make is missing; the message names the Debian package to install."""


class FirmwareSourceError(FirmwareBuildError):
    """The source to build from is not a Betaflight tree, or its tarball is unsafe to unpack."""


class UnsupportedFirmwareError(SitlError):
    """The firmware runs, but is of a generation or build variant bfsitl cannot drive."""


class PortInUseError(SitlError):
    """Another process already holds a port the SITL needs."""


class SitlExitedError(SitlError):
    """The SITL process ended while it was needed."""

    def __init__(self, message: str, returncode: int | None = None, log_tail: str = "") -> None:
        self.returncode = returncode
        self.log_tail = log_tail
        super().__init__(message)


class AttachError(SitlError):
    """``bfsitl top`` cannot attach to a running flight: none advertises itself, several do
    and none was chosen, or the flight's second MSP port is held by another client."""


class SitlNotReadyError(SitlError, TimeoutError):
    """The SITL process never answered MSP."""

    #: What went wrong, in a few words, for "... ; killed it, starting again".
    brief = "the SITL stayed silent (a hung start)"


class SitlLockedOutError(SitlNotReadyError):
    """The SITL answers MSP, but its gyro/PID tasks never ran (and never will)."""

    brief = "the SITL's gyro/PID tasks never started (the scheduler lock-out at boot)"


class SitlTcpServerLostError(SitlNotReadyError):
    """The SITL's TCP server for its MSP port failed at boot (and will never serve)."""

    brief = "the SITL's MSP port never served (the dyad TCP-server race at boot)"


class Interrupted(KeyboardInterrupt):
    """A stop signal, raised where the main thread was (bfsitl.stop_signals).  A
    :class:`KeyboardInterrupt`, not a :class:`BfsitlError`: code that already cleans up on
    Ctrl-C does the same for SIGTERM and SIGHUP, and ``except BfsitlError`` never swallows
    it."""

    def __init__(self, signal_name: str = "SIGINT") -> None:
        super().__init__(signal_name)
        self.signal_name = signal_name
