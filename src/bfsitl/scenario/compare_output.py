"""What an A/B comparison writes: lines for the terminal, ``compare.json``, JUnit XML (one
test case per scenario: a failure when it got worse or changed, unless accepted) and an HTML
page with each scenario's figures side by side and both sides' runs overlaid on one plot."""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from datetime import UTC, datetime
from html import escape
from pathlib import Path

from junitparser import Error, Failure, JUnitXml, Skipped, TestCase, TestSuite

from bfsitl.atomic_file import write_atomically
from bfsitl.errors import BfsitlError
from bfsitl.scenario.compare import Change, ScenarioComparison, Side
from bfsitl.scenario.report import (
    STYLE,
    embedded_image,
    href,
    in_effect,
    overridden,
    settings_details,
)
from bfsitl.scenario.result import ScenarioResult
from bfsitl.scenario.setup_lines import SIDE
from bfsitl.scenario.suite import dir_name


def _verdict_word(comparison: ScenarioComparison) -> str:
    word = comparison.change.value.upper()
    waived = comparison.accepted and comparison.change.fails and not comparison.fails
    return f"{word} (accepted)" if waived else word


def comparison_lines(comparisons: Sequence[ScenarioComparison]) -> list[str]:
    """One line per scenario, then a count."""
    lines = [f"{_verdict_word(c):<18} {c.name}: {c.reason}" for c in comparisons]
    counts = {change: sum(c.change is change for c in comparisons) for change in Change}
    lines.append(
        ", ".join(f"{n} {change.value}" for change, n in counts.items() if n) or "nothing compared"
    )
    return lines


def _figure_dict(comparison: ScenarioComparison) -> list[dict[str, object]]:
    return [
        {
            "name": f.name,
            "unit": f.unit,
            "a": list(f.a),
            "b": list(f.b),
            "change": f.change.value,
            "note": f.note,
        }
        for f in comparison.figures
    ]


def write_comparison_json(
    comparisons: Sequence[ScenarioComparison], sides: tuple[Side, Side], path: Path
) -> Path:
    data = {
        "sides": [
            {
                "label": s.label,
                "firmware": s.firmware,
                "cli": list(s.cli),
                # Absent: each scenario's own [rc] rate_hz; null: a frame in every packet.
                **({"rc_rate_hz": s.rc_rate.hz} if s.rc_rate is not None else {}),
            }
            for s in sides
        ],
        "scenarios": [
            {
                "name": c.name,
                "change": c.change.value,
                "accepted": c.accepted,
                "fails": c.fails,
                "reason": c.reason,
                "differences": c.differences,
                "figures": _figure_dict(c),
                "runs": {
                    side.label: [str(r.artifacts.get("summary", "")) for r in runs]
                    for side, runs in zip(sides, (c.a_runs, c.b_runs), strict=True)
                },
            }
            for c in comparisons
        ],
    }
    write_atomically(path, (json.dumps(data, indent=2) + "\n").encode("utf-8"))
    return path


def _detail(comparison: ScenarioComparison, sides: tuple[Side, Side]) -> str:
    lines = [f"{sides[0].title}", f"{sides[1].title}", ""]
    lines += comparison.differences
    lines += [f"{f.change.value:<8} {f.name}: {f.note}" for f in comparison.figures]
    return "\n".join(lines)


def write_comparison_junit(
    comparisons: Sequence[ScenarioComparison], sides: tuple[Side, Side], path: Path
) -> Path:
    """One suite, one case per scenario; the figures of each side in the suite's
    properties (``NAME.FIGURE = A ... | B ...``)."""
    suite = TestSuite(f"bfsitl compare [{sides[0].title} | {sides[1].title}]")
    for comparison in comparisons:
        suite.add_property(f"{comparison.name}.change", _verdict_word(comparison).lower())
        for figure in comparison.figures:
            suite.add_property(
                f"{comparison.name}.{figure.name}",
                f"A {_values(figure.a)} | B {_values(figure.b)} {figure.unit}",
            )
        overlay = comparison.a_runs and comparison.a_runs[0].artifacts.get("overlay")
        if overlay:
            suite.add_property(f"{comparison.name}.overlay", str(overlay))
    for comparison in comparisons:
        case = TestCase(
            comparison.name,
            "compare",
            sum(r.wall_time_s for r in comparison.a_runs + comparison.b_runs),
        )
        detail = _detail(comparison, sides)
        if comparison.change is Change.SKIPPED:
            case.result = [Skipped(comparison.reason)]
        elif comparison.change is Change.ERROR:
            error = Error(comparison.reason, "error")
            error.text = detail
            case.result = [error]
        elif comparison.fails:
            failure = Failure(
                f"{comparison.change.value}: {comparison.reason}", comparison.change.value
            )
            failure.text = detail
            case.result = [failure]
        case.system_out = detail
        suite.add_testcase(case)
    suite.update_statistics()
    xml = JUnitXml("bfsitl compare")
    xml.add_testsuite(suite)
    xml.update_statistics()
    buffer = io.BytesIO()
    xml.write(buffer, pretty=True)
    write_atomically(path, buffer.getvalue())
    return path


