"""Where a SITL runs: the host's network, or a private network namespace of its own.

The SITL's ports are fixed at compile time and bound with SO_REUSEADDR, so two SITLs on one
network silently share UDP 9003/9004 and corrupt each other.  :class:`IsolatedNetwork` gives
a SITL a namespace of its own (``unshare -rn``, no root needed) and hands the host process
sockets that live inside it; :class:`HostNetwork` is the plain case.  Both offer the same
three things: make a socket, start a process, and the pid whose ``/proc/PID/net`` shows the
namespace (for finding who holds a port).  An :class:`IsolatedNetwork` can also *join* the
namespace of a SITL another bfsitl process started (``join_pid``): that is how ``bfsitl top``
reaches a running flight's second MSP port.
"""

from __future__ import annotations

import json
import os
import select
import shutil
import signal
import socket
import subprocess
import sys
import threading
import weakref
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Protocol

from bfsitl.errors import SitlError
from bfsitl.sitl.timer_slack import timer_slack


class ProcessHandle(Protocol):
    """The part of a process the SITL supervisor needs."""

    pid: int

    def poll(self) -> int | None: ...

    def wait(self, timeout_s: float) -> int | None: ...

    def signal_group(self, signum: int) -> None: ...


class Network(Protocol):
    netns_pid: int | None
    isolated: bool

    def socket(self, family: int, kind: int) -> socket.socket: ...

    def spawn(
        self,
        argv: Sequence[str],
        cwd: Path,
        log_path: Path,
        env: Mapping[str, str] | None = None,
        timer_slack_ns: int | None = None,
    ) -> ProcessHandle: ...

    def close(self) -> None: ...


# --- the host network ----------------------------------------------------------------------


class _PopenHandle:
    def __init__(self, popen: subprocess.Popen[bytes]) -> None:
        self._popen = popen
        self.pid = popen.pid

    def poll(self) -> int | None:
        return self._popen.poll()

    def wait(self, timeout_s: float) -> int | None:
        try:
            return self._popen.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            return None

    def signal_group(self, signum: int) -> None:
        if self._popen.poll() is None:
            try:
                os.killpg(self._popen.pid, signum)
            except ProcessLookupError:
                pass


class HostNetwork:
    """Run in the host's own network namespace (ports shared with everything else)."""

    netns_pid: int | None = None
    isolated = False

    def socket(self, family: int, kind: int) -> socket.socket:
        return socket.socket(family, kind)

    def spawn(
        self,
        argv: Sequence[str],
        cwd: Path,
        log_path: Path,
        env: Mapping[str, str] | None = None,
        timer_slack_ns: int | None = None,
    ) -> ProcessHandle:
        with open(log_path, "ab") as log, timer_slack(timer_slack_ns):
            popen = subprocess.Popen(
                list(argv),
                cwd=cwd,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                env=dict(env) if env is not None else None,
            )
        return _PopenHandle(popen)

    def close(self) -> None:
        pass


# --- a private namespace -------------------------------------------------------------------


class _AgentProcessHandle:
    def __init__(self, network: IsolatedNetwork, pid: int) -> None:
        self._network = network
        self.pid = pid
        self._returncode: int | None = None
        # A pidfd polls readable once the process has ended: a check costs one select() of
        # no time (a mission asks every control step), where /proc costs an open and a read.
        self._pidfd = _open_pidfd(pid)
        self._close_pidfd = weakref.finalize(self, _close_fd, self._pidfd)

    def _ended(self) -> bool:
        if self._pidfd >= 0:
            return bool(select.select([self._pidfd], [], [], 0)[0])
        return not _running(self.pid)

    def poll(self) -> int | None:
        if self._returncode is None and not self._network.closed:
            if not self._ended():
                return None  # the agent round trip (~150 us) only once it has ended
            self._returncode = self._network.call({"op": "poll", "pid": self.pid})["returncode"]
        if self._returncode is not None:
            self._close_pidfd()
        return self._returncode

    def wait(self, timeout_s: float) -> int | None:
        if self._returncode is None and not self._network.closed:
            reply = self._network.call(
                {"op": "wait", "pid": self.pid, "timeout_s": timeout_s}, timeout_s=timeout_s + 5.0
            )
            self._returncode = reply["returncode"]
        return self._returncode

    def signal_group(self, signum: int) -> None:
        if self._returncode is None and not self._network.closed:
            self._network.call({"op": "signal", "pid": self.pid, "signal": signum})


def _open_pidfd(pid: int) -> int:
    """A pidfd for ``pid``, or -1 where there is none (Linux before 5.3, another system) or
    the process is gone already."""
    try:
        return os.pidfd_open(pid)
    except (AttributeError, OSError):
        return -1


def _close_fd(fd: int) -> None:
    if fd >= 0:
        try:
            os.close(fd)
        except OSError:
            pass


