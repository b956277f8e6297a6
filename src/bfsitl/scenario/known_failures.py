"""Known firmware defects a scenario flies into on purpose: ``[[known_failure]]``.

A scenario that pins a firmware bug (master's LAND leg that aims 200 m below the quad) should
not read as a healthy pass.  Like pytest's strict ``xfail``:

* the defect happens (its analyser finds it) and every expectation is met: the run is a
  **known failure**, shown as such (yellow), with why and where it is written up;
* it does not happen: the run **fails**, saying so: the defect may be fixed, and the
  scenario should say so too;
* another expectation fails: the run fails as any would.

.. code-block:: toml

    [[known_failure]]
    finding = "crash"                 # the analyser that finds it
    generation = "master"             # optional: "4.6" or "master" (default: every build)
    why = "master's LAND leg aims 200 m below the quad"
    see = "docs/firmware-findings.md, finding 1"
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from bfsitl.analysis import ANALYSERS, Finding
from bfsitl.errors import ScenarioError
from bfsitl.scenario.result import CheckResult

#: ``generation`` values: the firmware generations (bfsitl.protocol.firmware_profile).
GENERATIONS = ("4.6", "master")
_KEYS = {"finding", "generation", "why", "see"}


@dataclass(frozen=True, slots=True)
class KnownFailure:
    """A firmware defect the scenario expects to see.

    Attributes:
        finding: The analyser that finds it (``crash``, ``hard_landing``...).
        why: The defect in a line.
        generation: The firmware generation it belongs to; None: every build.
        see: Where it is written up.
    """

    finding: str
    why: str
    generation: str | None = None
    see: str = ""

    def applies_to(self, generation: str) -> bool:
        return self.generation is None or self.generation == generation


def read_known_failures(raw: Any, where: str) -> tuple[KnownFailure, ...]:
    """``[[known_failure]]`` tables, checked; one clear error per mistake."""
    if not isinstance(raw, list) or not all(isinstance(entry, dict) for entry in raw):
        raise ScenarioError(f"{where}: known failures are written as [[known_failure]] tables")
    names = {a.name for a in ANALYSERS}
    out = []
    for number, entry in enumerate(raw, 1):
        here = f"{where}, known_failure {number}"
        unknown = sorted(set(entry) - _KEYS)
        if unknown:
            raise ScenarioError(
                f"{here}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_KEYS))}"
            )
        finding = entry.get("finding")
        if finding not in names:
            raise ScenarioError(
                f"{here}: finding = {finding!r} is no analyser; one of {', '.join(sorted(names))}"
            )
        why = entry.get("why")
        if not isinstance(why, str) or not why.strip():
            raise ScenarioError(f'{here}: why = "..." says what the defect is (missing)')
        generation = entry.get("generation")
        if generation is not None and generation not in GENERATIONS:
            raise ScenarioError(
                f"{here}: generation = {generation!r}; one of {', '.join(GENERATIONS)}"
            )
        see = entry.get("see", "")
        if not isinstance(see, str):
            raise ScenarioError(f"{here}: see must be text (where the defect is written up)")
        out.append(KnownFailure(finding, why.strip(), generation, see.strip()))
    return tuple(out)


def judge_known(
    known: Sequence[KnownFailure], generation: str, findings: Sequence[Finding]
) -> tuple[list[CheckResult], list[KnownFailure]]:
    """One check per known failure of this generation (met when its analyser found it), and
    those that happened."""
    checks, happened = [], []
    for entry in known:
        if not entry.applies_to(generation):
            continue
        found = next((f for f in findings if f.analyser == entry.finding), None)
        shown = f"known_failure = {entry.finding!r}"
        if found is None:
            checks.append(
                CheckResult(
                    shown,
                    False,
                    f"{shown}: the known failure did not happen ({entry.finding} found nothing)"
                    f": fixed? then the scenario should no longer declare it ({entry.why})",
                )
            )
            continue
        happened.append(entry)
        checks.append(
            CheckResult(
                shown,
                True,
                f"{shown}: {entry.finding} found {found.severity.label}: {found.summary}",
                found.severity.label,
                found.time_s,
            )
        )
    return checks, happened


def known_reason(happened: Sequence[KnownFailure]) -> str:
    """The reason line of a known failure: what the defect is and where it is written up."""
    first = happened[0]
    see = f" ({first.see})" if first.see else ""
    more = f" and {len(happened) - 1} more" if len(happened) > 1 else ""
    return f"known failure: {first.why}{see}{more}"
