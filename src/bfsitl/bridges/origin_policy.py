"""Which web pages may open bfsitl's WebSocket servers: the Origin rule they all share.

A WebSocket is not bound by the browser's same-origin policy: any page a user has open can
open ``ws://127.0.0.1:6761``.  Without a check, a page in another tab could drive the FC through
the Configurator bridge (send CLI commands and ``save`` them: cross-site WebSocket hijacking)
or read the flight from the Foxglove server.  Browsers always send the page's origin in the
``Origin`` header and a page cannot forge it, so the servers accept:

* no ``Origin`` at all: not a browser (websocat, a Python script), so not a page in a tab;
* the Configurator's own origins: its hosted app (``https://app.betaflight.com`` and the
  preview sites under it), a local web build on ``localhost``/``127.0.0.1``/``[::1]`` on any
  port, its desktop app (Tauri: ``tauri://localhost`` or ``http(s)://tauri.localhost``; the
  older NW.js one is a ``chrome-extension://`` page) and its mobile app (Capacitor:
  ``capacitor://localhost``, ``https://localhost``);
* Foxglove's hosted app (``https://app.foxglove.dev``), for the Foxglove server;
* whatever the user names with ``--allow-origin`` (an exact origin, or ``*`` for any).

Everything else is refused with close code 1008 (policy violation) and a reason that says how
to allow it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from urllib.parse import urlsplit

from bfsitl.errors import BridgeError

#: RFC 6455 close code for "the message (here: the handshake) violates the server's policy".
CLOSE_POLICY_VIOLATION = 1008

#: Exact origins the Configurator and Foxglove apps use (scheme://host[:port], lower case).
KNOWN_APP_ORIGINS: frozenset[str] = frozenset(
    {
        "https://app.betaflight.com",
        "tauri://localhost",
        "http://tauri.localhost",
        "https://tauri.localhost",
        "capacitor://localhost",
        "https://app.foxglove.dev",
    }
)
#: Hosts whose pages, on any port over http or https, are the user's own machine.
LOOPBACK_HOSTS: frozenset[str] = frozenset({"localhost", "127.0.0.1", "::1"})
#: Sub-sites of the hosted Configurator (e.g. master.app.betaflight.com, pull-request previews).
_HOSTED_SUFFIX = ".app.betaflight.com"


def normalise_origin(text: str) -> str:
    """``scheme://host[:port]`` in lower case, the form browsers send; raises on anything else.

    Used for ``--allow-origin`` values, so a typo is an error at start, not a silent refusal
    of the page the user meant.
    """
    value = text.strip().rstrip("/").lower()
    if value == "*":
        return value
    parts = urlsplit(value)
    if not parts.scheme or not parts.netloc or parts.path or parts.query or parts.fragment:
        raise BridgeError(
            f"--allow-origin {text!r}: give an origin as a browser sends it, "
            f"scheme://host[:port] with no path (e.g. https://example.org:8443), or '*'"
        )
    return f"{parts.scheme}://{parts.netloc}"


@dataclass(frozen=True, slots=True)
class OriginPolicy:
    """The rule above; ``allowed`` adds exact origins (``"*"`` allows every origin)."""

    allowed: frozenset[str] = frozenset()

    @classmethod
    def with_extra(cls, origins: Iterable[str] = ()) -> OriginPolicy:
        """A policy that also accepts ``origins`` (checked and normalised)."""
        return cls(frozenset(normalise_origin(origin) for origin in origins))

    def refusal(self, origin: str | None) -> str | None:
        """Why a client with this ``Origin`` header is refused, or None when it is accepted.

        The reason is a close reason: at most 123 UTF-8 bytes.
        """
        if origin is None or "*" in self.allowed:
            return None
        value = origin.strip().lower()
        if value in self.allowed or value in KNOWN_APP_ORIGINS:
            return None
        parts = urlsplit(value)
        host = parts.hostname or ""
        if parts.scheme in ("http", "https") and (
            host in LOOPBACK_HOSTS or host.endswith(_HOSTED_SUFFIX)
        ):
            return None
        if parts.scheme == "chrome-extension":  # the NW.js desktop Configurator
            return None
        reason = f"origin {origin.strip()[:60]} not allowed; start bfsitl with --allow-origin"
        return reason.encode("utf-8")[:123].decode("utf-8", "ignore")

    def accepts(self, origin: str | None) -> bool:
        return self.refusal(origin) is None

    def describe(self) -> str:
        """One line for help text and logs."""
        extra = ", ".join(sorted(self.allowed)) if self.allowed else "none"
        return (
            "the Configurator's and Foxglove's apps, pages on localhost/127.0.0.1, clients "
            f"without an Origin (scripts); also allowed: {extra}"
        )
