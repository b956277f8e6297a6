"""Where frames go: a live full-screen view on a terminal, or printed once.

``LiveScreen`` draws on the terminal's alternate screen, like ``top``: the shell's scrollback
is left as it was when the dashboard quits.  Refreshing is driven by the loop
(``auto_refresh=False``), so Rich starts no thread of its own and a frame appears exactly
when its data arrived.
"""

from __future__ import annotations

from rich.console import Console
from rich.live import Live

from bfsitl.dashboard.render import render_dashboard
from bfsitl.dashboard.view_model import DashboardView


class LiveScreen:
    """A context manager whose :meth:`show` replaces the frame on screen."""

    def __init__(self, console: Console | None = None, *, alternate_screen: bool = True) -> None:
        self.console = console or Console()
        self._live = Live(
            console=self.console,
            auto_refresh=False,
            screen=alternate_screen,
            transient=not alternate_screen,
            redirect_stdout=False,
            redirect_stderr=False,
        )

    def __enter__(self) -> LiveScreen:
        self._live.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._live.stop()

    def show(self, view: DashboardView) -> None:
        self._live.update(render_dashboard(view), refresh=True)


class PrintOnce:
    """Print frames to a console as they come (``--once`` shows exactly one)."""

    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console()
        self.frames = 0

    def show(self, view: DashboardView) -> None:
        self.console.print(render_dashboard(view))
        self.frames += 1
