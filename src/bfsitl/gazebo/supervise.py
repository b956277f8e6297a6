"""Watching a started Gazebo server: is the plugin up yet, and stopping it cleanly.

The only outside sign that the BetaflightPlugin has loaded is its motor socket: it binds UDP
9002 in ``Configure``, after the world and its sensors were created.  The SITL should start
only then, so the servo_packet it sends while booting (the plugin's cue to go online, see
docs/firmware-facts.md#gazebo-plugin) is received.  The socket is seen in
``/proc/<pid>/net/udp`` of any process in the namespace (:mod:`bfsitl.sitl.ports`).
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from pathlib import Path

from bfsitl.errors import GazeboStartError
from bfsitl.gazebo.install_hints import DOCS
from bfsitl.sitl.network import Network, ProcessHandle
from bfsitl.sitl.ports import PROC_ROOT, check_ports_free, read_proc_net

#: UDP port the plugin binds for servo packets (``fdm_port_in`` in the world).
PLUGIN_MOTOR_PORT = 9002
#: Loading the world and the plugin takes a few seconds; the first run of a machine longer.
DEFAULT_START_TIMEOUT_S = 60.0
#: Time gz gets to shut down after SIGINT (and after SIGTERM) before the next signal.
DEFAULT_STOP_GRACE_S = 5.0


def check_plugin_port_free(network: Network, port: int = PLUGIN_MOTOR_PORT) -> None:
    """Raise :class:`~bfsitl.errors.PortInUseError` (naming the holder) if ``port`` is taken.

    Call it before spawning Gazebo: the plugin cannot bind a taken port, and
    :func:`wait_for_plugin` would take the other holder's socket for the plugin's.
    """
    check_ports_free((), (port,), netns_pid=network.netns_pid)


def plugin_listening(
    netns_pid: int | None, port: int = PLUGIN_MOTOR_PORT, *, proc_root: Path = PROC_ROOT
) -> bool:
    """Whether a UDP socket is bound to ``port`` in the namespace of ``netns_pid``."""
    return any(
        sock.protocol == "udp" and sock.port == port
        for sock in read_proc_net(netns_pid, proc_root=proc_root)
    )


def wait_for_plugin(
    network: Network,
    gazebo: ProcessHandle,
    *,
    port: int = PLUGIN_MOTOR_PORT,
    timeout_s: float = DEFAULT_START_TIMEOUT_S,
    poll_s: float = 0.1,
    proc_root: Path = PROC_ROOT,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> None:
    """Return once the plugin's motor port is bound; raise :class:`GazeboStartError` when gz
    exits first or ``timeout_s`` passes (the gz log then says why)."""
    deadline_s = clock() + timeout_s
    while True:
        if plugin_listening(network.netns_pid, port, proc_root=proc_root):
            return
        code = gazebo.poll()
        if code is not None:
            raise GazeboStartError(
                f"gz sim exited with code {code} before the BetaflightPlugin bound UDP {port}; "
                f"see its log (a missing plugin or model, or a world error). {DOCS} lists "
                f"the usual causes."
            )
        if clock() >= deadline_s:
            raise GazeboStartError(
                f"gz sim runs but nothing bound UDP {port} within {timeout_s:g} s: the "
                f"BetaflightPlugin did not load (check GZ_SIM_SYSTEM_PLUGIN_PATH and the gz "
                f"log for 'Failed to load system plugin'), or another world is running"
            )
        sleep(poll_s)


def stop_gazebo(gazebo: ProcessHandle, *, grace_s: float = DEFAULT_STOP_GRACE_S) -> int | None:
    """SIGINT (gz's own clean shutdown), then SIGTERM, then SIGKILL; the exit code if known."""
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        if gazebo.poll() is not None:
            break
        gazebo.signal_group(signum)
        gazebo.wait(grace_s)
    return gazebo.poll()
