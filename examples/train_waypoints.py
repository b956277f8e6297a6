"""Train a course of waypoints through the real Betaflight with Stable-Baselines3 (CPU torch),
and race it against bfsitl's Autopilot.

    pip install torch==2.13.0 'bfsitl[sitl,learn]'   # torch: the CPU build (see pyproject)
    bfsitl firmware build --gps --lockstep
    python examples/train_waypoints.py --minutes 15 --out waypoints-run/

``bfsitl/Waypoints-v0`` gives the policy ``--count`` points in turn, each drawn within
``--horizontal-m`` of the start and 1.5 to 3 m up, the next one in the observation; it is paid
for the metres it closes on the point, charged for every step, and the episode ends at the
last point (:mod:`bfsitl.gym.tasks`).  The policy flies the FC's ANGLE mode through
:class:`bfsitl.gym.scaled.ScaledEnv` with ``--tilt-stick`` of the roll and pitch travel.
Training runs as ``examples/train_hover.py`` does; every checkpoint then flies the evaluation
course once.

The evaluation: the exported policy (ONNX, run with onnxruntime) against bfsitl's
:class:`~bfsitl.autopilot.Autopilot` (``goto`` each point in turn: a reference travelling at up
to 2 m/s with 1 m/s^2 ramps, so on 4 m legs it peaks at 2 m/s, and a stop at each point) and
the hand-written policy (:mod:`bfsitl.gym.baseline`, which
flies to the observation's point), all on the same laps: the course ``COURSE`` (never drawn
in training) ``--laps`` times, in still air, in a 3 m/s wind gusting 1.5, and with motor 1 at
75 %, then ``--courses`` random courses drawn from seeds training never used.  A point counts
as passed when the truth comes within 0.5 m of it, in order; the **lap time** runs from the
hand-over at the start (the Autopilot's: the end of its take-off) to the last point, and a
**miss** is a point not passed when the lap ended (a crash, the bounds, or 20 s; the
Autopilot is given 20 s a leg).

What it writes in ``--out``: ``learning_curve.csv``/``.png``, ``checkpoints/``,
``policy.zip``, ``policy.onnx``, ``laps.csv`` (a row per lap: condition, pilot, course, the
points passed, the lap time, why it ended) and ``evaluation.json`` (per condition and
pilot: laps completed, points missed, the lap times' median and 90th percentile).
``--smoke`` trains for a few hundred steps and flies one lap of each: CI runs it.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import train_hover as shared  # noqa: E402  (the training machinery the examples share)

import bfsitl.gym  # noqa: E402, F401  (registers the environments)
from bfsitl import Autopilot, launch_sitl  # noqa: E402
from bfsitl.backend.options import World  # noqa: E402
from bfsitl.errors import MissionError  # noqa: E402
from bfsitl.gym.baseline import hand_policy, hover_stick  # noqa: E402
from bfsitl.gym.env import DEFAULT_START_ALT_M, WaypointsEnv  # noqa: E402
from bfsitl.gym.random_vehicle import RandomVehicle  # noqa: E402
from bfsitl.gym.random_wind import RandomWind  # noqa: E402
from bfsitl.gym.scaled import ScaledEnv, StickLimits  # noqa: E402
from bfsitl.gym.snapshot import Vec3  # noqa: E402
from bfsitl.gym.tasks import REACHED_M, Waypoints  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics.wind import Wind  # noqa: E402
from bfsitl.vehicles import load_vehicle  # noqa: E402

#: The evaluation course: a 4 m square with a climb and a descent, back to the start; the
#: legs are longer than training's draws put most points apart, and it is never drawn.
COURSE: tuple[Vec3, ...] = ((4.0, 0.0, 2.0), (4.0, 4.0, 3.0), (0.0, 4.0, 2.0), (0.0, 0.0, 1.5))
#: The evaluation's seeds start here; training draws its own, never these.
EVAL_SEED = 30_000
#: A lap's time limit: the environment's episode (20 s); the Autopilot gets it per leg.
LAP_S = 20.0
WIND = Wind.from_direction(3.0, 0.0, 1.5)
WEAK_MOTOR, WEAK_FRACTION = 1, 0.75
#: The conditions the course is flown in, by the name the outputs give them: the wind, and
#: whether motor 1 is weak.
CONDITIONS: dict[str, tuple[Wind | None, bool]] = {
    "still air": (None, False),
    "wind 3 m/s, gusts 1.5 m/s": (WIND, False),
    "motor 1 at 75 %": (None, True),
}
RANDOM = "random courses, still air"

#: A lap's pilot: flies the environment (the learned and hand-written policies) or a SITL of
#: its own (the Autopilot); gets the condition, the course and the seed; returns the lap.
Pilot = Callable[[str, tuple[Vec3, ...], int], dict[str, Any]]


def passed(course: tuple[Vec3, ...], track: list[tuple[float, Vec3]]) -> list[float]:
    """The times at which ``track`` (time, north/east/up) passed the course's points, in
    order, each within REACHED_M: one per point passed."""
    times: list[float] = []
    for time_s, position in track:
        if len(times) == len(course):
            break
        if math.dist(position, course[len(times)]) <= REACHED_M:
            times.append(time_s)
    return times


def lap_row(course: tuple[Vec3, ...], times: list[float], ended: str | None) -> dict[str, Any]:
    done = len(times) == len(course)
    return {
        "passed": len(times),
        "missed": len(course) - len(times),
        "lap_s": round(times[-1], 2) if done else None,
        "ended_because": ended,
    }


class EnvPilot:
    """Laps of a policy through the environment (one per condition, made when first asked)."""

    def __init__(self, args: argparse.Namespace, policy: shared.Policy, name: str) -> None:
        self.args, self.policy, self.name = args, policy, name
        self.envs: dict[str, WaypointsEnv] = {}

    def env(self, condition: str) -> WaypointsEnv:
        if condition not in self.envs:
            wind, weak = CONDITIONS.get(condition, (None, False))
            self.envs[condition] = WaypointsEnv(
                sitl=SitlLaunch(
                    firmware=self.args.firmware,
                    workdir=self.args.out / "sitl" / f"{self.name}-{len(self.envs)}",
                ),
                control_hz=self.args.control_hz,
                max_episode_steps=round(LAP_S * self.args.control_hz),
                course=COURSE,
                world=World(quad=load_vehicle(self.args.vehicle), wind=wind),
                disturbances=weak_motor if weak else None,
            )
        return self.envs[condition]

    def __call__(self, condition: str, course: tuple[Vec3, ...], seed: int) -> dict[str, Any]:
        env = self.env(condition)
        observation, info = env.reset(seed=seed, options={"course": course})
        track: list[tuple[float, Vec3]] = []
        while True:
            observation, _reward, terminated, truncated, info = env.step(self.policy(observation))
            truth = info["truth"]
            track.append((info["time_s"], (truth["north_m"], truth["east_m"], truth["alt_m"])))
            if terminated or truncated:
                return lap_row(course, passed(course, track), info["ended_because"])

    def close(self) -> None:
        for env in self.envs.values():
            env.close()


def weak_motor(surface: Any, _time_s: float) -> None:
    surface.set_motor_thrust(WEAK_MOTOR, WEAK_FRACTION)


def autopilot_pilot(args: argparse.Namespace) -> Pilot:
    """Laps of the Autopilot: a SITL of its own per lap, ``goto`` each point in turn."""

    def lap(condition: str, course: tuple[Vec3, ...], seed: int) -> dict[str, Any]:
        wind, weak = CONDITIONS.get(condition, (None, False))
        with launch_sitl(
            args.firmware, vehicle=args.vehicle, wind=wind, seed=seed, workdir=None
        ) as vehicle:
            pilot = Autopilot(vehicle)
            pilot.takeoff(DEFAULT_START_ALT_M)  # where the environment's laps start
            if weak:
                vehicle.disturbances.set_motor_thrust(WEAK_MOTOR, WEAK_FRACTION)
            began_s, ended = vehicle.time_s, None
            try:
                for north, east, up in course:
                    pilot.goto(north, east, up, timeout_s=LAP_S)
            except MissionError as exc:  # a timeout, a crash, a disarm
                ended = str(exc).splitlines()[0]
            track = [
                (row.time_s - began_s, (row.sim_north_m, row.sim_east_m, row.sim_alt_m))
                for row in pilot.rows
                if row.time_s >= began_s
            ]
        return lap_row(course, passed(course, track), ended)

    return lap


def random_courses(args: argparse.Namespace) -> list[tuple[Vec3, ...]]:
    """``--courses`` courses drawn as training draws them, from the evaluation's seeds."""
    task = Waypoints(count=args.count, horizontal_m=args.horizontal_m)
    courses = []
    for number in range(args.courses):
        task.reset(np.random.default_rng(EVAL_SEED + number))
        courses.append(tuple(task.targets))
    return courses


