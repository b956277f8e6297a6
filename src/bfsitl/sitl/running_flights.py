"""Running flights that say where a second MSP client can reach them (``bfsitl top``).

A flight that serves MSP on its SITL's UART2 as well (``bfsitl fly`` does by default) writes
one small JSON file, its *advert*, into ``flights/`` of bfsitl's cache
(:func:`flights_dir`), and removes it when it ends: normally, on an error, on Ctrl-C or
SIGTERM alike (the session's exit stack).  Only a SIGKILL or a power cut leaves one behind,
and such a stale advert is recognised and removed by the next reader: its process is gone,
or its pid now belongs to another process (the advert records the process's start time,
which a reused pid does not share).

An advert names the flight (:attr:`FlightAdvert.key`, the flight process's pid, with a
suffix for a second flight in one process), the command that flies it, the firmware, the
address of UART2, and a process inside the SITL's private network namespace, through which
a reader reaches an isolated SITL (:class:`bfsitl.sitl.network.IsolatedNetwork` with
``join_pid``).  Adverts are written whole (write to a temporary file, then rename), so a
reader never sees half of one.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import os
import shlex
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from bfsitl.atomic_file import write_atomically
from bfsitl.cache_location import cache_root
from bfsitl.errors import AttachError

#: The folder of bfsitl's cache that holds the adverts.
FLIGHTS_DIR_NAME = "flights"
#: Bumped when a field changes meaning; adverts of another version are ignored.
ADVERT_VERSION = 1
#: A command line longer than this is cut (with "...") in the advert.
MAX_COMMAND_CHARS = 160

PROC_ROOT = Path("/proc")
#: Where a SITL's UART2 can be: its loopback (in its namespace or the host's).
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")

#: ``start_ticks(pid)``: when that process started, clock ticks after boot; None if it is gone.
StartTicks = Callable[[int], "int | None"]

#: The flights this process has advertised so far (a second one gets ``PID.2`` as its key).
_advertised_here = itertools.count(1)


def flights_dir(environ: Mapping[str, str] | None = None) -> Path:
    """Where adverts are kept: ``flights/`` in bfsitl's cache (``$BFSITL_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/bfsitl/firmware``, else ``~/.cache/bfsitl/firmware``)."""
    return cache_root(environ) / FLIGHTS_DIR_NAME


def process_start_ticks(pid: int, proc_root: Path = PROC_ROOT) -> int | None:
    """When process ``pid`` started (clock ticks after boot, field 22 of ``/proc/PID/stat``),
    or None when there is no such process or it has ended (a zombie counts as ended)."""
    try:
        text = (proc_root / str(pid) / "stat").read_text()
    except OSError:
        return None
    fields = text.rsplit(")", 1)[-1].split()
    try:
        state, ticks = fields[0], int(fields[19])
    except (IndexError, ValueError):
        return None
    return None if state in ("Z", "X") else ticks


def command_line(argv: Sequence[str] | None = None) -> str:
    """This process's command as a person would type it (``bfsitl fly --mission square``),
    cut at :data:`MAX_COMMAND_CHARS`."""
    words = list(sys.argv if argv is None else argv)
    if words:
        words[0] = Path(words[0]).name
    text = shlex.join(words)
    if len(text) > MAX_COMMAND_CHARS:
        text = text[: MAX_COMMAND_CHARS - 3] + "..."
    return text


