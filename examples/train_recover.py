"""Train a recovery from throws through the real Betaflight with Stable-Baselines3 (CPU torch).

    pip install torch==2.13.0 'bfsitl[sitl,learn]'   # torch: the CPU build (see pyproject)
    bfsitl firmware build --gps --lockstep
    python examples/train_recover.py --mode acro --minutes 10 --out recover-run/

``bfsitl/Recover-v0`` throws the armed quad at 10 m, tilted up to upside down, moving and
spinning, its rotors stopped (:mod:`bfsitl.gym.throws`); the policy must stop the fall and
hold the point of the throw.  ``--mode angle`` flies the sticks in the FC's ANGLE mode (the FC
levels the quad itself; the policy mostly chooses the throttle), ``--mode acro`` in rate mode
(the policy must right the quad itself).  The policy sees the environment through
:class:`bfsitl.gym.scaled.ScaledEnv` with the sticks' whole travel (a recovery needs it).
Training runs as ``examples/train_hover.py`` does (the same learner, vector environment and
checkpoints); every checkpoint is then thrown ``--checkpoint-throws`` times, and the last
policy, exported to ONNX and run with onnxruntime, ``--throws`` times from seeds training
never drew, beside two yardsticks on the same throws: the sticks centred at the hover
throttle (in ANGLE mode the FC's own levelling) and the hand-written hover policy
(:mod:`bfsitl.gym.baseline`); all three in still air, then in what training never had: a
3 m/s wind with 1.5 m/s gusts, and motor 1 at 75 % of its thrust.  ``--vehicle`` trains
another quad (``5inch-freestyle``), ``--train-wind-m-s`` trains in a wind drawn per episode
(:class:`bfsitl.gym.random_wind.RandomWind`), ``--vehicles`` on a quad drawn per episode
(:class:`bfsitl.gym.random_vehicle.RandomVehicle`, with ``--mass-spread`` and
``--thrust-spread`` about each); ``--eval-vehicles`` adds throws of other quads in still air
(one training never flew: a profile ``bfsitl log fit`` made from a real log);
``--evaluate-only`` throws the policy a run left in ``--out`` again.

What it writes in ``--out``: ``learning_curve.csv``/``.png`` (each training episode's return
against wall time, each checkpoint's recoveries), ``checkpoints/``, ``policy.zip``,
``policy.onnx``, ``throws.csv`` (one row per evaluation throw, condition and policy: the
throw, recovered or not, after how long, the height lost, why it ended) and
``evaluation.json`` (the recoveries out of ``--throws`` and the height lost per condition and
policy, the training's figures).

A throw counts as **recovered** when the quad was upright, slow and calm at some step
(:func:`bfsitl.gym.tasks.recovered`) and the episode then ran to its end without a crash.
``--smoke`` trains for a few hundred steps and throws twice: CI runs it to show the pipeline
works, not that anything is learned.
"""

from __future__ import annotations

import argparse
import csv
import functools
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import train_hover as shared  # noqa: E402  (the training machinery both examples use)

import bfsitl.gym  # noqa: E402, F401  (registers the environments)
from bfsitl.backend.disturbances import Disturbances  # noqa: E402
from bfsitl.backend.options import World  # noqa: E402
from bfsitl.gym.baseline import hand_policy, hover_stick  # noqa: E402
from bfsitl.gym.env import MODES, DisturbanceHook, RecoverEnv  # noqa: E402
from bfsitl.gym.random_vehicle import RandomVehicle  # noqa: E402
from bfsitl.gym.random_wind import RandomWind  # noqa: E402
from bfsitl.gym.scaled import ScaledEnv, StickLimits  # noqa: E402
from bfsitl.gym.throws import Throw  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics.params import QuadParams  # noqa: E402
from bfsitl.physics.wind import Wind  # noqa: E402
from bfsitl.vehicles import load_vehicle  # noqa: E402

#: A recovery needs the throttle from idle (thrust pushes an inverted quad down) to full, and
#: in rate mode the roll and pitch sticks' whole travel (the FC's full rates).  In ANGLE mode
#: the FC rights the quad itself: the hover's tilt limit is kept (with the whole travel, 60
#: degree tilts, 70 of 100 throws recovered against 100 of 100 by the hand-written policy).
RECOVERY_LIMITS = {
    "acro": StickLimits(tilt_stick=1.0, throttle_span=1.0),
    "angle": StickLimits(tilt_stick=0.4, throttle_span=1.0),
}
#: The evaluation's seeds start here: training draws its own, never these.
EVAL_SEED = 20_000
#: What every policy is also thrown in, never met in training: wind from the north with
#: gusts, and motor 1 giving three quarters of its thrust.
WIND = Wind.from_direction(3.0, 0.0, 1.5)
WEAK_MOTOR, WEAK_FRACTION = 1, 0.75
TRAINING_EPISODE_S = 4.0