def _running(pid: int) -> bool:
    """The process exists and has not ended (a zombie has ended: its parent, the agent, has
    not collected it yet).  ``unshare -rn`` shares the PID namespace, so the agent's child has
    this PID here too."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            state = stat.read().rsplit(b")", 1)[-1].split()[0]
    except (OSError, IndexError):
        return False
    return state not in (b"Z", b"X")


def unshare_available() -> bool:
    return shutil.which("unshare") is not None


def _unshare_command() -> list[str]:
    """Runs the agent in a new user and network namespace."""
    unshare = shutil.which("unshare")
    if unshare is None:
        raise SitlError(
            "isolation needs `unshare` (util-linux): install it (apt-get install "
            "util-linux) or run without isolation"
        )
    return [unshare, "--user", "--map-root-user", "--net", "--"]


def _nsenter_command(join_pid: int) -> list[str]:
    """Runs the agent in the user and network namespaces of process ``join_pid``.  The
    user namespace's root is our own user (``--map-root-user``), so entering it needs no
    privileges; ``--preserve-credentials`` keeps our ids (that namespace denies setgroups)."""
    nsenter = shutil.which("nsenter")
    if nsenter is None:
        raise SitlError(
            "reaching a SITL in its private network namespace needs `nsenter` (util-linux): "
            "install it (apt-get install util-linux)"
        )
    return [
        nsenter,
        "--target",
        str(join_pid),
        "--user",
        "--net",
        "--preserve-credentials",
        "--",
    ]


class IsolatedNetwork:
    """A private network namespace with its own loopback, served by ``netns_agent``.

    Args:
        start_timeout_s: Seconds the agent has to say it is ready.
        join_pid: Join the namespace process ``join_pid`` lives in (another bfsitl's SITL
            namespace, its agent's pid) instead of making a new one.  Closing it then
            ends only this agent, never the SITL.
    """

    isolated = True

    def __init__(self, start_timeout_s: float = 10.0, *, join_pid: int | None = None) -> None:
        launcher = _unshare_command() if join_pid is None else _nsenter_command(join_pid)
        self._lock = threading.Lock()
        self.closed = False
        parent_end, child_end = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._control = parent_end
        src_root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        # The agent imports this package: make sure it can, installed or not.
        env["PYTHONPATH"] = src_root + os.pathsep + env.get("PYTHONPATH", "")
        try:
            self._agent = subprocess.Popen(
                [
                    *launcher,
                    sys.executable,
                    "-m",
                    "bfsitl.sitl.netns_agent",
                    "--control-fd",
                    str(child_end.fileno()),
                ],
                pass_fds=[child_end.fileno()],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                start_new_session=True,
                env=env,
            )
        finally:
            child_end.close()
        try:
            hello = self._receive(start_timeout_s)[0]
        except SitlError as exc:
            stderr = self._agent_stderr()
            self._agent.kill()
            self._agent.wait()
            if join_pid is not None:
                raise SitlError(
                    f"could not enter the network namespace of process {join_pid} with "
                    f"`nsenter`: {stderr or exc}. Is that flight still running, as this user?"
                ) from exc
            raise SitlError(
                f"could not create a network namespace with `unshare -rn`: {stderr or exc}. "
                f"Unprivileged user namespaces may be disabled "
                f"(sysctl kernel.unprivileged_userns_clone=1) or run without isolation."
            ) from exc
        if not hello.get("ok"):
            self._agent.wait()
            raise SitlError(f"network namespace agent failed: {hello.get('error')}")
        #: The agent lives in the namespace; /proc/<netns_pid>/net shows its sockets.
        self.netns_pid: int | None = self._agent.pid

    def _agent_stderr(self) -> str:
        if self._agent.poll() is None or self._agent.stderr is None:
            return ""
        return self._agent.stderr.read().decode(errors="replace").strip()

    def _receive(self, timeout_s: float) -> tuple[dict, list[int]]:
        self._control.settimeout(timeout_s)
        try:
            data, fds, _flags, _addr = socket.recv_fds(self._control, 65536, 4)
        except TimeoutError as exc:
            raise SitlError("network namespace agent did not answer") from exc
        except OSError as exc:
            raise SitlError(f"network namespace agent is gone: {exc}") from exc
        if not data:
            raise SitlError(f"network namespace agent exited: {self._agent_stderr()}")
        return json.loads(data), fds

    def call(self, request: dict, timeout_s: float = 10.0) -> dict:
        reply, fds = self._call_with_fds(request, timeout_s)
        for fd in fds:
            os.close(fd)
        return reply

    def _call_with_fds(self, request: dict, timeout_s: float) -> tuple[dict, list[int]]:
        if self.closed:
            raise SitlError("the network namespace was closed")
        with self._lock:
            try:
                self._control.send(json.dumps(request).encode())
            except OSError as exc:
                raise SitlError(f"network namespace agent is gone: {exc}") from exc
            reply, fds = self._receive(timeout_s)
        if not reply.get("ok"):
            for fd in fds:
                os.close(fd)
            raise SitlError(f"network namespace agent: {reply.get('error')}")
        return reply, fds

    def socket(self, family: int, kind: int) -> socket.socket:
        _reply, fds = self._call_with_fds({"op": "socket", "family": family, "type": kind}, 10.0)
        if len(fds) != 1:
            for fd in fds:
                os.close(fd)
            raise SitlError("network namespace agent sent no socket")
        return socket.socket(fileno=fds[0])

    def spawn(
        self,
        argv: Sequence[str],
        cwd: Path,
        log_path: Path,
        env: Mapping[str, str] | None = None,
        timer_slack_ns: int | None = None,
    ) -> ProcessHandle:
        reply = self.call(
            {
                "op": "spawn",
                "argv": list(argv),
                "cwd": str(cwd),
                "log": str(log_path),
                "env": dict(env) if env is not None else None,
                "timer_slack_ns": timer_slack_ns,
            }
        )
        return _AgentProcessHandle(self, int(reply["pid"]))

    def close(self) -> None:
        """End the namespace: the agent stops every process it started, then exits."""
        if self.closed:
            return
        self.closed = True
        try:
            self._control.close()
        finally:
            try:
                self._agent.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                os.killpg(self._agent.pid, signal.SIGKILL)
                self._agent.wait()
            if self._agent.stderr is not None:
                self._agent.stderr.close()

    def __enter__(self) -> IsolatedNetwork:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()
