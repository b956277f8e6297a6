"""Scenarios: a flight, faults at given times and expectations, as a regression suite.

A scenario file (TOML, :mod:`bfsitl.scenario.spec`) says what to provision, how to fly, which
faults to inject when (:mod:`bfsitl.scenario.faults`) and what must hold
(:mod:`bfsitl.scenario.expectations`); :mod:`bfsitl.scenario.run` flies one,
:mod:`bfsitl.scenario.suite` many side by side, and the results
(:mod:`bfsitl.scenario.result`) become JUnit XML and a report page.
"""
