"""How a scenario file's numbers are checked: one rule and one message for every table."""

from __future__ import annotations

import math
from typing import Any

from bfsitl.errors import ScenarioError


def number_in(where: str, key: str, value: Any, low: float, high: float) -> float:
    """``value`` as a float when it is a finite number in ``low..high`` (not a bool); else a
    :class:`ScenarioError` naming the place, the key and the range."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or not low <= value <= high
    ):
        raise ScenarioError(f"{where}: {key} = {value!r} must be a number in {low:g}..{high:g}")
    return float(value)
