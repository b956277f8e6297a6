"""The figures in docs/ (the PNGs the pages show), each made by the command its page quotes
(a `bfsitl` command, a benchmark, a few lines of Python) in a folder of its own, so that they
cannot go stale.  tools/regenerate_docs.py makes them (and the pages' sample outputs)."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from docs_running import (
    CHROMIUM,
    CONFIGURATOR,
    GAZEBO,
    GYMNASIUM,
    LOCKSTEP_46,
    LOCKSTEP_MASTER,
    REPO,
    ROMA_LOG,
    STOCK,
    Context,
    MakeFailed,
    Need,
    benchmark,
    bfsitl,
    compare_run,
    demo_run,
    excite_fit_run,
    hover_run_file,
    install,
    one,
    png,
    real_log,
    recover_run_file,
    roma_replay_run,
    run,
    square_run,
    waypoints_run_file,
)


@dataclass(frozen=True)
class Figure:
    """``docs/NAME.png``: the command that makes it (for --list and the docs), what it needs,
    and the function that makes it in a folder and returns the PNG's path there."""

    name: str
    how: str
    needs: tuple[Need, ...]
    make: Callable[[Context, Path], Path]

    def regenerate(self, ctx: Context, work: Path, out: Path) -> str:
        """Make the PNG in ``work`` and copy it to ``out/docs/NAME.png``; what changed."""
        target = out / "docs" / f"{self.name}.png"
        target.parent.mkdir(parents=True, exist_ok=True)
        return f"docs/{target.name} ({install(self.make(ctx, work), target)})"


# -- the figures -----------------------------------------------------------------------------


def make_flight(ctx: Context, work: Path) -> Path:
    return png(demo_run(ctx) / "flight.png")


def make_altitude_step(ctx: Context, work: Path) -> Path:
    run(benchmark("altitude.py", "--repeats", "5", "--plot", "altitude-step.png"), work)
    return png(work / "altitude-step.png")


def make_altitude_step_firmwares(ctx: Context, work: Path) -> Path:
    argv = benchmark(
        "altitude.py",
        *("--controllers", "tutorial-pid,fused", "--repeats", "3"),
        *("--firmware", "", "--firmware", ctx.firmware_master),
        *("--plot", "altitude-step-firmwares.png"),
    )
    run(argv, work)
    return png(work / "altitude-step-firmwares.png")


def make_square(ctx: Context, work: Path) -> Path:
    return png(square_run(ctx) / "square.png")


def make_scenario_gps_rescue(ctx: Context, work: Path) -> Path:
    argv = bfsitl("scenario", "run", "gps-rescue-home", "--firmware", ctx.firmware_46)
    run([*argv, "--plot", "--out", "runs"], work)
    return png(one(work / "runs", "*/gps-rescue-home/plot.png"))


def make_compare_autoland(ctx: Context, work: Path) -> Path:
    return png(compare_run(ctx) / "out" / "overlays" / "rc-loss-hover-autoland.png")


def make_compare_report(ctx: Context, work: Path) -> Path:
    page = compare_run(ctx) / "report" / "index.html"
    if not page.is_file():
        raise MakeFailed("the compare run wrote no report")
    shot = work / "screenshot.png"
    chromium = [
        *("chromium", "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"),
        *("--window-size=1280,1500", f"--screenshot={shot}", page.as_uri()),
    ]
    run(chromium, work, timeout_s=120)
    return shrink(png(shot), work / "compare-report.png")


def shrink(shot: Path, out: Path, scale: float = 0.7, colours: int = 64) -> Path:
    """The screenshot at ``scale`` with ``colours`` colours, to keep the PNG small."""
    from PIL import Image

    with Image.open(shot) as image:
        size = (round(image.width * scale), round(image.height * scale))
        small = image.convert("RGB").resize(size, Image.Resampling.LANCZOS)
    small.quantize(colors=colours).save(out, optimize=True)
    return png(out)


def make_log_fit_sitl(ctx: Context, work: Path) -> Path:
    return png(excite_fit_run(ctx) / "my-quad" / "fit-report.png")


def make_log_fit_cs110(ctx: Context, work: Path) -> Path:
    log = ctx.real_logs / "cs110-3.1.5-smooth.bbl"
    # 1: the profile does not replay the log (untrusted), which is what the page shows.
    run(bfsitl("log", "fit", str(log), "--mass-g", "110", "--out", "fit"), work, ok=(0, 1))
    return png(work / "fit" / "fit-report.png")


def make_log_replay_roma(ctx: Context, work: Path) -> Path:
    return png(roma_replay_run(ctx) / "replay" / "replay-report.png")


def make_gym_render(ctx: Context, work: Path) -> Path:
    """Step 150 of a Waypoints episode (seed 3) flown by the hand-written policy."""
    import gymnasium
    import numpy as np
    from PIL import Image

    import bfsitl.gym  # noqa: F401  (registers the environments)
    from bfsitl.gym.baseline import hand_policy
    from bfsitl.mission.session import SitlLaunch

    env = gymnasium.make(
        "bfsitl/Waypoints-v0",
        render_mode="rgb_array",
        sitl=SitlLaunch(firmware=ctx.firmware_46, workdir=work / "sitl"),
    )
    try:
        observation, _ = env.reset(seed=3)
        for _ in range(150):
            observation, _, terminated, truncated, _ = env.step(hand_policy(observation))
            if terminated or truncated:
                raise MakeFailed("the episode ended before step 150")
        frame = env.render()
    finally:
        env.close()
    if not isinstance(frame, np.ndarray):
        raise MakeFailed(f"render() gave {type(frame).__name__}, not a frame")
    Image.fromarray(frame).save(work / "gym-render.png")
    return png(work / "gym-render.png")


