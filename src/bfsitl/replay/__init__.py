"""``bfsitl log replay``: a real flight's blackbox log flown again through the real firmware.

:func:`~bfsitl.replay.replay_log.replay_log` takes a decoded log (``bfsitl.fit.pick_log``), a
lockstep build and a quad, and returns a :class:`~bfsitl.replay.replay_log.Replay`: the log's
header carried over to the build's settings (:mod:`.header_settings`), its sticks streamed on
simulated time at the real receiver's rate (:mod:`.sticks`, :mod:`.flight`), and the two logs
compared per axis (:mod:`.compare`, :mod:`.step_response`).  docs/log-replay.md says how, and
how well.
"""

from bfsitl.replay.replay_log import Replay, replay_log

__all__ = ["Replay", "replay_log"]
