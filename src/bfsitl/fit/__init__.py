"""Identify a quad from its blackbox log: ``bfsitl log fit``.

:func:`~bfsitl.fit.fit_log.fit_log` reads a real (or SITL) flight and returns a
:class:`~bfsitl.fit.fit_log.LogFit`: the motors' lag, each axis' control effectiveness, the
thrust-to-weight ratio, a vehicle profile built from them, and the open-loop replay's score on
the part of the flight the fit did not see.  docs/log-fit.md says how, and how well.
"""

from bfsitl.fit.fit_log import LogFit, fit_log, pick_log

__all__ = ["LogFit", "fit_log", "pick_log"]
