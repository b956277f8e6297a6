"""The flight controller's own blackbox log: found in a SITL's run directory, copied out and
decoded into typed frames (:mod:`bfsitl.blackbox.decode`), the FC's evidence of what it did.

In SITL, ``blackbox_device = VIRTUAL`` writes the log into the process's working directory
(``blackbox/blackbox_virtual.c``): 4.6.0 names it ``LOG00001.BF`` (a buffer one byte short
truncates the name, so every process starts at 1 again and overwrites it), master
``LOG00001.BFL``, ``LOG00002.BFL``, ... continuing from the highest there.
"""

from bfsitl.blackbox.collect import collect_blackbox, find_blackbox_files
from bfsitl.blackbox.decode import (
    DISARM_REASONS,
    BlackboxFrame,
    BlackboxLog,
    FailsafePhase,
    decode_blackbox,
)

__all__ = [
    "DISARM_REASONS", "BlackboxFrame", "BlackboxLog", "FailsafePhase", "collect_blackbox",
    "decode_blackbox", "find_blackbox_files",
]