def race(args: argparse.Namespace, pilots: dict[str, Pilot]) -> list[dict[str, Any]]:
    """Every pilot on every lap: the course in each condition, then the random courses."""
    laps = [(c, COURSE, EVAL_SEED + n) for c in CONDITIONS for n in range(args.laps)]
    laps += [(RANDOM, course, EVAL_SEED + n) for n, course in enumerate(random_courses(args))]
    rows = []
    for name, pilot in pilots.items():
        for number, (condition, course, seed) in enumerate(laps):
            row = {"condition": condition, "pilot": name, "lap": number, "seed": seed}
            rows.append({**row, **pilot(condition, course, seed)})
        print(f"[race] {name}: {summarise(r for r in rows if r['pilot'] == name)}", flush=True)
    return rows


def summarise(rows: Any) -> dict[str, Any]:
    rows = list(rows)
    times = [r["lap_s"] for r in rows if r["lap_s"] is not None]
    quantiles = np.percentile(times, [50, 90]).round(2).tolist() if times else None
    return {
        "laps": len(rows),
        "completed": len(times),
        "missed_points": sum(r["missed"] for r in rows),
        "lap_s_median_p90": quantiles,
    }


def judge_checkpoints(args: argparse.Namespace) -> list[dict[str, Any]]:
    """Each checkpoint flies the course once in still air."""
    verdicts = []
    env = WaypointsEnv(
        sitl=SitlLaunch(firmware=args.firmware, workdir=args.out / "sitl" / "checkpoints"),
        control_hz=args.control_hz,
        max_episode_steps=round(LAP_S * args.control_hz),
        course=COURSE,
        world=World(quad=load_vehicle(args.vehicle)),
    )
    scaled = ScaledEnv(env, args.limits)
    try:
        for path in sorted((args.out / "checkpoints").glob("*.zip"), key=shared.checkpoint_wall_s):
            policy = shared.learned_policy(shared.model_class(args.method).load(path, device="cpu"))
            observation, info = scaled.reset(seed=EVAL_SEED)
            while True:
                observation, _r, terminated, truncated, info = scaled.step(policy(observation))
                if terminated or truncated:
                    break
            done = info["waypoint"] + (info["ended_because"] is None and not truncated)
            verdicts.append(
                {
                    "checkpoint": path.name,
                    "wall_s": shared.checkpoint_wall_s(path),
                    "flights": len(COURSE),
                    "held": int(done),  # the curve's axis: points passed
                    "lap_s": round(info["time_s"], 2) if done == len(COURSE) else None,
                }
            )
            print(f"[evaluate] {path.name}: {verdicts[-1]}", flush=True)
    finally:
        env.close()
    return verdicts


