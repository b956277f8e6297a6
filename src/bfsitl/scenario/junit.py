"""A run's results as JUnit XML, written with ``junitparser`` (the registry's JUnit library).

One ``<testsuite>`` per firmware, one ``<testcase>`` per scenario: a failed run is a
``<failure>`` whose message is its reason (the first failed check) and whose text lists every
check, the analysers' findings and the event timeline; a run that could not be flown is an
``<error>``; a run that was not attempted a ``<skipped>``.  The timeline also goes to
``system-out`` (CI pages show it for passed runs too), the firmware version, the simulated
time, each finding (``NAME.finding.crash = failure at t=...``) and the run's files to the
suite's ``<properties>``.  CI servers (Jenkins, GitLab, GitHub's test reporters) read it as
they read any test run's.
"""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from pathlib import Path

from junitparser import Attr, Error, Failure, JUnitXml, Skipped, TestCase, TestSuite

from bfsitl.atomic_file import write_atomically
from bfsitl.scenario.result import ScenarioResult, Verdict

# Characters XML 1.0 cannot carry at all, not even escaped (a SITL's stdout may hold ANSI
# escapes or NULs); ElementTree would write them raw and the file would not parse.
_NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")


class _ScenarioCase(TestCase):
    """A test case with the ``file`` attribute pytest's and most CI readers' use (junitparser's
    own TestCase has no field for it)."""

    file = Attr()


def _xml_safe(text: str) -> str:
    """``text`` with the characters XML 1.0 forbids written as ``\\xNN`` escapes."""
    return _NOT_XML.sub(lambda match: match.group().encode("unicode_escape").decode(), text)


def _display_path(path: Path) -> str:
    """Relative to the current directory when under it (CI readers join it to the checkout),
    else as given: a ``../../..`` path says less than the path itself."""
    try:
        return Path(path).resolve().relative_to(Path.cwd().resolve()).as_posix()
    except (ValueError, OSError):
        return str(path)


def _classname(firmware: str) -> str:
    """CI readers split a class name at its dots into packages; a version like ``4.6.0`` must
    stay one part."""
    return f"scenarios.{firmware.replace('.', '_')}"


def _detail_text(result: ScenarioResult) -> str:
    """Every check (PASS/FAIL and its message), then the timeline: what a person reading a
    failure needs to see why, without opening the run's files."""
    lines = [f"retried: attempt {n} was lost: {why}" for n, why in enumerate(result.retried, 1)]
    lines += [f"{'PASS' if c.passed else 'FAIL'} {c.message}" for c in result.checks]
    if result.findings:
        if lines:
            lines.append("")
        lines.append("findings (the analysers that watch every run):")
        lines.extend(f.line() for f in result.findings)
    if result.events:
        if lines:
            lines.append("")
        lines.append("events:")
        lines.extend(_timeline_lines(result))
    return "\n".join(lines)


def _timeline_lines(result: ScenarioResult) -> list[str]:
    """One line per event, simulation time first so the lines align."""
    return [f"t={event.time_s:8.3f} s  {event.text}" for event in result.events]


def _outcome(result: ScenarioResult) -> Failure | Error | Skipped | None:
    """The JUnit element for the verdict; None for a pass (JUnit marks a pass by absence)."""
    reason = _xml_safe(result.reason)
    detail = _xml_safe(_detail_text(result))
    if result.verdict is Verdict.FAILED:
        failure = Failure(reason, "expectation")
        failure.text = detail or reason
        return failure
    if result.verdict is Verdict.ERROR:
        error = Error(reason, "error")
        error.text = detail or reason
        return error
    if result.verdict is Verdict.SKIPPED:
        return Skipped(reason)
    if result.verdict is Verdict.KNOWN:
        # As pytest writes an xfail: skipped, with the type saying why.
        return Skipped(reason, "known failure")
    return None


def _case(result: ScenarioResult) -> TestCase:
    case = _ScenarioCase(
        _xml_safe(result.name), _xml_safe(_classname(result.firmware)), float(result.wall_time_s)
    )
    if result.source is not None:
        case.file = _xml_safe(_display_path(result.source))
    outcome = _outcome(result)
    if outcome is not None:
        case.result = [outcome]
    out = _detail_text(result)
    if out:
        case.system_out = _xml_safe(out)
    return case


def _suite(name: str, runs: Sequence[ScenarioResult]) -> TestSuite:
    """One firmware's runs.  Properties go first: the JUnit schema wants them before the
    cases; a case's own are prefixed with its name (the schema has no per-case properties)."""
    suite = TestSuite(_xml_safe(name))
    version = next((r.firmware_version for r in runs if r.firmware_version), "")
    if version:
        suite.add_property("firmware_version", _xml_safe(version))
    for result in runs:
        prefix = _xml_safe(result.name) + "."
        suite.add_property(prefix + "vehicle", _xml_safe(result.vehicle))
        suite.add_property(prefix + "sim_time_s", f"{result.sim_time_s:g}")
        for finding in result.findings:
            suite.add_property(
                f"{prefix}finding.{finding.analyser}",
                _xml_safe(
                    f"{finding.severity.label} at t={finding.time_s:.2f} s: {finding.summary}"
                ),
            )
        for kind, artifact in result.artifacts.items():
            suite.add_property(prefix + _xml_safe(kind), _xml_safe(_display_path(artifact)))
    for result in runs:
        suite.add_testcase(_case(result))
    suite.update_statistics()
    return suite


def _by_firmware(results: Sequence[ScenarioResult]) -> dict[str, list[ScenarioResult]]:
    """Runs grouped by firmware, in the order each firmware first appears."""
    groups: dict[str, list[ScenarioResult]] = {}
    for result in results:
        groups.setdefault(result.firmware, []).append(result)
    return groups


def write_junit(
    results: Sequence[ScenarioResult], path: str | Path, *, suite_name: str = "bfsitl scenarios"
) -> Path:
    """Write ``results`` to ``path`` as JUnit XML; returns the path.

    Atomic: the file is written beside ``path`` and renamed over it, so a run interrupted
    while writing leaves the previous file (or none), never half of one that a CI server
    would reject.
    """
    xml = JUnitXml(_xml_safe(suite_name))
    for firmware, runs in _by_firmware(results).items():
        xml.add_testsuite(_suite(f"{suite_name} [{firmware}]", runs))
    xml.update_statistics()
    buffer = io.BytesIO()
    xml.write(buffer, pretty=True)
    out = Path(path)
    write_atomically(out, buffer.getvalue())
    return out
