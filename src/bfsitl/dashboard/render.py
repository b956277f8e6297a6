"""View model -> Rich renderable: the layout of ``bfsitl top``.

Why Rich (and not Textual): the dashboard is a read-only view redrawn a few times a second,
with one key (q) to quit.  Rich draws exactly that (``Live`` on the alternate screen) from
plain renderables, needs only ``markdown-it-py`` and ``pygments`` besides itself, starts in a
fraction of the time Textual's asyncio application does, and renders the same frame into a
``Console(record=True)`` for tests and for ``--once`` output.  Textual would bring widgets,
focus, CSS and an event loop that a single-key view does not use, and would make the
synchronous MSP client run inside asyncio.  Rich is imported by this module only, so the rest
of bfsitl works without it.

Every string coming from the FC or the arming table goes in as :class:`rich.text.Text`, never
as markup, so a ``[`` in a message can not be taken for a style tag.
"""

from __future__ import annotations

import io

from rich import box
from rich.console import Console, Group, RenderableType
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from bfsitl.dashboard.link_stats import LinkStats
from bfsitl.dashboard.view_model import ChannelView, DashboardView, FlightView

#: Characters of a motor bar and of an RC channel bar.
MOTOR_BAR_WIDTH = 12
RC_BAR_WIDTH = 8
#: RC channels per column in the RC panel (10 channels: two columns of five).
RC_ROWS = 5
#: Default width of text renders (tests, ``--once`` into a pipe).
TEXT_WIDTH = 120


def _bar(fill: float, width: int) -> Text:
    full = round(fill * width)
    return Text("█" * full, style="cyan") + Text("·" * (width - full), style="dim")