def export(model: Any, args: argparse.Namespace) -> Any:
    from bfsitl.gym.onnx_policy import OnnxPolicy
    from bfsitl.gym.policy_export import export_policy

    path = export_policy(
        model,
        args.out / "policy.onnx",
        limits=args.limits,
        hover_throttle=hover_stick(load_vehicle(args.vehicle)),
        control_hz=args.control_hz,
        mode="angle",
        description=f"bfsitl/Waypoints-v0, {args.method.upper()}, examples/train_waypoints.py",
    )
    return OnnxPolicy(path)


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    shared.add_learner_arguments(
        parser,
        control_hz=100.0,
        gamma=0.99,
        lr_schedule="linear",
        minutes=15.0,
        checkpoint_s=60.0,
        n_steps=1024,
    )
    parser.add_argument("--vehicle", default="iris", help="a vehicle's name or profile file")
    parser.add_argument(
        "--vehicles",
        default=None,
        metavar="NAME,NAME,...",
        help="train on a quad drawn per episode from these (the evaluation flies --vehicle)",
    )
    parser.add_argument("--count", type=int, default=4, help="points per training course")
    parser.add_argument("--horizontal-m", type=float, default=3.0, help="training's spread")
    parser.add_argument("--tilt-stick", type=float, default=0.6, help="of the roll/pitch travel")
    parser.add_argument("--laps", type=int, default=10, help="laps of the course per condition")
    parser.add_argument("--courses", type=int, default=30, help="random courses to race")
    parser.add_argument("--train-wind-m-s", type=float, default=0.0)
    parser.add_argument("--out", type=Path, default=Path("waypoints-run"))
    parser.add_argument("--smoke", action="store_true", help="a few hundred steps, one lap each")
    parser.add_argument("--resume", type=Path, default=None, metavar="DIR")
    parser.add_argument("--evaluate-only", action="store_true")
    args = parser.parse_args()
    if args.learning_rate is None:
        args.learning_rate = 3e-4 if args.method == "ppo" else 1e-3
    args.env_id, args.episode_s = "bfsitl/Waypoints-v0", LAP_S
    args.limits = StickLimits(tilt_stick=args.tilt_stick, throttle_span=0.5)
    args.env_options = {
        "count": args.count,
        "horizontal_m": args.horizontal_m,
        "world": World(quad=load_vehicle(args.vehicle)),
    }
    if args.vehicles:
        args.env_options["random_vehicle"] = RandomVehicle.named(*args.vehicles.split(","))
    if args.train_wind_m_s > 0.0:
        args.env_options["random_wind"] = RandomWind(args.train_wind_m_s, args.train_wind_m_s / 2)
    if args.smoke:
        args.steps, args.n_steps, args.laps, args.courses = 256, 64, 1, 1
        args.minutes, args.checkpoint_s = 0.0, 1e9
    return args