def world(
    args: argparse.Namespace, wind: Wind | None = None, quad: QuadParams | None = None
) -> World:
    """``--vehicle``'s physics (or ``quad``), in still air or ``wind``."""
    return World(quad=load_vehicle(args.vehicle) if quad is None else quad, wind=wind)


def weak_motor(surface: Disturbances, _time_s: float) -> None:
    surface.set_motor_thrust(WEAK_MOTOR, WEAK_FRACTION)


#: Each evaluation condition's wind and disturbance hook, by the name the outputs give it.
CONDITIONS: dict[str, tuple[Wind | None, DisturbanceHook | None]] = {
    "still air": (None, None),
    "wind 3 m/s, gusts 1.5 m/s": (WIND, None),
    "motor 1 at 75 %": (None, weak_motor),
}
#: The condition of each of ``--eval-vehicles``: that quad, in still air.
ON_VEHICLE = "{name}, still air"


def conditions(args: argparse.Namespace) -> dict[str, tuple[QuadParams, Wind | None, Any]]:
    """Each evaluation condition's quad, wind and hook: CONDITIONS with ``--vehicle``, then
    each of ``--eval-vehicles`` in still air."""
    quad = load_vehicle(args.vehicle)
    chosen = {name: (quad, wind, hook) for name, (wind, hook) in CONDITIONS.items()}
    for name in args.eval_vehicles.split(",") if args.eval_vehicles else ():
        other = load_vehicle(name)
        chosen[ON_VEHICLE.format(name=other.name)] = (other, None, None)
    return chosen


def evaluation_env(
    args: argparse.Namespace,
    condition: tuple[QuadParams, Wind | None, DisturbanceHook | None],
    number: int,
) -> RecoverEnv:
    """An environment for the evaluation's throws in ``condition`` (of :func:`conditions`)."""
    quad, wind, disturbances = condition
    return RecoverEnv(
        sitl=SitlLaunch(firmware=args.firmware, workdir=args.out / "sitl" / f"eval{number}"),
        control_hz=args.control_hz,
        max_episode_steps=round(TRAINING_EPISODE_S * args.control_hz),
        mode=args.mode,
        throw=throw_range(args),
        world=world(args, wind, quad),
        disturbances=disturbances,
    )


def throw_range(args: argparse.Namespace) -> Throw:
    return Throw(
        height_m=args.height_m,
        max_tilt_deg=args.max_tilt_deg,
        max_speed_m_s=args.max_speed_m_s,
        max_rate_deg_s=args.max_rate_deg_s,
    )


def throw_many(
    policy: shared.Policy, env: RecoverEnv, seed: int, count: int, *, scaled: bool
) -> list[dict[str, Any]]:
    """``count`` throws in a row from ``seed`` (the first reset seeded, the rest drawn from
    it, as training's are), each flown to its end by ``policy``."""
    flown: Any = ScaledEnv(env, RECOVERY_LIMITS[env.mode]) if scaled else env
    results = []
    for number in range(count):
        observation, info = flown.reset(seed=seed if number == 0 else None)
        throw, total = info["throw"], 0.0
        while True:
            observation, reward, terminated, truncated, info = flown.step(policy(observation))
            total += reward
            if terminated or truncated:
                break
        step = info["recovered_step"] if info["recovered"] else None
        results.append(
            {
                "throw": number,
                **{key: round(value, 2) for key, value in throw.items()},
                "recovered": step is not None and info["ended_because"] is None,
                "recovered_after_s": None if step is None else round(step / env.control_hz, 2),
                "height_lost_m": round(info["height_lost_m"], 2),
                "ended_because": info["ended_because"],
                "return": round(total, 1),
            }
        )
    return results