def _channels_table(channels: tuple[ChannelView, ...], bar_width: int, rows: int) -> Table:
    """Channels in columns of ``rows`` entries, each entry label, value and bar."""
    columns = max(1, -(-len(channels) // rows))
    table = Table.grid(padding=(0, 1))
    for _ in range(columns):
        table.add_column(no_wrap=True)
        table.add_column(justify="right", no_wrap=True)
        table.add_column(no_wrap=True)
    for row in range(min(rows, len(channels))):
        cells: list[RenderableType] = []
        for column in range(columns):
            index = column * rows + row
            if index < len(channels):
                channel = channels[index]
                cells += [
                    Text(channel.label),
                    Text(str(channel.value_us)),
                    _bar(channel.fill, bar_width),
                ]
            else:
                cells += [Text(""), Text(""), Text("")]
        table.add_row(*cells)
    return table


def _pairs(rows: list[tuple[str, str]], columns: int = 1) -> Table:
    """Name/value pairs, ``columns`` pairs side by side."""
    table = Table.grid(padding=(0, 1))
    for _ in range(columns):
        table.add_column(style="bold", no_wrap=True)
        table.add_column(no_wrap=columns > 1)
    for start in range(0, len(rows), columns):
        cells: list[RenderableType] = []
        for name, value in rows[start : start + columns]:
            cells += [Text(name), Text(value)]
        cells += [Text("")] * (2 * columns - len(cells))
        table.add_row(*cells)
    return table


def _fmt_ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} ms"


def _link_panel(link: LinkStats) -> Panel:
    rows = [
        ("rate", f"{link.updates_per_s:.1f} updates/s"),
        ("polls", f"{link.updates} answered, {link.errors} failed"),
        (
            "MSP round trip",
            f"{_fmt_ms(link.rtt_last_ms)} (mean {_fmt_ms(link.rtt_mean_ms)}, "
            f"max {_fmt_ms(link.rtt_max_ms)})",
        ),
        ("last reply", "none yet" if link.age_s is None else f"{link.age_s:.1f} s ago"),
    ]
    if link.last_error:
        rows.append(("last error", link.last_error))
    return Panel(_pairs(rows), title="link", box=box.ROUNDED)


def _state_panel(flight: FlightView) -> Panel:
    return Panel(
        _pairs(
            [
                ("roll", f"{flight.roll_deg:+.1f}°"),
                ("altitude", f"{flight.altitude_m:+.2f} m"),
                ("pitch", f"{flight.pitch_deg:+.1f}°"),
                ("vario", f"{flight.vario_m_s:+.2f} m/s"),
                ("heading", f"{flight.heading_deg:d}°"),
                ("battery", f"{flight.battery_v:.2f} V"),
                ("PID loop", f"{flight.cycle_time_us} us"),
                ("CPU", f"{flight.cpu_load_percent} %"),
            ],
            columns=2,
        ),
        title="attitude, baro altitude",
        subtitle="pitch + = nose down",
        box=box.ROUNDED,
    )


def _arming_panel(flight: FlightView) -> Panel:
    if flight.armed:
        body: RenderableType = Text("ARMED", style="bold red")
    elif not flight.blockers:
        body = Text("nothing blocks arming", style="green")
    else:
        table = Table(box=None, expand=True, pad_edge=False, show_edge=False)
        table.add_column("flag", style="bold yellow", no_wrap=True)
        table.add_column("meaning", ratio=1)
        table.add_column("fix", ratio=1)
        for blocker in flight.blockers:
            table.add_row(Text(blocker.name), Text(blocker.meaning), Text(blocker.fix))
        body = table
    count = len(flight.blockers)
    title = "arming" if flight.armed or not count else f"arming blocked by {count} flag(s)"
    return Panel(body, title=title, box=box.ROUNDED)


def _side_by_side(*panels: RenderableType, ratios: tuple[int, ...] | None = None) -> Table:
    grid = Table.grid(expand=True, padding=(0, 1))
    for ratio in ratios or (1,) * len(panels):
        grid.add_column(ratio=ratio)
    grid.add_row(*panels)
    return grid


def _header(view: DashboardView) -> Text:
    header = Text("bfsitl top", style="bold") + Text(f"  {view.target}  ")
    if view.flight is None:
        header += Text("waiting for telemetry", style="yellow")
    elif view.flight.armed:
        header += Text("ARMED", style="bold red")
    else:
        header += Text("disarmed", style="green")
    if view.stale:
        header += Text("  STALE (no reply)", style="bold red")
    header += Text(f"  polling at {view.rate_hz:g} Hz   q quits", style="dim")
    return header


def render_dashboard(view: DashboardView) -> RenderableType:
    """One frame: header; state and link; arming blockers; motors and RC; flight modes.

    Arming comes before the bars because it is what a user acts on, and a short terminal
    crops the bottom of the frame first.
    """
    parts: list[RenderableType] = [_header(view)]
    flight = view.flight
    if flight is None:
        parts.append(
            _side_by_side(
                Panel(
                    Text(f"no telemetry yet from {view.target}"),
                    title="flight controller",
                    box=box.ROUNDED,
                ),
                _link_panel(view.link),
            )
        )
        return Group(*parts)
    parts.append(_side_by_side(_state_panel(flight), _link_panel(view.link)))
    parts.append(_arming_panel(flight))
    parts.append(
        _side_by_side(
            Panel(
                _channels_table(flight.motors, MOTOR_BAR_WIDTH, rows=4),
                title="motors (us)",
                box=box.ROUNDED,
            ),
            Panel(
                _channels_table(flight.rc, RC_BAR_WIDTH, rows=RC_ROWS),
                title="RC channels (us)",
                box=box.ROUNDED,
            ),
            ratios=(2, 3),
        )
    )
    modes = ", ".join(flight.flight_modes) if flight.flight_modes else "none active"
    parts.append(Text("flight modes: ", style="bold") + Text(modes))
    return Group(*parts)


def render_text(view: DashboardView, width: int = TEXT_WIDTH) -> str:
    """The frame as plain text (no colour codes), as a terminal of ``width`` columns shows it."""
    console = Console(
        record=True,
        width=width,
        file=io.StringIO(),
        color_system=None,
        force_terminal=False,
        legacy_windows=False,
    )
    console.print(render_dashboard(view))
    return console.export_text()
