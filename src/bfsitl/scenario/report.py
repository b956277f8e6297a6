"""A run's results as one HTML page a person opens from disk: the summary, a table of every
run with links to its files, and per run its checks, its timeline and its plots.

Self-contained (inline style, no script, nothing fetched); links and images are relative to
the page's directory, so the directory can be zipped or published as a CI artifact together
with the runs.  Every text from a scenario file or a run is escaped: scenario names,
descriptions and messages are user input.
"""

from __future__ import annotations

import base64
import os
from collections.abc import Sequence
from datetime import UTC, datetime
from html import escape
from pathlib import Path
from urllib.parse import quote

from bfsitl.analysis.findings import evidence_text
from bfsitl.atomic_file import write_atomically
from bfsitl.scenario.result import CheckResult, ScenarioResult, Verdict

#: Files shown as images in a run's section (when they exist), by their suffix.
_IMAGE_SUFFIXES = (".png", ".svg", ".jpg", ".jpeg")

STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 72em;
       padding: 0 1em; color: #1f2328; }
table { border-collapse: collapse; width: 100%; margin: 1em 0; }
th, td { border-bottom: 1px solid #d0d7de; padding: .3em .5em; text-align: left;
         vertical-align: top; }
th { background: #f6f8fa; }
.num { text-align: right; font-variant-numeric: tabular-nums; }
.verdict { font-weight: 600; }
.passed { color: #1a7f37; } .failed { color: #cf222e; }
.error { color: #9a6700; } .skipped { color: #6e7781; }
.known { color: #9a6700; background: #fff8c5; padding: 0 .3em; }
.missing { color: #6e7781; text-decoration: line-through; }
section { border-top: 2px solid #d0d7de; margin-top: 2em; }
pre { background: #f6f8fa; padding: .6em; overflow-x: auto; font-size: 12px; }
img { max-width: 100%; border: 1px solid #d0d7de; margin: .5em 0; }
.finding { font-weight: 600; } span.finding { margin-right: .4em; }
.finding.failure { color: #cf222e; } .finding.warning { color: #9a6700; }
.finding.info { color: #0969da; } .unwatched { color: #6e7781; font-size: 12px; }
.same { color: #1a7f37; } .better { color: #1a7f37; } .worse { color: #cf222e; }
.changed { color: #8250df; } .accepted { color: #6e7781; }
"""


def href(target: Path, directory: Path) -> str:
    """``target`` relative to the page's directory, URL-quoted (a space or ``#`` in a file name
    must not break the link) and escaped for an attribute."""
    try:
        relative = Path(os.path.relpath(Path(target).resolve(), directory.resolve())).as_posix()
    except ValueError:  # another drive on Windows: no relative path exists
        return escape(Path(target).resolve().as_uri(), quote=True)
    return escape(quote(relative), quote=True)


def embedded_image(path: Path) -> str:
    """A plot as a ``data:`` URI: the page shows it wherever it is copied (a CI artefact, an
    e-mail), with no file beside it."""
    kind = "image/svg+xml" if path.suffix.lower() == ".svg" else f"image/{path.suffix.lower()[1:]}"
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return escape(f"data:{kind};base64,{data}", quote=True)


def _verdict(verdict: Verdict) -> str:
    return f'<span class="verdict {verdict.name.lower()}">{escape(verdict.value.upper())}</span>'


def _summary(results: Sequence[ScenarioResult]) -> str:
    """Counts per verdict and how fast the runs flew; the wall time is summed over runs, so
    with ``--jobs`` the ratio is per run, not the batch's."""
    tally = {v: sum(1 for r in results if r.verdict is v) for v in Verdict}
    counts = ", ".join(
        f"{n} {v.value}{'s' if v is Verdict.KNOWN and n > 1 else ''}"
        for v, n in tally.items()
        if n or v is not Verdict.KNOWN
    )
    simulated = sum(r.sim_time_s for r in results)
    wall = sum(r.wall_time_s for r in results)
    ratio = f"{simulated / wall:.1f}x real time" if wall > 0 else "no run time measured"
    return (
        f'<p class="summary"><b>{len(results)} runs</b>: {escape(counts)}. '
        f"{simulated:.1f} s simulated in {wall:.1f} s of run time ({ratio}, summed over "
        "runs).</p>"
    )


def _links(result: ScenarioResult, directory: Path) -> str:
    """A link per file the run wrote; a file named but absent is shown struck through rather
    than as a link that goes nowhere."""
    parts = []
    for kind, path in result.artifacts.items():
        if Path(path).exists():
            parts.append(f'<a href="{href(path, directory)}">{escape(kind)}</a>')
        else:
            parts.append(f'<span class="missing" title="not written">{escape(kind)}</span>')
    return " ".join(parts)


def _table(results: Sequence[ScenarioResult], directory: Path) -> str:
    rows = [
        f'<tr><td><a href="#run-{index}">{escape(result.name)}</a></td>'
        f"<td>{escape(result.firmware)}</td><td>{_verdict(result.verdict)}</td>"
        f"<td>{escape(_reason(result))}</td><td>{_finding_badges(result)}</td>"
        f'<td class="num">{result.sim_time_s:.1f}</td>'
        f'<td class="num">{result.wall_time_s:.1f}</td><td>{_links(result, directory)}</td>'
        "</tr>"
        for index, result in enumerate(results)
    ]
    return (
        "<table><tr><th>scenario</th><th>firmware</th><th>verdict</th><th>reason</th>"
        '<th class="num">sim s</th><th class="num">wall s</th><th>files</th></tr>'
        + "".join(rows)
        + "</table>"
    )


def _reason(result: ScenarioResult) -> str:
    """The run's reason, and how often it had to be run (a Ray node or worker lost)."""
    if not result.retried:
        return result.reason
    return f"{result.reason} (run {len(result.retried) + 1} times: {'; '.join(result.retried)})"


def _check_row(check: CheckResult) -> str:
    verdict = Verdict.PASSED if check.passed else Verdict.FAILED
    label = "PASS" if check.passed else "FAIL"
    at = "" if check.at_time_s is None else f"{check.at_time_s:.2f}"
    return (
        f'<tr><td class="verdict {verdict.value}">{label}</td>'
        f'<td>{escape(check.message)}</td><td class="num">{at}</td></tr>'
    )


def _checks(result: ScenarioResult) -> str:
    """The checks as a table; a run with none (an error, a skip) shows its reason instead."""
    if not result.checks:
        return f"<p>{escape(result.reason)}</p>" if result.reason else ""
    return (
        '<table><tr><th></th><th>check</th><th class="num">at s</th></tr>'
        + "".join(_check_row(c) for c in result.checks)
        + "</table>"
    )


def _finding_badges(result: ScenarioResult) -> str:
    """The run's findings in the summary table: each analyser's name, coloured by severity."""
    return " ".join(
        f'<span class="finding {f.severity.label}" '
        f'title="{escape(f.summary, quote=True)}">{escape(f.analyser)}</span>'
        for f in result.findings
    )


def _findings(result: ScenarioResult) -> str:
    """What the analysers found, with the evidence; which of them could not watch."""
    if not result.findings and not result.unwatched:
        return ""
    rows = "".join(
        f'<tr><td class="finding {f.severity.label}">{f.severity.label}</td>'
        f"<td>{escape(f.analyser)}</td><td>{escape(f.summary)}</td>"
        f'<td class="num">{f.time_s:.2f}</td><td>{escape(f.source)}</td>'
        f"<td><code>{escape(evidence_text(f.evidence))}</code></td></tr>"
        for f in result.findings
    )
    table = (
        (
            '<table><tr><th></th><th>analyser</th><th>finding</th><th class="num">at s'
            "</th><th>seen in</th><th>evidence</th></tr>" + rows + "</table>"
        )
        if rows
        else "<p>nothing found</p>"
    )
    unwatched = ""
    if result.unwatched:
        unwatched = (
            '<p class="unwatched">not watched: '
            + escape("; ".join(f"{name} ({why})" for name, why in result.unwatched.items()))
            + "</p>"
        )
    return f"<h3>findings</h3>{table}{unwatched}"


def setting_key(line: str) -> str:
    """What a CLI line sets: ``set NAME`` for ``set name = value`` (spaces or not, any case),
    ``feature NAME`` for ``feature [-]NAME``, else the line itself."""
    words = line.replace("=", " = ").split()
    if len(words) >= 2 and words[0].lower() in ("set", "feature"):
        return f"{words[0].lower()} {words[1].lstrip('-').lower()}"
    return line


def overridden(settings: Sequence[tuple[str, str, str]]) -> list[bool]:
    """Per line: a later line sets the same thing (the FC keeps the last)."""
    keys = [setting_key(line) for _, line, _ in settings]
    return [key in keys[i + 1 :] for i, key in enumerate(keys)]


def in_effect(settings: Sequence[tuple[str, str, str]]) -> dict[str, tuple[str, str, str]]:
    """The line that stands for each thing set, the last one given."""
    return {setting_key(line): (source, line, why) for source, line, why in settings}


def settings_details(summary: str, settings: Sequence[tuple[str, str, str]]) -> str:
    """A run's configuration as a folded table: each line, where it came from, why, and
    whether a later line replaced it."""
    rows = "".join(
        f"<tr><td>{escape(source)}</td><td><code>{escape(line)}</code></td>"
        f"<td>{escape(why)}{' (a later line sets it again)' if later else ''}</td></tr>"
        for (source, line, why), later in zip(settings, overridden(settings), strict=True)
    )
    return (
        f"<details><summary>{escape(summary)}</summary><table><tr><th>from</th><th>line</th>"
        f"<th>why</th></tr>{rows}</table></details>"
    )


def _timeline(result: ScenarioResult) -> str:
    if not result.events:
        return ""
    lines = "\n".join(f"t={event.time_s:8.2f} s  {event.text}" for event in result.events)
    return f"<h3>events</h3><pre>{escape(lines)}</pre>"


def _images(result: ScenarioResult, directory: Path) -> str:
    """The run's plots that exist on disk, the scenario plot first."""
    kinds = sorted(result.artifacts, key=lambda kind: kind != "plot")
    images = []
    for kind in kinds:
        path = Path(result.artifacts[kind])
        if path.suffix.lower() in _IMAGE_SUFFIXES and path.exists():
            images.append(
                f'<img src="{embedded_image(path)}" '
                f'alt="{escape(kind, quote=True)} of {escape(result.name, quote=True)}">'
            )
    return "".join(images)


def _section(index: int, result: ScenarioResult, directory: Path) -> str:
    parts = [
        f'<section id="run-{index}"><h2>{escape(result.name)} on '
        f"{escape(result.firmware)}: {_verdict(result.verdict)}</h2>"
    ]
    flew = f"Betaflight {result.firmware_version}, " if result.firmware_version else ""
    parts.append(f"<p>{escape(flew)}vehicle {escape(result.vehicle)}</p>")
    if result.description:
        parts.append(f"<p>{escape(' '.join(result.description.split()))}</p>")
    parts.extend(
        (
            _checks(result),
            _findings(result),
            _timeline(result),
            settings_details(
                f"configuration: the {len(result.settings)} lines its FC was given",
                result.settings,
            )
            if result.settings
            else "",
            _images(result, directory),
            "</section>",
        )
    )
    return "".join(parts)


def render_report(
    results: Sequence[ScenarioResult], directory: Path, *, title: str = "bfsitl scenarios"
) -> str:
    """The page as text; ``directory`` is where it will live (links are relative to it)."""
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    sections = "".join(_section(i, r, directory) for i, r in enumerate(results))
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{escape(title)}</title><style>{STYLE}</style></head><body>"
        f"<h1>{escape(title)}</h1><p>written {stamp}</p>{_summary(results)}"
        f"{_table(results, directory)}{sections}</body></html>\n"
    )


def write_report(
    results: Sequence[ScenarioResult], directory: str | Path, *, title: str = "bfsitl scenarios"
) -> Path:
    """Write ``directory/index.html`` (atomically, see :func:`write_atomically`); returns its
    path."""
    directory = Path(directory)
    path = directory / "index.html"
    write_atomically(path, render_report(results, directory, title=title).encode("utf-8"))
    return path
