"""A ``[replay]`` scenario's run: the log's sticks flown again through the firmware
(:func:`bfsitl.replay.replay_log`), then judged as any scenario is.

The side's and the scenario's CLI lines come after the log's carried settings, so a
comparison's ``--b-cli`` is the change tried on the real flight.  The replaying FC's log is
watched by the analysers (a change that crashes the quad is a failure-severity finding, so the
side is worse), and its figures (:data:`bfsitl.scenario.metrics.REPLAY_METRICS`: how each
axis followed its setpoint, rose and overshot, how far it flew from the real flight) are what
``bfsitl scenario compare`` compares between builds or settings.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from bfsitl.analysis import analyse, track_from_blackbox
from bfsitl.backend.options import Timing
from bfsitl.fit.fit_log import pick_log
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.replay import Replay, replay_log
from bfsitl.replay.replay_report import write_report_json, write_report_png
from bfsitl.replay.sticks import IDENTITY_RC_LINES
from bfsitl.scenario.expectations import settle_verdict
from bfsitl.scenario.metrics import replay_metrics
from bfsitl.scenario.result import PlotWhen, ScenarioResult, TimedEvent, wants_plot
from bfsitl.scenario.setup_lines import BFSITL, LOG, asked_lines
from bfsitl.scenario.spec import Scenario
from bfsitl.scenario.timings import Stopwatch
from bfsitl.scenario.trace import Trace

Progress = Callable[[str], None]


def fly_replay_scenario(
    scenario: Scenario,
    binary: Path,
    profile: FirmwareProfile,
    out: Path,
    result: ScenarioResult,
    say: Progress,
    *,
    plot: PlotWhen,
    timing: Timing,
) -> None:
    """Replay ``scenario.replay``'s log on ``binary`` with the scenario's quad, seed, wind and
    lines, at ``timing``, and fill ``result`` (figures, findings, checks, verdict, files in
    ``out``; the report's plot as ``plot`` says).

    Raises:
        BfsitlError: The log cannot be read or replayed, or the SITL would not fly (the
            runner makes it an error result).
    """
    spec = scenario.replay
    if spec is None:
        raise ValueError(f"{scenario.name} is no replay")
    watch = Stopwatch()
    say(f"reading {spec.log.name} ...")
    with watch.span("log read"):
        log = pick_log(spec.log, spec.index)
    generation = profile.generation.value
    lines = tuple(asked.line for asked in asked_lines(scenario, generation))
    # The replay's start-up, arming and flight are one call: timed as the flight.
    with watch.span("flight"):
        replay = replay_log(
            log,
            firmware=binary,
            quad=scenario.quad,
            out_dir=out,
            extra_cli=lines,
            progress=say,
            seed=scenario.seed,
            wind=scenario.wind,
            timing=timing,
        )
    comparison = replay.comparison
    result.settings = _replay_settings(scenario, replay, generation)
    result.sim_time_s = round(replay.flight.flown_s, 3)
    result.artifacts["blackbox"] = replay.flight.blackbox
    result.events.append(
        TimedEvent(
            0.0,
            f"replaying {log.path.name} log {log.index} ({log.firmware_revision}): "
            f"{len(replay.settings.carried)} settings carried over, "
            f"{len(replay.settings.not_carried)} not",
        )
    )
    if comparison.lost_control_s is not None:
        result.events.append(
            TimedEvent(
                comparison.lost_control_s,
                "the real quad lost control here (log time); compared up to a second before",
            )
        )
    report = out / "replay-report.json"
    with watch.span("files"):
        write_report_json(replay, report)
    result.artifacts["replay_report"] = report
    with watch.span("analysers"):
        _judge(scenario, replay, result, generation)
    if wants_plot(plot, result.verdict):
        with watch.span("plots"):
            write_report_png(replay, out / "replay-report.png")
        result.artifacts["plot"] = out / "replay-report.png"
    result.timings_s = dict(watch.spans_s)


def _replay_settings(
    scenario: Scenario, replay: Replay, generation: str
) -> list[tuple[str, str, str]]:
    """Every line the replaying FC was given, in order, with where it came from."""
    whence: dict[str, tuple[str, str]] = {
        line: (LOG, setting.header)
        for setting in replay.settings.carried
        for line in setting.cli_lines
    }
    whence.update(dict.fromkeys(IDENTITY_RC_LINES, (BFSITL, "the identity stick path")))
    whence.update((a.line, (a.source, a.why)) for a in asked_lines(scenario, generation))
    settings = []
    for line in replay.flight.cli_lines:
        source, why = whence.get(line, (BFSITL, "the FC's own log"))
        settings.append((source, line, why))
    return settings


def _judge(scenario: Scenario, replay: Replay, result: ScenarioResult, generation: str) -> None:
    """The analysers on the replaying FC's log, the figures, the expectations."""
    comparison = replay.comparison
    analysis = analyse(track_from_blackbox(replay.replayed))
    result.take_analysis(analysis)
    figures = replay_metrics(comparison, result.findings)
    result.metrics, result.behaviour = figures.values, figures.behaviour
    trace = Trace(
        blackbox=[replay.replayed],
        findings=analysis.findings,
        unwatched=analysis.skipped,
        replay=comparison,
    )
    settle_verdict(result, scenario, trace, generation)