def _values(values: Sequence[float | None]) -> str:
    return ",".join("-" if v is None else f"{v:.3g}" for v in values)


def draw_overlays(
    comparisons: Sequence[ScenarioComparison], sides: tuple[Side, Side], directory: Path
) -> None:
    """Each scenario's seeds on both sides, one plot (``directory/NAME.png``), from the runs'
    ``trace.csv`` (a replay's: the two replaying FCs' first logs, per axis); the path is kept
    as the first A run's ``overlay`` artifact."""
    from bfsitl.scenario.plot import write_overlay_plot
    from bfsitl.scenario.trace import read_trace_csv

    directory.mkdir(parents=True, exist_ok=True)
    for comparison in comparisons:
        if not comparison.a_runs or not comparison.b_runs:
            continue
        first_a, first_b = comparison.a_runs[0], comparison.b_runs[0]
        if "replay_report" in first_a.artifacts and "replay_report" in first_b.artifacts:
            _draw_replay_overlay(comparison, sides, directory)
            continue
        try:
            traced = [
                (
                    side.title,
                    [
                        read_trace_csv(Path(run.artifacts["trace"]))
                        for run in runs
                        if "trace" in run.artifacts and Path(run.artifacts["trace"]).is_file()
                    ],
                )
                for side, runs in zip(sides, (comparison.a_runs, comparison.b_runs), strict=True)
            ]
        except BfsitlError:
            continue
        if not all(traces for _, traces in traced):
            continue
        first_a.artifacts["overlay"] = write_overlay_plot(
            traced,
            directory / f"{dir_name(comparison.name)}.png",
            title=f"{comparison.name}: {comparison.change.value}",
        )


def _draw_replay_overlay(
    comparison: ScenarioComparison, sides: tuple[Side, Side], directory: Path
) -> None:
    """Two replays of one log: B's replaying FC against A's, per axis (setpoint, gyro, step
    response) and the motors."""
    from bfsitl.blackbox import decode_blackbox
    from bfsitl.replay.compare import compare_logs
    from bfsitl.replay.replay_report import write_comparison_png

    first_a, first_b = comparison.a_runs[0], comparison.b_runs[0]
    try:
        logs = [
            max(decode_blackbox(Path(run.artifacts["blackbox"])), key=lambda log: len(log.frames))
            for run in (first_a, first_b)
        ]
        path = directory / f"{dir_name(comparison.name)}.png"
        write_comparison_png(
            compare_logs(logs[0], logs[1]),
            path,
            labels=("A", "B"),
            title=f"{comparison.name}: {comparison.change.value}; {sides[1].title} against "
            f"{sides[0].title}",
        )
    except (BfsitlError, KeyError, ValueError, OSError):
        return  # a side without a readable log: the figures still say what changed
    first_a.artifacts["overlay"] = path


def write_comparison_report(
    comparisons: Sequence[ScenarioComparison], sides: tuple[Side, Side], directory: Path
) -> Path:
    """``directory/index.html``: a table of verdicts, then per scenario its figures side by
    side, what differs, and the overlay plot."""
    directory.mkdir(parents=True, exist_ok=True)
    stamp = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    rows = "".join(
        f'<tr><td><a href="#cmp-{i}">{escape(c.name)}</a></td>'
        f'<td class="verdict {c.change.value}">{escape(_verdict_word(c))}</td>'
        f"<td>{escape(c.reason)}</td></tr>"
        for i, c in enumerate(comparisons)
    )
    sections = "".join(_section(i, c, sides, directory) for i, c in enumerate(comparisons))
    page = (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>bfsitl compare</title><style>{STYLE}</style></head><body>"
        f"<h1>bfsitl compare</h1><p>written {stamp}</p><p>{escape(sides[0].title)}<br>"
        f"{escape(sides[1].title)}</p><p>{escape(comparison_lines(comparisons)[-1])}</p>"
        "<table><tr><th>scenario</th><th>verdict</th><th>why</th></tr>"
        f"{rows}</table>{sections}</body></html>\n"
    )
    path = directory / "index.html"
    write_atomically(path, page.encode("utf-8"))
    return path


