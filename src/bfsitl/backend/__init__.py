"""What sits under the flight controller, behind one interface (:mod:`bfsitl.backend.base`).

Layers: ``bfsitl.physics`` (pure physics) < ``bfsitl.sim`` (the exchange with the firmware)
< ``bfsitl.backend`` (a clock, an RC sender, the truth and the disturbances per kind of
backend) < ``bfsitl.mission`` (flights).  :func:`make_backend` is the one place that picks one.
"""

from bfsitl.backend.base import (
    BOARD_IMU,
    SITL_IMU,
    Backend,
    ImuScale,
    RcSender,
    SessionClock,
    SitlBackend,
    Truth,
    WallClock,
)
from bfsitl.backend.disturbances import Disturbances
from bfsitl.backend.factory import make_backend

__all__ = [
    "BOARD_IMU",
    "SITL_IMU",
    "Backend",
    "Disturbances",
    "ImuScale",
    "RcSender",
    "SessionClock",
    "SitlBackend",
    "Truth",
    "WallClock",
    "make_backend",
]
