"""Altitude controllers: RC throttle from the FC's altitude (and accelerometer).

Every controller follows :class:`~bfsitl.control.base.AltitudeController`: ``reset(time_s)``
after arming, then ``update(AltitudeInput) -> throttle_us`` at the mission's rate.

==============  ==============================================================================
name            what it is
==============  ==============================================================================
fused           (default) barometer + accelerometer estimate, reference, PD, hover learnt
cascade         barometer only: spool-up, smooth reference, feedforward, lag-matched cascade
tutorial-pid    the tutorial's single altitude PID, re-created faithfully as the baseline
open-loop       the tutorial's throttle-by-the-clock take-off (no feedback at all)
==============  ==============================================================================

:func:`make_controller` builds one by name with gain overrides (``--gain kp=150`` on the
command line); :func:`gain_names` lists a controller's gains with their defaults.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

from bfsitl.control.base import AltitudeController, AltitudeInput
from bfsitl.control.cascade import CascadedAltitudeController, CascadeGains
from bfsitl.control.fused import FusedAltitudeController, FusedGains
from bfsitl.control.landing import LandingController, LandingGains
from bfsitl.control.metrics import StepMetrics, step_response
from bfsitl.control.tutorial import (
    OpenLoopGains,
    OpenLoopTakeoff,
    TutorialPid,
    TutorialPidGains,
)
from bfsitl.control.vehicle_gains import vehicle_gains
from bfsitl.errors import ControllerConfigError
from bfsitl.physics.params import QuadParams

DEFAULT_CONTROLLER = "fused"

#: Controller name -> class.  Each class takes one optional argument, its gains dataclass
#: (see :data:`GAINS`).
CONTROLLERS: dict[str, type] = {
    "cascade": CascadedAltitudeController,
    "fused": FusedAltitudeController,
    "tutorial-pid": TutorialPid,
    "open-loop": OpenLoopTakeoff,
}

#: Controller name -> its gains dataclass.
GAINS: dict[str, type] = {
    "cascade": CascadeGains,
    "fused": FusedGains,
    "tutorial-pid": TutorialPidGains,
    "open-loop": OpenLoopGains,
}


def _gains_type(name: str) -> type:
    try:
        return GAINS[name]
    except KeyError:
        known = ", ".join(sorted(CONTROLLERS))
        raise ControllerConfigError(
            f"unknown controller {name!r}; choose one of: {known}"
        ) from None


def gain_names(name: str) -> dict[str, float]:
    """The gains of controller ``name`` and their defaults, in declaration order."""
    defaults = _gains_type(name)()
    return {f.name: getattr(defaults, f.name) for f in dataclasses.fields(defaults)}


def make_controller(
    name: str = DEFAULT_CONTROLLER,
    gains: Mapping[str, float] | None = None,
    *,
    quad: QuadParams | None = None,
) -> AltitudeController:
    """Controller ``name`` with its default gains, overridden by ``gains``.

    Args:
        name: ``"fused"`` (the default), ``"cascade"``, ``"tutorial-pid"`` or ``"open-loop"``.
        gains: Gain name to value, for the gains to change (:func:`gain_names` lists a
            controller's gains and their defaults); None keeps every default.
        quad: The vehicle flown: the defaults are carried over to it from IRIS
            (:mod:`bfsitl.control.vehicle_gains`); None (a board) or IRIS keeps them.

    Returns:
        A new controller, ready to be reset at arming.

    Raises:
        ControllerConfigError: An unknown controller, an unknown gain name (the message lists
            the known ones) or a value the controller cannot work with.  Also a
            ``ValueError``.
    """
    gains_type = _gains_type(name)
    overrides = dict(gains or {})
    carried = vehicle_gains(gains_type, quad) if quad is not None else {}
    known = gain_names(name)
    unknown = sorted(set(overrides) - set(known))
    if unknown:
        raise ControllerConfigError(
            f"controller {name!r} has no gain {', '.join(map(repr, unknown))}; its gains are: "
            + ", ".join(known)
        )
    values: dict[str, float] = {}
    for key, value in overrides.items():
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise ControllerConfigError(
                f"gain {key} of {name!r} must be a number, got {value!r}"
            ) from None
        if not math.isfinite(number):
            raise ControllerConfigError(f"gain {key} of {name!r} must be finite, got {value!r}")
        values[key] = number
    return CONTROLLERS[name](gains_type(**(carried | values)))


def make_landing(quad: QuadParams | None = None) -> LandingController:
    """The usual landing controller, its defaults carried over to ``quad`` (None: IRIS's).

    Args:
        quad: The vehicle flown; None (a board) or IRIS keeps the defaults.

    Returns:
        A new landing controller.
    """
    carried = vehicle_gains(LandingGains, quad) if quad is not None else {}
    return LandingController(LandingGains(**carried))


__all__ = [
    "CONTROLLERS",
    "DEFAULT_CONTROLLER",
    "GAINS",
    "AltitudeController",
    "AltitudeInput",
    "CascadeGains",
    "CascadedAltitudeController",
    "ControllerConfigError",
    "FusedAltitudeController",
    "FusedGains",
    "LandingController",
    "LandingGains",
    "OpenLoopGains",
    "OpenLoopTakeoff",
    "StepMetrics",
    "TutorialPid",
    "TutorialPidGains",
    "gain_names",
    "make_controller",
    "make_landing",
    "step_response",
]