def _section(
    index: int, comparison: ScenarioComparison, sides: tuple[Side, Side], directory: Path
) -> str:
    figures = "".join(
        f'<tr><td>{escape(f.name)}</td><td class="num">{escape(_values(f.a))}</td>'
        f'<td class="num">{escape(_values(f.b))}</td><td>{escape(f.unit)}</td>'
        f'<td class="verdict {f.change.value}">{escape(f.change.value)}</td></tr>'
        for f in comparison.figures
    )
    differences = "".join(f"<li>{escape(d)}</li>" for d in comparison.differences)
    overlay = comparison.a_runs[0].artifacts.get("overlay") if comparison.a_runs else None
    image = (
        f'<img src="{embedded_image(Path(overlay))}" alt="{escape(comparison.name)}: '
        f'A and B overlaid">'
        if overlay and Path(overlay).is_file()
        else ""
    )
    return (
        f'<section id="cmp-{index}"><h2>{escape(comparison.name)}: '
        f'<span class="verdict {comparison.change.value}">'
        f"{escape(_verdict_word(comparison))}</span></h2><p>{escape(comparison.reason)}</p>"
        + (f"<ul>{differences}</ul>" if differences else "")
        + (
            '<table><tr><th>figure</th><th class="num">A (each seed)</th>'
            '<th class="num">B (each seed)</th><th>unit</th><th></th></tr>'
            f"{figures}</table>"
            if figures
            else ""
        )
        + f"{image}{_configuration(comparison)}{_run_links(comparison, directory)}</section>"
    )


def _settings_of(runs: Sequence[ScenarioResult]) -> list[tuple[str, str, str]]:
    return list(runs[0].settings) if runs else []


def _configuration(comparison: ScenarioComparison) -> str:
    """What each side's FC was given: the lines on one side only first, then each side's
    whole list with where every line came from."""
    a, b = _settings_of(comparison.a_runs), _settings_of(comparison.b_runs)
    if not a and not b:
        return ""
    # What each FC ended with: a line the scenario replaced later had no effect.
    a_now, b_now = in_effect(a), in_effect(b)
    only = [("A", a_now[k]) for k in a_now if a_now[k][1] != b_now.get(k, ("", "", ""))[1]]
    only += [("B", b_now[k]) for k in b_now if b_now[k][1] != a_now.get(k, ("", "", ""))[1]]
    differing = "".join(
        f"<li>{side} only: <code>{escape(line)}</code> ({escape(source)})</li>"
        for side, (source, line, _why) in only
    )
    unused = [
        (label, line)
        for label, settings in (("A", a), ("B", b))
        for (source, line, _why), later in zip(settings, overridden(settings), strict=True)
        if later and source == SIDE
    ]
    differing += "".join(
        f"<li>{label}'s <code>{escape(line)}</code> had no effect: a later line sets it again</li>"
        for label, line in unused
    )
    tables = "".join(
        settings_details(f"{label}: the {len(settings)} lines its FC was given", settings)
        for label, settings in (("A", a), ("B", b))
    )
    said = f"<ul>{differing}</ul>" if differing else "<p>Both sides were given the same lines.</p>"
    return f"<h3>Configuration</h3>{said}{tables}"


def _run_links(comparison: ScenarioComparison, directory: Path) -> str:
    """Each run's files, linked from the report's folder (they sit beside it)."""
    items = []
    for label, runs in (("A", comparison.a_runs), ("B", comparison.b_runs)):
        for number, run in enumerate(runs, start=1):
            links = ", ".join(
                f'<a href="{href(Path(path), directory)}">{escape(kind)}</a>'
                for kind, path in run.artifacts.items()
                if kind in RUN_FILES and Path(path).exists()
            )
            items.append(f"<li>{label}, run {number}: {escape(run.verdict.value)}; {links}</li>")
    return f"<h3>Runs</h3><ul>{''.join(items)}</ul>" if items else ""


#: The run files a report links to.
RUN_FILES = ("summary", "blackbox", "trace", "log", "plot", "blackbox_plot", "replay_report")
