"""A run's results as one HTML page a person opens from disk: the summary, a table of every
run with links to its files, and per run its checks, its timeline and its plot.

Self-contained (inline style, no script, nothing fetched); links and images are relative to
the page's directory, so the directory can be zipped or published as a CI artifact together
with the runs.  Every text from a scenario file or a run is escaped.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from datetime import UTC, datetime
from html import escape
from pathlib import Path

from bfsitl.scenario.result import ScenarioResult, Verdict

_COLOURS = {Verdict.PASSED: "#1a7f37", Verdict.FAILED: "#cf222e", Verdict.ERROR: "#9a6700",
            Verdict.SKIPPED: "#6e7781"}
_STYLE = """
body { font: 14px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 70em; color: #1f2328; }
table { border-collapse: collapse; width: 100%; margin: 1em 0; }
th, td { border-bottom: 1px solid #d0d7de; padding: .3em .5em; text-align: left;
         vertical-align: top; }
th { background: #f6f8fa; }
.verdict { font-weight: 600; }
.num { text-align: right; font-variant-numeric: tabular-nums; }
section { border-top: 2px solid #d0d7de; margin-top: 2em; }
pre { background: #f6f8fa; padding: .6em; overflow-x: auto; font-size: 12px; }
img { max-width: 100%; border: 1px solid #d0d7de; }
.pass { color: #1a7f37; } .fail { color: #cf222e; }
"""


def _href(target: Path, directory: Path) -> str:
    try:
        relative = os.path.relpath(Path(target).resolve(), directory.resolve())
    except ValueError:
        relative = str(target)
    return escape(Path(relative).as_posix(), quote=True)


def _anchor(result: ScenarioResult) -> str:
    return escape(f"run-{result.firmware}-{result.name}".replace(" ", "-"), quote=True)


def _verdict(result: ScenarioResult) -> str:
    colour = _COLOURS[result.verdict]
    return (f'<span class="verdict" style="color:{colour}">'
            f"{escape(result.verdict.value.upper())}</span>")


def _summary(results: Sequence[ScenarioResult]) -> str:
    counts = {v: sum(1 for r in results if r.verdict is v) for v in Verdict}
    simulated = sum(r.sim_time_s for r in results)
    wall = sum(r.wall_time_s for r in results)
    ratio = f"{simulated / wall:.1f}x" if wall > 0 else "n/a"
    parts = ", ".join(f"{counts[v]} {v.value}" for v in Verdict)
    return (f"<p><b>{len(results)} runs</b>: {escape(parts)}. {simulated:.0f} s simulated in "
            f"{wall:.0f} s of run time ({ratio} real time, summed over runs).</p>")


def _table(results: Sequence[ScenarioResult], directory: Path) -> str:
    rows = []
    for result in results:
        links = " ".join(f'<a href="{_href(path, directory)}">{escape(kind)}</a>'
                         for kind, path in result.artifacts.items())
        rows.append(
            f"<tr><td><a href=\"#{_anchor(result)}\">{escape(result.name)}</a></td>"
            f"<td>{escape(result.firmware)}</td><td>{_verdict(result)}</td>"
            f"<td>{escape(result.reason)}</td><td class=\"num\">{result.sim_time_s:.1f}</td>"
            f"<td class=\"num\">{result.wall_time_s:.1f}</td><td>{links}</td></tr>")
    return ("<table><tr><th>scenario</th><th>firmware</th><th>verdict</th><th>reason</th>"
            "<th>sim s</th><th>wall s</th><th>files</th></tr>" + "".join(rows) + "</table>")


def _section(result: ScenarioResult, directory: Path) -> str:
    parts = [f'<section id="{_anchor(result)}"><h2>{escape(result.name)} on '
             f"{escape(result.firmware)} {_verdict(result)}</h2>"]
    if result.firmware_version:
        parts.append(f"<p>Betaflight {escape(result.firmware_version)}</p>")
    if result.description:
        parts.append(f"<p>{escape(' '.join(result.description.split()))}</p>")
    if result.checks:
        parts.append("<ul>" + "".join(
            f'<li class="{"pass" if c.passed else "fail"}">{"PASS" if c.passed else "FAIL"} '
            f"{escape(c.message)}</li>" for c in result.checks) + "</ul>")
    elif result.reason:
        parts.append(f"<p>{escape(result.reason)}</p>")
    if result.events:
        parts.append("<pre>" + escape("\n".join(f"t={e.time_s:8.2f} s  {e.text}"
                                                for e in result.events)) + "</pre>")
    plot = result.artifacts.get("plot")
    if plot is not None and Path(plot).exists():
        parts.append(f'<img src="{_href(plot, directory)}" alt="plot of '
                     f'{escape(result.name, quote=True)}">')
    parts.append("</section>")
    return "".join(parts)


def write_report(results: Sequence[ScenarioResult], directory: str | Path, *,
                 title: str = "bfsitl scenarios") -> Path:
    """Write ``directory/index.html`` (atomically); returns its path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    page = (f"<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{escape(title)}</title><style>{_STYLE}</style></head><body>"
            f"<h1>{escape(title)}</h1><p>{stamp}</p>{_summary(results)}"
            f"{_table(results, directory)}"
            + "".join(_section(r, directory) for r in results) + "</body></html>\n")
    path = directory / "index.html"
    temporary = path.with_name("index.html.tmp")
    temporary.write_text(page, encoding="utf-8")
    temporary.replace(path)
    return path
