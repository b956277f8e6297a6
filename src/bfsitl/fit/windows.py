"""The half-second windows a fit learns from and a replay is scored on.

A window starts at a logged state and runs :data:`WINDOW_S` on: the replay resets the model to
the log at each window's start, so an error cannot grow beyond one window (issue "your quad in
the simulator": "reset to the logged state every 0.5 s").  The fit minimises that same error,
so what it learns is what the score measures.  Fit and score never share a window: the fit
reads the first :data:`TRAIN_SHARE` of the usable flight, the score the rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfsitl.fit.log_data import FlightData

WINDOW_S = 0.5
TRAIN_SHARE = 0.7


@dataclass(frozen=True, slots=True)
class Windows:
    """Start frames of whole windows in the usable flight, and their length in frames."""

    starts: np.ndarray
    length: int

    def __len__(self) -> int:
        return len(self.starts)

    def spans(self, values: np.ndarray) -> np.ndarray:
        """``values`` (..., N) cut into windows: (..., windows, length + 1), from each start."""
        index = self.starts[:, None] + np.arange(self.length + 1)[None, :]
        return values[..., index]

    def changes(self, values: np.ndarray) -> np.ndarray:
        """How far ``values`` moved from each window's start: (..., windows, length)."""
        spans = self.spans(values)
        return spans[..., 1:] - spans[..., :1]


def windows_between(data: FlightData, first: int, end: int) -> Windows:
    """Whole usable windows starting at or after frame ``first`` and ending before ``end``."""
    length = max(2, int(round(WINDOW_S / data.dt_s)))
    usable = data.usable.astype(np.int64)
    counts = np.concatenate([[0], np.cumsum(usable)])
    candidates = np.arange(first, max(first, end - length), length)
    whole = counts[candidates + length + 1] - counts[candidates] == length + 1
    return Windows(candidates[whole], length)


def train_and_test(data: FlightData) -> tuple[Windows, Windows]:
    """The fit's windows (the first :data:`TRAIN_SHARE` of the usable flight) and the
    score's (the rest)."""
    split = data.split_index(TRAIN_SHARE)
    return windows_between(data, 0, split), windows_between(data, split, len(data.time_s))
