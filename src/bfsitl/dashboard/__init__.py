"""``bfsitl top``: a live terminal dashboard of a flight controller.

The pure half turns a telemetry snapshot into a view model (:mod:`.view_model`, with the link
figures of :mod:`.link_stats`); :mod:`.render` lays a view model out with Rich; :mod:`.loop`
polls the FC and paces the frames; :mod:`.keys` reads ``q`` from the terminal and
:mod:`.live` puts frames on the screen.  Only :mod:`.render` and :mod:`.live` import Rich (the
``top`` extra), so importing this package does not need it.
"""

from bfsitl.dashboard.link_stats import LinkMeter, LinkStats
from bfsitl.dashboard.loop import DEFAULT_RATE_HZ, DashboardResult, run_dashboard
from bfsitl.dashboard.view_model import (
    BlockerView,
    ChannelView,
    DashboardView,
    FlightView,
    build_view,
    flight_view,
)

__all__ = [
    "DEFAULT_RATE_HZ",
    "BlockerView",
    "ChannelView",
    "DashboardResult",
    "DashboardView",
    "FlightView",
    "LinkMeter",
    "LinkStats",
    "build_view",
    "flight_view",
    "run_dashboard",
]
