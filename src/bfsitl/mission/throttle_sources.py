"""Throttle sources that stand in for an altitude controller in one manoeuvre: a fixed stick
for the firmware's own modes, idle on the ground while the controller only watches."""

from __future__ import annotations

from bfsitl.control.base import (
    THROTTLE_MIN_US,
    AltitudeController,
    AltitudeInput,
    ObservesGround,
)


class FixedThrottle:
    """One throttle, whatever the altitude: the stick a firmware mode reads."""

    def __init__(self, throttle_us: float) -> None:
        self.name = "fixed throttle"
        self.throttle_us = throttle_us

    def reset(self, time_s: float) -> None:
        pass

    def update(self, sample: AltitudeInput) -> float:
        return self.throttle_us


class GroundObserver:
    """Idle throttle on the ground; the samples go to the controller's ``observe_ground``
    when it has one (an altitude controller's ``update`` would spool up or wind up)."""

    def __init__(self, controller: AltitudeController) -> None:
        self.name = getattr(controller, "name", "controller")
        self._observe = (
            controller.observe_ground if isinstance(controller, ObservesGround) else None
        )

    def reset(self, time_s: float) -> None:
        pass

    def update(self, sample: AltitudeInput) -> float:
        if self._observe is not None:
            self._observe(sample)
        return THROTTLE_MIN_US
