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
from bfsitl.scenario.report import STYLE, embedded_image
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
        "sides": [{"label": s.label, "firmware": s.firmware, "cli": list(s.cli)} for s in sides],
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
    """Each scenario's first seed on both sides, one plot (``directory/NAME.png``), from the
    runs' ``trace.csv`` (a replay's: the two replaying FCs' logs, per axis); the path is kept
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
        paths = [first_a.artifacts.get("trace"), first_b.artifacts.get("trace")]
        if not all(p is not None and Path(p).is_file() for p in paths):
            continue
        try:
            traces = [
                (side.title, read_trace_csv(Path(p)))  # type: ignore[arg-type]
                for side, p in zip(sides, paths, strict=True)
            ]
        except BfsitlError:
            continue
        first_a.artifacts["overlay"] = write_overlay_plot(
            traces,
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
        + f"{image}</section>"
    )
