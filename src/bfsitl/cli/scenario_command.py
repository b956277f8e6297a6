"""``bfsitl scenario``: run scenario files as a regression suite, list them, list the faults."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.cli.arg_types import (
    add_vehicle_argument,
    number_in,
    parse_speed,
    whole_number_at_least,
)
from bfsitl.cli.compare_command import add_compare_parser
from bfsitl.cli.scenario_inputs import check_builds, paths_or_library
from bfsitl.cli.target import progress

if TYPE_CHECKING:
    from bfsitl.scenario.result import PlotWhen

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_INTERRUPTED = 130
DEFAULT_OUT = "scenario-runs"

_MARK = {
    "passed": "PASS",
    "failed": "FAIL",
    "known failure": "KNOWN",
    "error": "ERROR",
    "skipped": "SKIP",
}


def add_scenario_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    scenario = sub.add_parser(
        "scenario",
        help="run failsafe / fault scenarios as a regression suite",
        description="Scenarios: a flight, faults at given times (RC loss, GPS loss, a weak "
        "motor, sensor errors, wind) and expectations checked on the simulated "
        "truth, the FC's telemetry and its own blackbox. See docs/scenarios.md.",
    )
    actions = scenario.add_subparsers(dest="scenario_action", metavar="ACTION", required=True)

    run = actions.add_parser(
        "run",
        help="fly scenario files and judge them",
        description="Fly each scenario on each firmware, each in its own SITL and network "
        "namespace. Exit 0 when every run passed, was a known failure (a firmware "
        "defect the scenario declares, and it happened) or was skipped (a fault the "
        "firmware cannot express, a GPS scenario on a build without GPS), 1 "
        "otherwise.",
        epilog="Examples:\n  bfsitl scenario run                       the shipped library, on the "
        "builds it names that you have\n"
        "  bfsitl scenario run my-scenarios/ --firmware 4.6.0-gps-lockstep --jobs 2 "
        "--junit results.xml --report report/",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    run.add_argument(
        "paths",
        nargs="*",
        metavar="FILE_OR_DIR",
        help="scenario files (.toml), directories of them, or names of the "
        "shipped library's scenarios (default: the "
        "library shipped with bfsitl; `bfsitl scenario list` shows it)",
    )
    add_vehicle_argument(run, per_scenario=True)
    run.add_argument(
        "--firmware",
        action="append",
        default=[],
        metavar="NAME",
        help="a cached build's name or a SITL binary; repeat for several "
        "(default: the builds each file names that are built; the others "
        "are named, with the command that builds them)",
    )
    run.add_argument(
        "--jobs",
        type=whole_number_at_least(1),
        default=None,
        metavar="N",
        help="runs side by side, each in its own process (default: one per core, "
        "at most one per run: a SITL wants most of one); 1 runs them here, one "
        "after the other, with every event shown",
    )
    run.add_argument(
        "--ray",
        metavar="ADDRESS",
        dest="ray_address",
        help="run on a Ray cluster instead (e.g. 127.0.0.1:6379 from `ray start "
        "--head`; 'auto' finds a local one): one task per run, one CPU "
        "each; the firmware travels to the nodes and each run's files come "
        "back to --out; needs the ray extra",
    )
    run.add_argument(
        "--ray-retries",
        type=whole_number_at_least(0),
        default=2,
        metavar="N",
        help="submit a run again at most N times when its Ray worker or node is "
        "lost (default 2; a run that fails on its own is never retried)",
    )
    run.add_argument(
        "--ray-max-mb",
        type=number_in(0.1, None, "MB"),
        default=256.0,
        metavar="MB",
        help="the most a run's files may bring home from a Ray node, compressed (default 256)",
    )
    run.add_argument(
        "--junit",
        type=Path,
        metavar="FILE",
        help="write the results as JUnit XML (one suite per firmware)",
    )
    run.add_argument(
        "--report",
        type=Path,
        metavar="DIR",
        help="write an HTML report (index.html, with the plots) into DIR",
    )
    run.add_argument(
        "--out",
        type=Path,
        default=Path(DEFAULT_OUT),
        metavar="DIR",
        help=f"where each run's files go, DIR/FIRMWARE/SCENARIO/ (default "
        f"{DEFAULT_OUT}/): CSV, plot, result.json, blackbox, the SITL's "
        f"log and run directory",
    )
    run.add_argument(
        "--speed",
        type=parse_speed,
        default=None,
        metavar="X",
        help="x real time (default: as fast as it goes on a lockstep build, real "
        "time on a stock one)",
    )
    plots = run.add_mutually_exclusive_group()
    plots.add_argument(
        "--plot",
        action="store_true",
        help="draw every run's plots (plot.png, blackbox.png); by default only a run that "
        "failed or errored draws them, and every run with --report",
    )
    plots.add_argument("--no-plot", action="store_true", help="no plots, not even for a failure")
    run.add_argument(
        "--timings",
        action="store_true",
        help="print where each run's wall time went (start-up, arming, flight, stop, "
        "blackbox, analysers, plots, files), per run and summed",
    )
    run.add_argument(
        "--mcap",
        action="store_true",
        help="write each run's flight as MCAP too (flight.mcap, Foxglove's "
        "schemas; the foxglove extra)",
    )
    run.set_defaults(func=cmd_scenario_run)

    show = actions.add_parser(
        "list",
        help="check scenario files and show what they do",
        description="Read and check scenario files without flying.",
    )
    show.add_argument(
        "paths",
        nargs="*",
        metavar="FILE_OR_DIR",
        help="scenario files, directories or library names (default: the shipped library)",
    )
    show.set_defaults(func=cmd_scenario_list)

    faults = actions.add_parser(
        "faults",
        help="the fault catalog, and where each works",
        description="Print the fault kinds and their parameters.",
    )
    faults.set_defaults(func=cmd_scenario_faults)
    add_compare_parser(actions)


def cmd_scenario_run(args: argparse.Namespace) -> int:
    from bfsitl.scenario.load import find_scenarios
    from bfsitl.scenario.spec import on_vehicle
    from bfsitl.scenario.suite import default_jobs, plan_runs, run_suite

    scenarios = on_vehicle(find_scenarios(paths_or_library(args.paths)), args.vehicle)
    runs = plan_runs(scenarios, args.firmware, args.out)
    if not args.firmware:
        runs = _runs_on_made_builds(runs)
    check_builds(runs, given=bool(args.firmware))
    jobs = args.jobs if args.jobs is not None else default_jobs(len(runs))
    progress(
        f"{len(runs)} runs of {len(scenarios)} scenarios"
        + (f", {jobs} at a time" if jobs > 1 and not args.ray_address else "")
        + f"; files in {args.out}/"
    )
    started = time.monotonic()

    def finished(result) -> None:  # type: ignore[no-untyped-def]
        mark = _MARK[result.verdict.value]
        print(
            f"{mark:5} {result.test_id}  {result.sim_time_s:6.1f} s simulated in "
            f"{result.wall_time_s:5.1f} s  {result.reason}",
            flush=True,
        )

    suite = run_suite(
        runs,
        jobs=jobs,
        speed=args.speed,
        plot=_plot_when(args),
        progress=progress if jobs == 1 or args.ray_address else None,
        on_result=finished,
        ray_address=args.ray_address,
        mcap=args.mcap,
        ray_retries=args.ray_retries,
        ray_max_mb=args.ray_max_mb,
    )
    results, interrupted = suite.results, suite.interrupted
    wall_s = time.monotonic() - started
    outputs_started = time.monotonic()
    _write_outputs(args, results)
    if args.timings:
        _print_timings(results, time.monotonic() - outputs_started)
    counts = {
        v: sum(1 for r in results if r.verdict.value == v)
        for v in ("passed", "failed", "known failure", "error", "skipped")
    }
    simulated = sum(r.sim_time_s for r in results)
    known = f"{counts['known failure']} known failures, " if counts["known failure"] else ""
    print(
        f"{counts['passed']} passed, {counts['failed']} failed, {known}{counts['error']} errors, "
        f"{counts['skipped']} skipped; {simulated:.0f} s simulated in {wall_s:.0f} s "
        f"({simulated / wall_s if wall_s > 0 else 0:.1f}x real time)"
    )
    if interrupted:
        progress(suite.stop_line())
        return EXIT_INTERRUPTED
    return EXIT_OK if counts["failed"] == counts["error"] == 0 else EXIT_FAILED


def _print_timings(results: list, outputs_s: float) -> None:  # type: ignore[type-arg]
    from bfsitl.scenario.timings import timings_table

    print("\nwhere the wall time went, seconds (per run, as each worker spent it):")
    rows = [(r.test_id, r.timings_s, r.sim_time_s) for r in results if r.timings_s]
    for line in timings_table(rows):
        print(line)
    print(f"the suite's JUnit and report: {outputs_s:.2f} s")


def _plot_when(args: argparse.Namespace) -> PlotWhen:
    """Every run's plots when asked for (``--plot``) or for the report, which shows them;
    none with ``--no-plot``; else only a run that failed or errored draws them."""
    if args.no_plot:
        return False
    return True if args.plot or args.report is not None else "failed"


def _write_outputs(args: argparse.Namespace, results: list) -> None:  # type: ignore[type-arg]
    if args.junit is not None:
        from bfsitl.scenario.junit import write_junit

        progress(f"JUnit XML: {write_junit(results, args.junit)}")
    if args.report is not None:
        from bfsitl.scenario.report import write_report

        progress(f"report: {write_report(results, args.report)}")


#: How each build a shipped scenario names is made (master comes from the user's clone).
_HOW_TO_BUILD = {
    "master-lockstep": "bfsitl firmware build --git https://github.com/betaflight/betaflight "
    "--ref master --lockstep --name master-lockstep",
    "4.6.0-gps-lockstep": "bfsitl firmware build --gps --lockstep",
    "4.6.0-lockstep": "bfsitl firmware build --lockstep",
}


def _runs_on_made_builds(runs: list) -> list:  # type: ignore[type-arg]
    """The runs on builds the files name that exist; one line for each one that does not.

    None made at all is an error that says how to make one."""
    from bfsitl.errors import FirmwareNotFoundError, ScenarioError
    from bfsitl.scenario.suite import split_by_build
    from bfsitl.sitl.firmware import find_firmware

    def is_built(name: str) -> bool:
        try:
            find_firmware(name)
        except FirmwareNotFoundError:
            return False
        return True

    kept, missing = split_by_build(runs, is_built)
    for name in missing:
        how = _HOW_TO_BUILD.get(name, "bfsitl firmware build ... --name " + name)
        progress(f"not running on {name}: not built (`{how}` makes it)")
    if not kept:
        wanted = ", ".join(missing)
        raise ScenarioError(
            f"none of the builds the scenarios name ({wanted}) is built: "
            f"`{_HOW_TO_BUILD['4.6.0-gps-lockstep']}` makes the 4.6.0 one, "
            f"or give --firmware NAME (`bfsitl firmware list` shows the "
            f"builds)"
        )
    return kept


def cmd_scenario_list(args: argparse.Namespace) -> int:
    from bfsitl.scenario.load import find_scenarios

    for scenario in find_scenarios(paths_or_library(args.paths)):
        firmware = ", ".join(scenario.firmware) or "(give --firmware)"
        print(f"{scenario.name}  [{scenario.where}]  {scenario.duration_s:g} s on {firmware}")
        if scenario.description:
            print("    " + " ".join(scenario.description.split()))
        for spec in scenario.faults:
            params = ", ".join(f"{k}={v!r}" for k, v in spec.params)
            lasts = f" for {spec.duration_s:g} s" if spec.duration_s is not None else ""
            print(
                f"    fault at {spec.at_s:g} s{lasts}: {spec.kind}"
                + (f" ({params})" if params else "")
            )
        for key, value in scenario.expect:
            print(f"    expect {key} = {value!r}")
        for known in scenario.known_failures:
            on = f" on {known.generation}" if known.generation else ""
            print(f"    known failure{on}: {known.finding}: {known.why}")
    return EXIT_OK


def cmd_scenario_faults(_args: argparse.Namespace) -> int:
    from bfsitl.scenario import faults

    doc = faults.__doc__ or ""
    print(doc.strip(), file=sys.stdout)
    return EXIT_OK