def summarise(results: list[dict[str, Any]]) -> dict[str, Any]:
    """Recoveries out of the throws, and the height lost and time taken by those recovered."""
    recovered = [r for r in results if r["recovered"]]
    upside_down = [r for r in results if r["tilt_deg"] >= 90.0]

    def quantiles(values: list[float]) -> dict[str, float] | None:
        if not values:
            return None
        median, p90 = np.percentile(values, [50, 90])
        return {"median": round(float(median), 2), "p90": round(float(p90), 2)}

    return {
        "recovered": len(recovered),
        "throws": len(results),
        "recovered_past_90_deg": sum(r["recovered"] for r in upside_down),
        "throws_past_90_deg": len(upside_down),
        "height_lost_m": quantiles([r["height_lost_m"] for r in recovered]),
        "recovered_after_s": quantiles([r["recovered_after_s"] for r in recovered]),
    }


def judge_checkpoints(args: argparse.Namespace, env: RecoverEnv, seed: int) -> list[dict[str, Any]]:
    verdicts = []
    for path in sorted((args.out / "checkpoints").glob("*.zip"), key=shared.checkpoint_wall_s):
        model = shared.model_class(args.method).load(path, device="cpu")
        results = throw_many(
            shared.learned_policy(model), env, seed, args.checkpoint_throws, scaled=True
        )
        summary = summarise(results)
        verdicts.append(
            {
                "checkpoint": path.name,
                "wall_s": shared.checkpoint_wall_s(path),
                "flights": len(results),
                "held": summary["recovered"],
                "height_lost_m": summary["height_lost_m"],
            }
        )
        print(
            f"[evaluate] {path.name}: recovered {summary['recovered']} of {len(results)}, "
            f"height lost {summary['height_lost_m']}",
            flush=True,
        )
    return verdicts


def yardsticks_for(exported: shared.Policy, quad: QuadParams) -> dict[str, shared.Policy]:
    """The learned policy and the two yardsticks, which know ``quad``'s hover throttle (the
    learned one does not: it was exported with the training's throttle centre)."""
    hover = hover_stick(quad)
    return {
        # The exported file, as it would fly anywhere: the raw observation in, the sticks out.
        "learned": exported,
        "sticks centred, hover throttle": lambda _o: np.array(
            [0.0, 0.0, hover, 0.0], dtype=np.float32
        ),
        "hand-written hover": functools.partial(hand_policy, hover_throttle=hover),
    }


def export(model: Any, args: argparse.Namespace) -> Any:
    from bfsitl.gym.onnx_policy import OnnxPolicy
    from bfsitl.gym.policy_export import export_policy

    path = export_policy(
        model,
        args.out / "policy.onnx",
        limits=RECOVERY_LIMITS[args.mode],
        hover_throttle=hover_stick(world(args).quad),
        control_hz=args.control_hz,
        mode=args.mode,
        description=f"bfsitl/Recover-v0 ({args.mode}), {args.method.upper()}, "
        f"examples/train_recover.py",
    )
    return OnnxPolicy(path)


