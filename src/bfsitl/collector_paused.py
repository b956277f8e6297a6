"""Python's cyclic garbage collector held off while a function builds many small objects.

Decoding a blackbox log or turning one into a track makes hundreds of thousands of tuples
and dataclasses, none of them in a reference cycle.  Every few hundred allocations the
collector runs, and every so often it walks every object alive (the whole decoded log
included): on a 60,000-frame log that walk is about a third of building its track.  Objects
are still freed as soon as nothing refers to them; only cycles wait for the collector, and
it runs again as before once the block ends.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_paused() -> Iterator[None]:
    """Hold the cyclic collector off inside the block; it is left as it was found (a block
    inside another, or a caller that had turned it off, keeps it off)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