def main() -> int:
    args = parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    model, episodes, train_s = shared.train_or_load(args)
    title = f"bfsitl/Waypoints-v0 ({args.vehicle}) through Betaflight 4.6.0 ({args.method.upper()})"
    shared.write_curve(episodes, [], args.out, title)
    exported = export(model, args)
    hover = hover_stick(load_vehicle(args.vehicle))
    env_pilots = {
        "learned": EnvPilot(args, exported, "learned"),
        "hand-written": EnvPilot(
            args, lambda o: hand_policy(o, hover_throttle=hover), "hand-written"
        ),
    }
    pilots: dict[str, Pilot] = {
        **env_pilots,
        "Autopilot": autopilot_pilot(args),
    }
    try:
        verdicts = judge_checkpoints(args)
        rows = race(args, pilots)
    finally:
        for pilot in env_pilots.values():
            pilot.close()
    with (args.out / "laps.csv").open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    shared.write_curve(episodes, verdicts, args.out, title, verdict_label="course points passed")
    conditions = [*CONDITIONS, RANDOM]
    summary = {
        "training": {
            **shared.training_figures(args, model, episodes, train_s),
            "vehicle": args.vehicle,
            "vehicles": args.vehicles.split(",") if args.vehicles else [args.vehicle],
            "count": args.count,
            "horizontal_m": args.horizontal_m,
            "tilt_stick": args.tilt_stick,
            "train_wind_m_s": args.train_wind_m_s,
        },
        "course": COURSE,
        "evaluation_seed": EVAL_SEED,
        "checkpoints": verdicts,
        "evaluation": {
            condition: {
                name: summarise(
                    r for r in rows if r["condition"] == condition and r["pilot"] == name
                )
                for name in pilots
            }
            for condition in conditions
        },
    }
    shared.write_summary(args.out, summary, exported, ("training", "evaluation"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
