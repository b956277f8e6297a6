"""``bfsitl scenario compare``: the same scenarios on two builds (or one build with changed
defaults) over several seeds, and a verdict per scenario (docs/compare.md)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.cli.arg_types import add_vehicle_argument, parse_speed, rc_rate, whole_number_at_least
from bfsitl.cli.target import progress

if TYPE_CHECKING:
    from bfsitl.scenario.compare import RcRate

EXIT_OK = 0
EXIT_DIFFERENT = 1
EXIT_INTERRUPTED = 130
DEFAULT_OUT = "scenario-compare"


def add_compare_parser(actions: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    compare = actions.add_parser(
        "compare",
        help="A/B: the scenarios on two builds, a verdict per scenario",
        description="Fly each scenario on side A and side B over --seeds seeds and judge "
        "what changed: the failsafe's phases, the modes, how it ended, what the "
        "analysers found, and the figures (where it landed, how hard, tilt, time "
        "to each failsafe phase, hold error, path, an energy proxy) against the "
        "seeds' spread. Each scenario is same, better, worse or changed. Exit 0 "
        "when none is worse or changed (or each such one is --accept'ed), 1 "
        "otherwise.",
        epilog="Examples:\n"
        "  bfsitl scenario compare --firmware master-lockstep --firmware my-branch\n"
        "  bfsitl scenario compare --firmware 4.6.0-gps-lockstep "
        "--b-cli 'set ap_hover_throttle = 1275' --seeds 2 --report cmp/\n"
        "  bfsitl scenario compare --firmware 4.6.0-gps-lockstep --b-rc-rate 50 "
        "rc-loss-hover-drop",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    compare.add_argument(
        "paths",
        nargs="*",
        metavar="FILE_OR_DIR",
        help="scenario files, directories or library names (default: the shipped library)",
    )
    add_vehicle_argument(compare, per_scenario=True)
    compare.add_argument(
        "--firmware",
        action="append",
        default=[],
        metavar="NAME",
        required=True,
        help="side A's build; give it twice for side B's (once: both sides "
        "fly it, and --a-cli / --b-cli or --a-rc-rate / --b-rc-rate make the difference)",
    )
    compare.add_argument(
        "--a-cli",
        action="append",
        default=[],
        metavar="LINE",
        help="a CLI line for side A, before each scenario's own lines "
        "(a changed default); repeat for several",
    )
    compare.add_argument(
        "--b-cli", action="append", default=[], metavar="LINE", help="the same for side B"
    )
    compare.add_argument(
        "--a-rc-rate",
        type=side_rc_rate,
        metavar="HZ|packet",
        help="side A's RC link rate for every scenario instead of its own [rc] rate_hz "
        "(16..1000, or 'packet': a frame in every fdm packet); replays keep their log's",
    )
    compare.add_argument(
        "--b-rc-rate",
        type=side_rc_rate,
        metavar="HZ|packet",
        help="the same for side B",
    )
    compare.add_argument(
        "--seeds",
        type=whole_number_at_least(1),
        default=3,
        metavar="N",
        help="seeds per scenario and side: the scenario's seed and the next "
        "N-1 (default 3); the spread across them is what a difference "
        "must exceed",
    )
    compare.add_argument(
        "--accept",
        action="append",
        default=[],
        metavar="SCENARIO",
        help="a scenario whose worse or changed verdict is expected (it is "
        "still reported); repeat for several",
    )
    compare.add_argument(
        "--jobs",
        type=whole_number_at_least(1),
        default=None,
        metavar="N",
        help="runs side by side (default: one per core, at most one per run; 1 runs "
        "them here with every event shown)",
    )
    compare.add_argument(
        "--ray",
        metavar="ADDRESS",
        dest="ray_address",
        help="fly the runs on a Ray cluster (as `scenario run --ray`)",
    )
    compare.add_argument(
        "--out",
        type=Path,
        default=Path(DEFAULT_OUT),
        metavar="DIR",
        help=f"runs under DIR/A/ and DIR/B/, compare.json and the overlay "
        f"plots in DIR (default {DEFAULT_OUT}/)",
    )
    compare.add_argument(
        "--junit",
        type=Path,
        metavar="FILE",
        help="JUnit XML: a test case per scenario, failed when worse or changed and not accepted",
    )
    compare.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="an HTML page: verdicts, figures side by side, overlay plots",
    )
    compare.add_argument(
        "--speed",
        type=parse_speed,
        default=None,
        metavar="X",
        help="x real time (default: as fast as a lockstep build goes)",
    )
    compare.set_defaults(func=cmd_scenario_compare)


def side_rc_rate(text: str) -> RcRate:
    """``--a-rc-rate`` / ``--b-rc-rate``: a rate in Hz or ``packet`` (not given: each
    scenario's own)."""
    from bfsitl.scenario.compare import RcRate

    return RcRate(rc_rate(text))


def cmd_scenario_compare(args: argparse.Namespace) -> int:
    from bfsitl.cli.scenario_inputs import check_builds, paths_or_library
    from bfsitl.errors import ScenarioError
    from bfsitl.scenario.compare import (
        Change,
        Side,
        compare_results,
        plan_comparison,
        seeds_for,
    )
    from bfsitl.scenario.compare_output import (
        comparison_lines,
        draw_overlays,
        write_comparison_json,
        write_comparison_junit,
        write_comparison_report,
    )
    from bfsitl.scenario.load import find_scenarios
    from bfsitl.scenario.spec import on_vehicle
    from bfsitl.scenario.suite import default_jobs, run_suite

    if len(args.firmware) > 2:
        raise ScenarioError(
            "--firmware: give side A's build, and side B's if it differs "
            f"(got {len(args.firmware)})"
        )
    firmware_b = args.firmware[1] if len(args.firmware) == 2 else args.firmware[0]
    sides = (
        Side("A", args.firmware[0], tuple(args.a_cli), args.a_rc_rate),
        Side("B", firmware_b, tuple(args.b_cli), args.b_rc_rate),
    )
    scenarios = on_vehicle(find_scenarios(paths_or_library(args.paths)), args.vehicle)
    unknown = sorted(set(args.accept) - {s.name for s in scenarios})
    if unknown:
        raise ScenarioError(
            f"--accept {', '.join(unknown)}: no such scenario among "
            f"{', '.join(s.name for s in scenarios)}"
        )
    planned = plan_comparison(scenarios, sides, args.seeds, args.out)
    check_builds([entry.run for entry in planned], given=True)
    a, b = ((side.firmware, side.cli, side.rc_rate) for side in sides)
    if a == b:
        progress(
            "A and B are the same build, lines and RC link: every scenario should come out same"
        )
    replays = sum(seeds_for(s, args.seeds) < args.seeds for s in scenarios)
    progress(
        f"{len(planned)} runs: {len(scenarios)} scenario(s) on 2 sides, {args.seeds} seed(s) "
        f"each; files in {args.out}/"
        + (
            f" ({replays} replay(s) without gusts flown with one seed: they repeat bit for bit)"
            if replays
            else ""
        )
    )
    for side in sides:
        progress(side.title)
    started = time.monotonic()

    # Which side and seed a result is: its files' folder (both sides may fly one build).
    where = {entry.run.out_dir.resolve(): entry for entry in planned}

    def finished(result) -> None:  # type: ignore[no-untyped-def]
        summary = result.artifacts.get("summary")
        entry = where.get(Path(summary).parent.resolve()) if summary else None
        which = f" (side {entry.side}, seed {entry.seed})" if entry is not None else ""
        print(
            f"  ran {result.test_id}{which}: {result.verdict.value} ({result.wall_time_s:.1f} s)",
            flush=True,
        )

    jobs = args.jobs if args.jobs is not None else default_jobs(len(planned))
    suite = run_suite(
        [entry.run for entry in planned],
        jobs=jobs,
        speed=args.speed,
        plot=False,
        progress=progress if jobs == 1 else None,
        on_result=finished,
        ray_address=args.ray_address,
    )
    comparisons = compare_results(planned, suite.results, sides, args.accept)
    draw_overlays(comparisons, sides, args.out / "overlays")
    for line in comparison_lines(comparisons):
        print(line)
    summary = write_comparison_json(comparisons, sides, args.out / "compare.json")
    progress(f"compare.json: {summary}")
    if args.junit is not None:
        progress(f"JUnit XML: {write_comparison_junit(comparisons, sides, args.junit)}")
    if args.report is not None:
        progress(f"report: {write_comparison_report(comparisons, sides, args.report)}")
    progress(f"{len(planned)} runs in {time.monotonic() - started:.0f} s")
    if suite.interrupted:
        progress(suite.stop_line())
        return EXIT_INTERRUPTED
    failing = [c for c in comparisons if c.fails]
    unflown = [c for c in failing if c.change is Change.ERROR]
    different = [c for c in failing if c.change is not Change.ERROR]
    if different:
        # Only a difference can be expected; a run that could not be flown cannot be waived.
        progress(
            f"{len(different)} scenario(s) "
            f"{'/'.join(sorted({c.change.value for c in different}))}: "
            f"{', '.join(c.name for c in different)} (--accept NAME if expected)"
        )
    if unflown:
        progress(
            f"{len(unflown)} scenario(s) could not be judged (a run errored): "
            f"{', '.join(c.name for c in unflown)}; the reasons are above"
        )
    return EXIT_DIFFERENT if failing else EXIT_OK
