"""Runs inside a private network namespace for :class:`bfsitl.sitl.network.IsolatedNetwork`.

Started as ``unshare -rn -- python -m bfsitl.sitl.netns_agent --control-fd N`` (or through
``nsenter`` into an existing one, for ``bfsitl top`` attaching to a flight).  It brings the
loopback interface up, then serves requests from its parent over a SOCK_SEQPACKET socket pair:

* ``socket``: make a socket *here* and pass its descriptor back (SCM_RIGHTS).  A socket keeps
  the namespace it was created in, so the parent can connect or bind it and talk to the
  isolated SITL while living in the host namespace itself.
* ``spawn`` / ``poll`` / ``signal`` / ``wait``: run processes (the SITL) inside the namespace.

When the parent goes away (EOF on the control socket, whatever the reason: exit, crash,
SIGKILL) the agent terminates everything it started and exits: nothing is left behind.
Requests and replies are single JSON datagrams.
"""

from __future__ import annotations

import argparse
import fcntl
import json
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable

from bfsitl.sitl.timer_slack import timer_slack
from bfsitl.stop_signals import die_with_parent

_SIOCGIFFLAGS = 0x8913
_SIOCSIFFLAGS = 0x8914
_IFF_UP = 0x1
_MAX_MESSAGE = 65536
#: How often an idle agent reaps children that exited: a SITL ends itself on every reboot, and
#: until someone waits for it, it lingers as a zombie under the agent.
REAP_INTERVAL_S = 0.2


def _die_with_agent(agent_pid: int) -> Callable[[], None]:
    """In the child between fork and exec: the kernel kills it when the agent ends, however
    the agent ends.  The agent cleans up after itself when its owner goes (EOF on the control
    socket), but a SIGKILL of the agent itself (a Ray worker cancelled with its processes, a
    killed container) must not leave the SITL running without a parent."""

    def arm() -> None:
        die_with_parent(agent_pid, signal.SIGKILL)

    return arm


def bring_loopback_up() -> None:
    """``ip link set lo up`` without needing iproute2: one ioctl on the interface flags.  A
    loopback that is up already (an agent that joined another's namespace) is left alone."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack("16sh22x", b"lo", 0)
        flags = struct.unpack("16sh22x", fcntl.ioctl(sock, _SIOCGIFFLAGS, request))[1]
        if flags & _IFF_UP:
            return
        fcntl.ioctl(sock, _SIOCSIFFLAGS, struct.pack("16sh22x", b"lo", flags | _IFF_UP))


class Agent:
    def __init__(self, control: socket.socket) -> None:
        self.control = control
        self.children: dict[int, subprocess.Popen[bytes]] = {}

    def serve(self) -> None:
        while True:
            readable, _, _ = select.select([self.control], [], [], REAP_INTERVAL_S)
            if not readable:
                self.reap()
                continue
            try:
                data = self.control.recv(_MAX_MESSAGE)
            except ConnectionResetError:
                data = b""
            if not data:
                return
            fds: list[int] = []
            try:
                request = json.loads(data)
                reply = self.handle(request, fds)
            except Exception as exc:  # noqa: BLE001 - every failure goes back as a reply
                reply = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
            payload = json.dumps(reply).encode()
            try:
                if fds:
                    socket.send_fds(self.control, [payload], fds)
                else:
                    self.control.send(payload)
            finally:
                for fd in fds:
                    os.close(fd)

    def handle(self, request: dict, fds: list[int]) -> dict:
        op = request.get("op")
        if op == "ping":
            return {"ok": True, "pid": os.getpid()}
        if op == "socket":
            sock = socket.socket(int(request["family"]), int(request["type"]))
            fds.append(sock.detach())
            return {"ok": True}
        if op == "spawn":
            slack_ns = request.get("timer_slack_ns")
            log = open(request["log"], "ab")  # noqa: SIM115 - handed to the child
            try:
                with timer_slack(None if slack_ns is None else int(slack_ns)):
                    child = subprocess.Popen(
                        request["argv"],
                        cwd=request["cwd"],
                        stdin=subprocess.DEVNULL,
                        stdout=log,
                        stderr=subprocess.STDOUT,
                        start_new_session=True,
                        env=request.get("env") or None,
                        preexec_fn=_die_with_agent(os.getpid()),  # noqa: PLW1509 - one thread
                    )
            finally:
                log.close()
            self.children[child.pid] = child
            return {"ok": True, "pid": child.pid}
        known = self.children.get(int(request.get("pid", -1)))
        if known is None:
            return {"ok": False, "error": f"no child with pid {request.get('pid')}"}
        child = known
        if op == "poll":
            return {"ok": True, "returncode": child.poll()}
        if op == "wait":
            try:
                code = child.wait(timeout=float(request.get("timeout_s", 0)))
            except subprocess.TimeoutExpired:
                code = None
            return {"ok": True, "returncode": code}
        if op == "signal":
            if child.poll() is None:
                try:
                    os.killpg(child.pid, int(request["signal"]))
                except ProcessLookupError:
                    pass
            return {"ok": True, "returncode": child.poll()}
        return {"ok": False, "error": f"unknown op {op!r}"}

    def reap(self) -> None:
        """Collect children that have exited; Popen keeps their exit codes for ``poll``."""
        for child in self.children.values():
            child.poll()

    def shutdown(self) -> None:
        for child in self.children.values():
            if child.poll() is None:
                try:
                    os.killpg(child.pid, signal.SIGTERM)
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + 3.0
        for child in self.children.values():
            try:
                child.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(child.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                child.wait()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--control-fd", type=int, required=True)
    args = parser.parse_args(argv)
    control = socket.socket(fileno=args.control_fd)
    # The parent's Ctrl-C reaches this process group too; the parent decides when to stop.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    try:
        bring_loopback_up()
    except OSError as exc:
        control.send(json.dumps({"ok": False, "error": f"cannot bring lo up: {exc}"}).encode())
        return 1
    control.send(json.dumps({"ok": True, "pid": os.getpid()}).encode())
    agent = Agent(control)
    try:
        agent.serve()
    finally:
        agent.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