def parse_args() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    shared.add_learner_arguments(
        parser,
        control_hz=100.0,
        gamma=0.98,
        lr_schedule="linear",
        minutes=10.0,
        checkpoint_s=60.0,
        n_steps=1024,
    )
    parser.add_argument("--mode", choices=MODES, default="acro", help="the FC's flight mode")
    parser.add_argument(
        "--vehicle", default="iris", help="a vehicle's name (bfsitl vehicles) or profile file"
    )
    parser.add_argument(
        "--vehicles",
        default=None,
        metavar="NAME,NAME,...",
        help="train on a quad drawn per episode from these names or profile files (--vehicle "
        "stays the throttle centre and the evaluation's quad)",
    )
    parser.add_argument("--mass-spread", type=float, default=0.0, help="with --vehicles")
    parser.add_argument("--thrust-spread", type=float, default=0.0, help="with --vehicles")
    parser.add_argument(
        "--eval-vehicles",
        default=None,
        metavar="NAME,FILE,...",
        help="also throw the policy on these quads, in still air (e.g. one training never "
        "flew: a bfsitl log fit profile)",
    )
    parser.add_argument("--throws", type=int, default=100, help="the final evaluation's throws")
    parser.add_argument("--checkpoint-throws", type=int, default=20)
    parser.add_argument("--height-m", type=float, default=Throw.height_m)
    parser.add_argument("--max-tilt-deg", type=float, default=Throw.max_tilt_deg)
    parser.add_argument("--max-speed-m-s", type=float, default=Throw.max_speed_m_s)
    parser.add_argument("--max-rate-deg-s", type=float, default=Throw.max_rate_deg_s)
    parser.add_argument(
        "--train-wind-m-s",
        type=float,
        default=0.0,
        help="train in a wind drawn per episode up to this speed (and gusts up to half of "
        "it), from any direction (default 0: still air)",
    )
    parser.add_argument("--out", type=Path, default=Path("recover-run"))
    parser.add_argument("--smoke", action="store_true", help="a few hundred steps, two throws")
    parser.add_argument(
        "--resume",
        type=Path,
        default=None,
        metavar="DIR",
        help="go on training the policy.zip an earlier run left in DIR (e.g. in wind, "
        "from a policy that learned in still air)",
    )
    parser.add_argument(
        "--evaluate-only",
        action="store_true",
        help="do not train: throw the policy.zip an earlier run left in --out",
    )
    args = parser.parse_args()
    if args.learning_rate is None:
        args.learning_rate = 5e-4 if args.method == "ppo" else 1e-3
    # What examples/train_hover.py's training reads.
    args.env_id, args.episode_s = "bfsitl/Recover-v0", TRAINING_EPISODE_S
    args.limits = RECOVERY_LIMITS[args.mode]
    args.env_options = {"mode": args.mode, "throw": throw_range(args), "world": world(args)}
    if args.train_wind_m_s > 0.0:
        args.env_options["random_wind"] = RandomWind(
            max_speed_m_s=args.train_wind_m_s, max_gust_m_s=args.train_wind_m_s / 2.0
        )
    if args.vehicles:
        args.env_options["random_vehicle"] = RandomVehicle.named(
            *args.vehicles.split(","),
            mass_spread=args.mass_spread,
            thrust_spread=args.thrust_spread,
        )
    if args.smoke:
        args.steps, args.n_steps, args.throws, args.checkpoint_throws = 256, 64, 2, 1
        args.minutes, args.checkpoint_s = 0.0, 1e9
    return args


def main() -> int:
    args = parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    model, episodes, train_s = shared.train_or_load(args)
    # The curve first, so that nothing of the training is lost if a throw fails; again with
    # the checkpoints' verdicts at the end.
    title = (
        f"bfsitl/Recover-v0 ({args.mode}, {args.vehicle}) through Betaflight 4.6.0 "
        f"({args.method.upper()})"
    )
    shared.write_curve(episodes, [], args.out, title)
    exported = export(model, args)
    seed = EVAL_SEED + args.seed * 1000
    results: dict[str, dict[str, list[dict[str, Any]]]] = {}
    verdicts: list[dict[str, Any]] = []
    for number, (condition, quad_wind_hook) in enumerate(conditions(args).items()):
        yardsticks = yardsticks_for(exported, quad_wind_hook[0])
        env = evaluation_env(args, quad_wind_hook, number)
        try:
            if number == 0:
                verdicts = judge_checkpoints(args, env, seed)
            results[condition] = {
                name: throw_many(policy, env, seed, args.throws, scaled=False)
                for name, policy in yardsticks.items()
            }
        finally:
            env.close()
        for name, flown in results[condition].items():
            print(f"[throws] {condition}, {name}: {summarise(flown)}", flush=True)
    with (args.out / "throws.csv").open("w", newline="") as file:
        rows = [
            {"condition": condition, "policy": name, **row}
            for condition, by_policy in results.items()
            for name, flown in by_policy.items()
            for row in flown
        ]
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    shared.write_curve(episodes, verdicts, args.out, title, verdict_label="throws recovered")
    summary = {
        "training": {
            **shared.training_figures(args, model, episodes, train_s),
            "mode": args.mode,
            "vehicle": args.vehicle,
            "throw": vars(throw_range(args)),
            "train_wind_m_s": args.train_wind_m_s,
            "vehicles": args.vehicles.split(",") if args.vehicles else [args.vehicle],
            "mass_spread": args.mass_spread,
            "thrust_spread": args.thrust_spread,
        },
        "evaluation_seed": seed,
        "criterion": "upright within 20 deg, slower than 1 m/s and 1 rad/s at once, then no "
        "crash to the episode's end (4 s)",
        "checkpoints": verdicts,
        "evaluation": {
            condition: {name: summarise(flown) for name, flown in by_policy.items()}
            for condition, by_policy in results.items()
        },
    }
    shared.write_summary(args.out, summary, exported, ("training", "evaluation"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
