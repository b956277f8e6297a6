"""The flight controller's own blackbox log: found in a SITL's run directory, copied out
(:mod:`bfsitl.blackbox.collect`) and decoded into typed frames and events
(:mod:`bfsitl.blackbox.decode`): the FC's evidence of what it did, on its own clock.

How a SITL writes one (measured on 4.6.0 and master SITL builds):

* ``set blackbox_device = VIRTUAL`` writes the log into the process's working directory, the
  run directory (``[4.6] src/main/blackbox/blackbox_virtual.c:37-58,85-98``).  The setting and
  ``blackbox_sample_rate`` are read once at boot (``blackboxInit``,
  ``[4.6] src/main/blackbox/blackbox.c:2286-2308``, ``[M] src/main/blackbox/blackbox.c:2280-2302``),
  and the firmware does not ask for a reboot when they change: provision them with
  ``Profile(reboot_when_changed=True)``, or no log is written until the next boot;
* ``blackbox_mode = NORMAL`` (the default) opens a log on arming and closes it on disarm with
  a DISARM event (the reason) and LOG_END.  The first frame comes after the header is written,
  about 0.3 s after arming on master (1 kHz loop), 0.1 s on 4.6.0 (8 kHz);
* 4.6.0 names the files ``LOG00001.BF``, ``LOG00002.BF``, ... (a buffer one byte short cuts
  the ``L``); its start-up scan looks for 12-character names only, so every new process
  starts at 1 again and overwrites the last run's files.  Master writes ``LOG00001.BFL``,
  ``LOG00002.BFL``, ... continuing from the highest already there;
* a SITL killed while armed leaves a log without LOG_END, possibly cut inside a frame:
  decoded, it keeps the frames before the cut and says ``truncated``.
"""

from bfsitl.blackbox.collect import collect_blackbox, find_blackbox_files
from bfsitl.blackbox.decode import (
    DISARM_REASONS,
    BlackboxEvent,
    BlackboxFrame,
    BlackboxLog,
    decode_blackbox,
    frames_to_rows,
)

__all__ = [
    "DISARM_REASONS",
    "BlackboxEvent",
    "BlackboxFrame",
    "BlackboxLog",
    "collect_blackbox",
    "decode_blackbox",
    "find_blackbox_files",
    "frames_to_rows",
]
