"""Telling a SITL that is still booting from one whose MSP port will never serve.

4.6.0 SITL runs its TCP servers on the ``dyad`` library, which is not thread-safe, from two
threads: ``systemInit()`` starts ``tcpThread``, which loops ``dyad_update()`` (every pass
begins with ``destroyClosedStreams()``, every 10 ms when idle), while the main thread goes on
to ``serialInit()``, where ``tcpReconfigure()`` calls ``dyad_newStream()`` (a stream born in
state CLOSED, already in the shared list) and then ``dyad_listenEx()`` (``getaddrinfo``,
``socket``, ``bind``, ``listen``, and only then state LISTENING).  If an update pass lands in
that window it frees the half-made stream:

- before the socket exists, the main thread goes on writing into freed memory: the port ends
  up LISTENING in the kernel, but no thread ever accepts, so connections pile up in the
  accept queue and MSP never answers;
- after it, the socket is closed under the main thread and the log says
  ``bind port 5761 for UART1 failed!!``.

Either way the process will never serve MSP.  Seen in 4 of ~230 starts on a loaded 2-core
machine; without this check each cost the whole ready timeout (10 s) before the retry.
"""

from __future__ import annotations

import re
from pathlib import Path

from bfsitl.errors import SitlTcpServerLostError
from bfsitl.sitl.ports import TCP_LISTEN_STATE, read_proc_net

#: A live dyad thread accepts within one 10 ms update; a starved one on a busy machine can
#: take longer, but not this long.
ACCEPT_STALL_S = 1.0


class TcpServerCheck:
    """Watches one SITL launch: its log (from ``log_offset``) and its MSP port's accept queue.

    :meth:`check` is called between readiness probes and raises
    :class:`SitlTcpServerLostError` once either symptom above is certain.
    """

    def __init__(
        self,
        *,
        log_path: Path,
        log_offset: int,
        netns_pid: int | None,
        port: int,
        stall_s: float = ACCEPT_STALL_S,
    ) -> None:
        self.log_path = log_path
        self.log_offset = log_offset
        self.netns_pid = netns_pid
        self.port = port
        self.stall_s = stall_s
        self._queued_since_s: float | None = None

    def check(self, now_s: float) -> None:
        if self._bind_failed():
            raise SitlTcpServerLostError(
                f"the SITL could not open TCP {self.port} (its log says the bind failed): "
                f"the SITL's TCP thread freed the port's server while the main thread was "
                f"creating it (a race at boot), or another process holds the port"
            )
        if self.accept_queue() > 0:
            if self._queued_since_s is None:
                self._queued_since_s = now_s
            elif now_s - self._queued_since_s >= self.stall_s:
                raise SitlTcpServerLostError(
                    f"the SITL listens on TCP {self.port} but has accepted no connection in "
                    f"{self.stall_s:g} s: the SITL's TCP thread (4.6.0 and master) lost the "
                    f"port's server at boot "
                    f"(a race), so it will never answer MSP"
                )
        else:
            self._queued_since_s = None

    def _bind_failed(self) -> bool:
        try:
            with open(self.log_path, "rb") as log:
                log.seek(self.log_offset)
                text = log.read().decode(errors="replace")
        except OSError:
            return False
        return re.search(rf"^bind port {self.port} for UART\d+ failed", text, re.M) is not None

    def accept_queue(self) -> int:
        """Connections waiting to be accepted on the port (0 when nothing listens)."""
        try:
            sockets = read_proc_net(self.netns_pid)
        except ProcessLookupError:
            return 0  # the namespace is gone: the process check reports that
        return max(
            (
                s.rx_queue
                for s in sockets
                if s.protocol == "tcp" and s.port == self.port and s.state == TCP_LISTEN_STATE
            ),
            default=0,
        )
