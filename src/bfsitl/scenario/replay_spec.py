"""A real flight as a scenario: ``[replay]`` in a scenario file.

.. code-block:: toml

    description = "my freestyle flight, replayed"
    cli = ["set p_roll = 40"]   # after the log's own settings: the change to try

    [replay]
    log = "flights/LOG00007.BFL"   # relative to this file
    index = 2                      # optional: which log in the file (default: the longest)

    [vehicle]
    model = "my-quad.toml"         # a fitted or shipped profile (default: the 5-inch)

    [expect]
    no_finding = ["crash", "loss_of_control"]
    min_setpoint_correlation = 0.99

The log's sticks are flown again through the firmware with the log's settings carried over
(:mod:`bfsitl.replay`), so ``bfsitl scenario run`` and ``compare`` (and the pytest plugin) can
hold a real flight like any other scenario: what a build or a setting would have done to it.
A replay flies the log's own sticks, so ``[flight]``, ``[[fault]]``, ``[[fc_waypoint]]``,
``duration_s`` and ``settle_s`` do not go with it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bfsitl.errors import ScenarioError

#: The shipped profile a replay flies when the file names none: a replay's log comes from a
#: real quad, and IRIS (the flight scenarios' default) is no quad a Betaflight pilot flies.
DEFAULT_REPLAY_VEHICLE = "5inch-freestyle"
#: Top-level keys that belong to a flown scenario, not a replay.
FLIGHT_ONLY_KEYS = ("flight", "fault", "fc_waypoint", "duration_s", "settle_s")
_KEYS = {"log", "index"}


@dataclass(frozen=True, slots=True)
class ReplaySpec:
    """``[replay]``: the blackbox file and which log in it.

    Attributes:
        log: The blackbox file (made absolute against the scenario file's folder).
        index: Which log in the file (1 is the first); None: the longest.
    """

    log: Path
    index: int | None = None


def read_replay_spec(data: dict[str, Any], *, where: str, source: Path | None) -> ReplaySpec:
    """``data["replay"]`` checked: the file must exist (a typo fails before anything flies),
    and nothing of a flown scenario may come with it."""
    raw = data["replay"]
    if not isinstance(raw, dict):
        raise ScenarioError(f'{where}: [replay] must be a table (log = "FILE", index = N)')
    unknown = set(raw) - _KEYS
    if unknown:
        raise ScenarioError(
            f"{where}: [replay] has unknown key(s) {', '.join(sorted(unknown))}; "
            f"known: {', '.join(sorted(_KEYS))}"
        )
    clashing = [key for key in FLIGHT_ONLY_KEYS if key in data]
    if isinstance(data.get("vehicle"), dict) and "heading_deg" in data["vehicle"]:
        clashing.append("[vehicle] heading_deg")  # the log's own heading is flown
    if clashing:
        raise ScenarioError(
            f"{where}: a [replay] flies the log's own sticks for as long as the log lasts; "
            f"{', '.join(clashing)} cannot go with it"
        )
    log = raw.get("log")
    if not isinstance(log, str) or not log.strip():
        raise ScenarioError(f"{where}: [replay] log must name a blackbox file")
    path = Path(log).expanduser()
    if not path.is_absolute() and source is not None:
        path = source.parent / path
    if not path.is_file():
        raise ScenarioError(f"{where}: [replay] log {log!r}: no such file ({path})")
    index = raw.get("index")
    if index is not None and (isinstance(index, bool) or not isinstance(index, int) or index < 1):
        raise ScenarioError(
            f"{where}: [replay] index = {index!r} must be a whole number from 1 (the first log)"
        )
    return ReplaySpec(path.resolve(), index)