@dataclass(frozen=True, slots=True)
class FlightAdvert:
    """Where a running flight's second MSP client connects, and how to tell it is running.

    Attributes:
        key: The name ``bfsitl top --attach KEY`` takes: the flight process's pid (``PID.2``
            for a second flight in the same process).
        pid: The flight's process.
        started_ticks: When that process started (``/proc/PID/stat``): a pid reused by
            another process does not match it.
        command: The command that flies it, for the person choosing.
        firmware: The firmware's name and version.
        host: UART2's address, inside the SITL's network.
        port: UART2's TCP port.
        netns_pid: A process inside the SITL's private network namespace, through which a
            reader connects; None when the SITL runs in the host's network.
        started_at_s: When the flight was advertised, seconds since the epoch.
        workdir: The SITL's run directory.
    """

    key: str
    pid: int
    started_ticks: int
    command: str
    firmware: str
    host: str
    port: int
    netns_pid: int | None
    started_at_s: float
    workdir: str

    @property
    def uri(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    @property
    def file_name(self) -> str:
        return f"{self.key}.json"

    def describe(self) -> str:
        """One line for a person: which flight, since when, and where it is reached."""
        network = " in its private network namespace" if self.netns_pid is not None else ""
        return (
            f"flight {self.key}: `{self.command}`, {self.firmware}, since "
            f"{self.started_at()}; MSP on UART2 at {self.uri}{network}"
        )

    def brief(self) -> str:
        """The key, the command and the start, for a list of flights on one line."""
        return f"{self.key} (`{self.command}`, since {self.started_at()})"

    def started_at(self) -> str:
        return time.strftime("%H:%M:%S", time.localtime(self.started_at_s))

    def to_json(self) -> str:
        return json.dumps({"version": ADVERT_VERSION, **asdict(self)}, indent=1) + "\n"

    @classmethod
    def from_json(cls, text: str) -> FlightAdvert | None:
        """The advert in ``text``, or None when it is not one this version reads."""
        try:
            data = json.loads(text)
            if data.pop("version") != ADVERT_VERSION:
                return None
            advert = cls(**data)
        except (ValueError, TypeError, KeyError, AttributeError):
            return None
        return advert if advert.well_formed() else None

    def well_formed(self) -> bool:
        """Every field of the type and range it must have: a file someone else wrote in the
        cache must not send ``top`` elsewhere than a SITL's loopback, or crash it."""

        def whole(value: object, low: int, high: int) -> bool:
            return type(value) is int and low <= value <= high

        return (
            all(isinstance(v, str) for v in (self.key, self.command, self.firmware, self.workdir))
            and whole(self.pid, 1, 2**22)
            and whole(self.started_ticks, 0, 2**63)
            and self.host in LOOPBACK_HOSTS
            and whole(self.port, 1, 65535)
            and (self.netns_pid is None or whole(self.netns_pid, 1, 2**22))
            and type(self.started_at_s) in (int, float)
            and math.isfinite(self.started_at_s)
        )

    @classmethod
    def for_this_process(
        cls,
        *,
        firmware: str,
        host: str,
        port: int,
        netns_pid: int | None,
        workdir: str,
        start_ticks: StartTicks = process_start_ticks,
        now_s: float | None = None,
    ) -> FlightAdvert:
        """The advert of a flight this process flies."""
        pid = os.getpid()
        number = next(_advertised_here)
        return cls(
            key=str(pid) if number == 1 else f"{pid}.{number}",
            pid=pid,
            started_ticks=start_ticks(pid) or 0,
            command=command_line(),
            firmware=firmware,
            host=host,
            port=port,
            netns_pid=netns_pid,
            started_at_s=time.time() if now_s is None else now_s,
            workdir=workdir,
        )


class FlightRegistry:
    """The adverts in one folder: write one, withdraw it, list those still running.

    Args:
        directory: The folder; None is :func:`flights_dir`.
        start_ticks: Reads a process's start time (None: gone); tests pass a fake.
    """

    def __init__(
        self, directory: Path | None = None, *, start_ticks: StartTicks = process_start_ticks
    ) -> None:
        self.directory = directory if directory is not None else flights_dir()
        self._start_ticks = start_ticks

    def advertise(self, advert: FlightAdvert) -> Path:
        """Write ``advert`` (whole, never half of it); returns its file."""
        path = self.directory / advert.file_name
        write_atomically(path, advert.to_json().encode())
        return path

    def withdraw(self, advert: FlightAdvert) -> None:
        (self.directory / advert.file_name).unlink(missing_ok=True)

    @contextlib.contextmanager
    def advertised(self, advert: FlightAdvert) -> Iterator[Path]:
        """Advertise ``advert`` while the block runs; it is withdrawn however the block ends."""
        path = self.advertise(advert)
        try:
            yield path
        finally:
            self.withdraw(advert)

    def is_running(self, advert: FlightAdvert) -> bool:
        """The advertising process still runs (and is the same process, not a reused pid)."""
        return self._start_ticks(advert.pid) == advert.started_ticks

    def running(self) -> list[FlightAdvert]:
        """The flights running now, oldest first; stale adverts are removed on the way.

        A file that is no advert of this version is left alone while a process with the pid
        of its name runs (a newer bfsitl may have written it) and removed otherwise.
        """
        try:
            paths = sorted(self.directory.glob("*.json"))
        except OSError:
            return []
        found: list[FlightAdvert] = []
        for path in paths:
            try:
                advert = FlightAdvert.from_json(path.read_text())
            except OSError:
                continue  # withdrawn while we looked
            except UnicodeDecodeError:
                advert = None  # not text: no advert
            if advert is not None and self.is_running(advert):
                found.append(advert)
            elif advert is not None or not self._named_pid_runs(path):
                with contextlib.suppress(OSError):  # a cache shared read-only: leave it
                    path.unlink(missing_ok=True)
        return sorted(found, key=lambda advert: (advert.started_at_s, advert.key))

    def _named_pid_runs(self, path: Path) -> bool:
        pid_text = path.stem.split(".", 1)[0]
        return pid_text.isdigit() and self._start_ticks(int(pid_text)) is not None


def choose_flight(flights: Sequence[FlightAdvert], key: str | None) -> FlightAdvert:
    """The flight to attach to: the one with ``key``, or the only one when ``key`` is None.

    Raises:
        AttachError: None runs, none has ``key``, or several run and no key was given (the
            message lists them and says how to choose).
    """
    if key is not None:
        for advert in flights:
            if advert.key == key:
                return advert
    if len(flights) == 1 and key is None:
        return flights[0]
    if not flights:
        raise AttachError(
            f"no running flight{'' if key is None else ' ' + key} to attach to: start one "
            f"with `bfsitl fly` (without --no-attach), or give the FC's address with --uri"
        )
    listing = ", ".join(advert.brief() for advert in flights)
    if key is not None:
        raise AttachError(
            f"no running flight {key}; running now: {listing}. Give one of those keys to --attach"
        )
    raise AttachError(
        f"{len(flights)} flights are running: {listing}. Choose one with "
        f"`bfsitl top --attach {flights[0].key}` (or another of those keys)"
    )