def copy_from_hover_run(name: str) -> Callable[[Context, Path], Path]:
    def make(ctx: Context, work: Path) -> Path:
        assert ctx.hover_run is not None
        return png(ctx.hover_run / name)

    return make


def copy_recover_curve(ctx: Context, work: Path) -> Path:
    assert ctx.recover_run is not None
    return png(ctx.recover_run / "learning_curve.png")


def make_gazebo_parity(ctx: Context, work: Path) -> Path:
    plot = work / "gazebo-parity.png"
    argv = benchmark("gazebo_parity.py", "--repeats", "1", "--out", str(work / "flights"))
    run([*argv, "--plot", str(plot)], work, timeout_s=900)
    return png(plot)


def copy_waypoints_curve(ctx: Context, work: Path) -> Path:
    assert ctx.waypoints_run is not None
    return png(ctx.waypoints_run / "learning_curve.png")


def make_configurator_flight(ctx: Context, work: Path) -> Path:
    shot = work / "configurator-flight.png"
    env = {
        **os.environ,
        "BFSITL_SAVE_SCREENSHOT": str(shot),
        "BFSITL_REQUIRE_SITL": "1",  # a skip inside the test is a failure here, with its reason
        "PYTHONDONTWRITEBYTECODE": "1",
    }
    test = REPO / "tests" / "integration" / "test_watch_flight_sitl.py"
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(test)]
    run([*argv, "-k", "master", "--basetemp", str(work / "pytest")], REPO, env=env)
    return png(shot)


FIGURES = (
    Figure(
        "flight",
        "bfsitl fly --log flight.csv --plot flight.png (make demo; real time)",
        (STOCK,),
        make_flight,
    ),
    Figure(
        "square",
        "bfsitl fly --firmware MASTER --mission square --wind 3 --gusts 1.5 --gps-noise",
        (LOCKSTEP_MASTER,),
        make_square,
    ),
    Figure(
        "altitude-step",
        "python benchmarks/altitude.py --repeats 5 --plot (15 flights, real time)",
        (STOCK,),
        make_altitude_step,
    ),
    Figure(
        "altitude-step-firmwares",
        "python benchmarks/altitude.py --controllers tutorial-pid,fused --repeats 3 "
        '--firmware "" --firmware MASTER --plot (12 flights, real time)',
        (STOCK, LOCKSTEP_MASTER),
        make_altitude_step_firmwares,
    ),
    Figure(
        "scenario-gps-rescue",
        "bfsitl scenario run gps-rescue-home --firmware 4.6 --plot (its plot.png)",
        (LOCKSTEP_46,),
        make_scenario_gps_rescue,
    ),
    Figure(
        "compare-autoland",
        "bfsitl scenario compare --firmware 4.6 --b-cli 'set ap_hover_throttle = 1275' "
        "--seeds 2 --jobs 2 rc-loss-hover-autoland rc-loss-forward-autoland (its overlay)",
        (LOCKSTEP_46,),
        make_compare_autoland,
    ),
    Figure(
        "compare-report",
        "the same compare's --report page, chromium --headless at 1280x1500, 70 %, 64 colours",
        (LOCKSTEP_46, CHROMIUM),
        make_compare_report,
    ),
    Figure(
        "log-fit-sitl",
        "bfsitl scenario run tests/data/fit/excite-5inch.toml --firmware 4.6, then bfsitl log "
        "fit LOG00001.BF --mass-g 650 --name my-5inch",
        (LOCKSTEP_46,),
        make_log_fit_sitl,
    ),
    Figure(
        "log-fit-cs110",
        "bfsitl log fit cs110-3.1.5-smooth.bbl --mass-g 110",
        (real_log("cs110-3.1.5-smooth.bbl"),),
        make_log_fit_cs110,
    ),
    Figure(
        "log-replay-roma",
        "bfsitl log replay roma-f5-4.2.9.bbl --vehicle 5inch-freestyle --firmware 4.6",
        (real_log(ROMA_LOG), LOCKSTEP_46),
        make_log_replay_roma,
    ),
    Figure(
        "gym-render",
        "bfsitl/Waypoints-v0 on 4.6, seed 3, hand_policy, env.render() at step 150",
        (LOCKSTEP_46, GYMNASIUM),
        make_gym_render,
    ),
    Figure(
        "gym-learning-curve",
        "examples/train_hover.py --minutes 5: learning_curve.png",
        (hover_run_file("learning_curve.png"),),
        copy_from_hover_run("learning_curve.png"),
    ),
    Figure(
        "gym-recover-curve",
        "examples/train_recover.py --minutes 10 (ACRO, IRIS): learning_curve.png",
        (recover_run_file("learning_curve.png"),),
        copy_recover_curve,
    ),
    Figure(
        "gym-waypoints-curve",
        "examples/train_waypoints.py --minutes 15 (IRIS): learning_curve.png",
        (waypoints_run_file("learning_curve.png"),),
        copy_waypoints_curve,
    ),
    Figure(
        "gym-evaluation",
        "examples/train_hover.py --minutes 5: evaluation.png",
        (hover_run_file("evaluation.png"),),
        copy_from_hover_run("evaluation.png"),
    ),
    Figure(
        "gazebo-parity",
        "python benchmarks/gazebo_parity.py --repeats 1 --plot gazebo-parity.png",
        (STOCK, GAZEBO),
        make_gazebo_parity,
    ),
    Figure(
        "configurator-flight",
        "tests/integration/test_watch_flight_sitl.py on master with BFSITL_SAVE_SCREENSHOT",
        (CONFIGURATOR,),
        make_configurator_flight,
    ),
)
