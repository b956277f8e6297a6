"""A run's results as JUnit XML, written with ``junitparser`` (the registry's JUnit library).

One ``<testsuite>`` per firmware, one ``<testcase>`` per scenario: a failed run is a
``<failure>`` whose message is its first failed check and whose text lists every check; a
run that could not be flown is an ``<error>``; a fault the firmware cannot express a
``<skipped>``.  The event timeline goes to ``system-out``, the firmware version and the
run's files to ``<properties>``.  CI servers (Jenkins, GitLab, GitHub's test reporters) read
it as they read any test run's.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from junitparser import Error, Failure, JUnitXml, Skipped, TestCase, TestSuite

from bfsitl.scenario.result import ScenarioResult, Verdict


def _case(result: ScenarioResult) -> TestCase:
    case = TestCase(result.name, f"scenarios.{result.firmware.replace('.', '_')}",
                    result.wall_time_s)
    checks = "\n".join(f"{'PASS' if c.passed else 'FAIL'} {c.message}" for c in result.checks)
    if result.verdict is Verdict.FAILED:
        failure = Failure(result.reason, "expectation")
        failure.text = checks
        case.result = [failure]
    elif result.verdict is Verdict.ERROR:
        error = Error(result.reason, "error")
        error.text = checks or result.reason
        case.result = [error]
    elif result.verdict is Verdict.SKIPPED:
        case.result = [Skipped(result.reason)]
    lines = [f"t={e.time_s:8.3f} s  {e.text}" for e in result.events]
    if result.verdict is Verdict.PASSED and checks:
        lines = [*checks.splitlines(), *lines]
    if lines:
        case.system_out = "\n".join(lines)
    return case


def _relative(path: Path) -> str:
    try:
        return os.path.relpath(path)
    except ValueError:  # another drive
        return str(path)


def write_junit(results: Sequence[ScenarioResult], path: str | Path, *,
                suite_name: str = "bfsitl scenarios") -> Path:
    """Write ``results`` to ``path`` (atomically: an interrupted run never leaves half a
    file); returns the path."""
    path = Path(path)
    xml = JUnitXml(suite_name)
    by_firmware: dict[str, list[ScenarioResult]] = {}
    for result in results:
        by_firmware.setdefault(result.firmware, []).append(result)
    for firmware, runs in by_firmware.items():
        suite = TestSuite(f"{suite_name} [{firmware}]")
        # Properties first: the JUnit schema wants them before the test cases.
        version = next((r.firmware_version for r in runs if r.firmware_version), "")
        if version:
            suite.add_property("firmware_version", version)
        for result in runs:
            prefix = f"{result.name}."
            suite.add_property(prefix + "sim_time_s", f"{result.sim_time_s:g}")
            if result.source is not None:
                suite.add_property(prefix + "file", _relative(result.source))
            for kind, artifact in result.artifacts.items():
                suite.add_property(prefix + kind, _relative(artifact))
        for result in runs:
            suite.add_testcase(_case(result))
        suite.update_statistics()
        xml.add_testsuite(suite)
    xml.update_statistics()
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(path.name + ".tmp")
    xml.write(str(temporary), pretty=True)
    temporary.replace(path)
    return path
