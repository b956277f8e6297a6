"""Train a hover policy through the real Betaflight with Stable-Baselines3 PPO (CPU torch).

    pip install 'bfsitl[sitl,gym]' stable-baselines3 torch
    bfsitl firmware build --gps --lockstep
    python examples/train_hover.py --envs 2 --steps 300000 --out hover-run/

What it writes in ``--out``:

* ``learning_curve.csv`` and ``learning_curve.png``: each training episode's return and
  length, in the order they ended, with a moving average;
* ``policy.zip`` and ``vecnormalize.pkl``: the trained policy and its observation scaling;
* ``evaluation.csv``, ``evaluation.png`` and ``evaluation.json``: one evaluation flight of
  ``--eval-s`` seconds, with the same columns and plot as ``bfsitl fly`` writes. The JSON holds
  the distance to the target over the last 10 s, next to a random policy's and the
  hand-written one's (``bfsitl.gym.baseline``) on the same seed.

``--smoke`` trains for a few hundred steps and evaluates for 2 s. CI runs it to show that the
pipeline works; it does not show that the policy learns.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import bfsitl.gym  # noqa: F401  (registers the environments)
from bfsitl.gym.baseline import hand_policy
from bfsitl.gym.env import DEFAULT_FIRMWARE, HoverEnv
from bfsitl.gym.recording import EpisodeRecorder
from bfsitl.mission.session import SitlLaunch

#: The evaluation's verdict: the distance to the target over its last seconds.
HOLD_WINDOW_S = 10.0
HOLD_WITHIN_M = 0.3
#: The training episodes' length: Hover-v0's 10 s, whatever the control rate (the
#: environment's limit counts steps).
TRAINING_EPISODE_S = 10.0


def make_env(firmware: str, control_hz: float, rank: int, out: Path) -> Callable[[], object]:
    def make() -> object:
        from stable_baselines3.common.monitor import Monitor

        # In a SubprocVecEnv worker each environment claims a core of its own for itself and
        # its SITL (HoverEnv's pin_core): the workers do not take each other's time.
        return Monitor(
            HoverEnv(
                sitl=SitlLaunch(firmware=firmware, workdir=out / "sitl" / f"env{rank}"),
                control_hz=control_hz,
                max_episode_steps=round(TRAINING_EPISODE_S * control_hz),
            )
        )

    return make


def train(args: argparse.Namespace) -> tuple[object, object, list[tuple[float, int, float]]]:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import SubprocVecEnv, VecNormalize

    # One thread for the learner: a network this small gains nothing from a second, and
    # torch's idle threads would spin on the cores the environments are pinned to.
    torch.set_num_threads(1)
    workers = SubprocVecEnv(
        [make_env(args.firmware, args.control_hz, rank, args.out) for rank in range(args.envs)],
        start_method="fork",
    )
    if args.resume:
        envs = VecNormalize.load(str(args.resume / "vecnormalize.pkl"), workers)
        episodes = read_curve(args.resume)
    else:
        envs = VecNormalize(workers, norm_obs=True, norm_reward=True, clip_obs=10.0)
        episodes = []
    started = time.monotonic()
    already_s = episodes[-1][2] if episodes else 0.0

    deadline = started + args.minutes * 60.0 if args.minutes else math.inf

    def learning_rate(remaining: float) -> float:
        """3e-4 falling to zero over the run (its steps, or its minutes when bounded): the
        last updates refine instead of undoing."""
        if args.minutes:
            remaining = max(0.0, deadline - time.monotonic()) / (args.minutes * 60.0)
        return 3e-4 * max(remaining, 0.02)

    class Curve(BaseCallback):
        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    episodes.append(
                        (
                            info["episode"]["r"],
                            info["episode"]["l"],
                            already_s + time.monotonic() - started,
                        )
                    )
                    if len(episodes) % 20 == 0:
                        recent = [r for r, _l, _t in episodes[-20:]]
                        print(
                            f"[train] {self.num_timesteps} steps, {len(episodes)} episodes, "
                            f"mean return of the last 20: {np.mean(recent):.1f}",
                            flush=True,
                        )
            return time.monotonic() < deadline  # --minutes: stop training then

    if args.resume:
        model = PPO.load(
            args.resume / "policy.zip",
            env=envs,
            device="cpu",
            custom_objects={"learning_rate": learning_rate, "lr_schedule": learning_rate},
        )
    else:
        # A narrower start than SB3's (std 1 on a [-1, 1] stick crashes at once), two small
        # layers.
        model = PPO(
            "MlpPolicy",
            envs,
            n_steps=args.n_steps,
            batch_size=256,
            learning_rate=learning_rate,
            gamma=args.gamma,
            gae_lambda=0.95,
            ent_coef=0.0,
            seed=args.seed,
            verbose=0,
            policy_kwargs={"log_std_init": -1.0, "net_arch": [64, 64]},
            device="cpu",
        )
    # SB3 makes an empty SB3-<date> folder in the temporary directory on every learn() unless
    # it is given a logger: one that writes nothing leaves nothing behind.
    model.set_logger(Logger(folder=None, output_formats=[]))
    try:
        model.learn(
            total_timesteps=args.steps, callback=Curve(), reset_num_timesteps=not args.resume
        )
    finally:
        model.save(args.out / "policy.zip")
        envs.save(str(args.out / "vecnormalize.pkl"))
        envs.close()
    return model, envs, episodes


def read_curve(folder: Path) -> list[tuple[float, int, float]]:
    """The episodes of an earlier run's learning_curve.csv (none if it has none)."""
    path = folder / "learning_curve.csv"
    if not path.exists():
        return []
    with path.open(newline="") as file:
        return [
            (float(row["return"]), int(row["length_steps"]), float(row["wall_s"]))
            for row in csv.DictReader(file)
        ]


def write_curve(episodes: list[tuple[float, int, float]], out: Path) -> None:
    with (out / "learning_curve.csv").open("w", newline="") as file:
        writer = csv.writer(file)
        writer.writerow(["episode", "return", "length_steps", "wall_s"])
        for number, (ret, length, wall_s) in enumerate(episodes, start=1):
            writer.writerow([number, f"{ret:.3f}", length, f"{wall_s:.1f}"])
    if not episodes:
        return
    from bfsitl.headless_pyplot import load_pyplot

    plt = load_pyplot()
    returns = np.array([r for r, _l, _t in episodes])
    window = max(1, min(50, len(returns) // 10))
    smooth = np.convolve(returns, np.ones(window) / window, mode="valid")
    figure, axis = plt.subplots(figsize=(8, 4))
    axis.plot(returns, ".", alpha=0.3, label="episode return")
    axis.plot(np.arange(window - 1, len(returns)), smooth, label=f"mean of {window}")
    axis.set_xlabel("training episode")
    axis.set_ylabel("return")
    axis.set_title("bfsitl/Hover-v0 through Betaflight 4.6.0 (PPO)")
    axis.legend()
    figure.tight_layout()
    figure.savefig(out / "learning_curve.png", dpi=100)
    plt.close(figure)


def fly(
    policy: Callable[[np.ndarray], np.ndarray],
    firmware: str,
    control_hz: float,
    seed: int,
    seconds: float,
    workdir: Path,
    recorder: EpisodeRecorder | None = None,
) -> dict[str, object]:
    """One evaluation flight; the distances over its last HOLD_WINDOW_S seconds."""
    env = HoverEnv(
        sitl=SitlLaunch(firmware=firmware, workdir=workdir),
        control_hz=control_hz,
        max_episode_steps=round(seconds * control_hz),
    )
    try:
        observation, info = env.reset(seed=seed)
        distances: list[tuple[float, float]] = []
        total = 0.0
        while True:
            action = policy(observation)
            observation, reward, terminated, truncated, info = env.step(action)
            total += reward
            distances.append((info["time_s"], info["distance_m"]))
            if recorder is not None:
                recorder.record(env, action)
            if terminated or truncated:
                break
    finally:
        env.close()
    window = [d for t, d in distances if t >= seconds - HOLD_WINDOW_S]
    return {
        "return": round(total, 2),
        "flown_s": round(info["time_s"], 2),
        "ended_because": info["ended_because"],
        "last_10s_max_distance_m": round(max(window), 3) if window else None,
        "last_10s_rms_distance_m": round(math.sqrt(np.mean(np.square(window))), 3)
        if window
        else None,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--firmware", default=DEFAULT_FIRMWARE)
    parser.add_argument("--envs", type=int, default=2)
    parser.add_argument(
        "--control-hz",
        type=float,
        default=50.0,
        help="the policy's rate (50 Hz: each step sees more of the flight)",
    )
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--n-steps", type=int, default=1024, help="PPO rollout per env")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--minutes",
        type=float,
        default=None,
        help="stop training after this much wall time (then evaluate)",
    )
    parser.add_argument("--eval-s", type=float, default=15.0)
    parser.add_argument(
        "--eval-seeds",
        type=int,
        default=5,
        help="fly the trained policy from this many starts and targets; the "
        "first is recorded and compared with the other policies",
    )
    parser.add_argument("--out", type=Path, default=Path("hover-run"))
    parser.add_argument(
        "--resume",
        type=Path,
        default=None,
        metavar="DIR",
        help="go on training the policy an earlier run left in DIR (its "
        "policy.zip, vecnormalize.pkl and learning curve)",
    )
    parser.add_argument(
        "--evaluate",
        type=Path,
        default=None,
        metavar="DIR",
        help="no training: evaluate the policy an earlier run left in DIR "
        "(the evaluation files go to --out)",
    )
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="a few hundred steps: the pipeline works, nothing is learned",
    )
    args = parser.parse_args()
    if args.smoke:
        args.steps, args.n_steps, args.eval_s, args.eval_seeds = 256, 64, 2.0, 1
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    if args.evaluate:
        from stable_baselines3 import PPO

        model, episodes = (
            PPO.load(args.evaluate / "policy.zip", device="cpu"),
            read_curve(args.evaluate),
        )
        policy_dir = args.evaluate
    else:
        model, _envs, episodes = train(args)
        write_curve(episodes, args.out)
        policy_dir = args.out
    train_s = time.monotonic() - started

    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    scaling = VecNormalize.load(
        str(policy_dir / "vecnormalize.pkl"),
        DummyVecEnv(
            [lambda: HoverEnv(sitl=SitlLaunch(firmware=args.firmware), control_hz=args.control_hz)]
        ),
    )
    scaling.training = False
    scaling.venv.close()

    def learned(observation: np.ndarray) -> np.ndarray:
        action, _state = model.predict(scaling.normalize_obs(observation), deterministic=True)
        return np.asarray(action, dtype=np.float32)

    random_actions = np.random.default_rng(args.seed)
    eval_seed = 10_000 + args.seed
    recorder = EpisodeRecorder(args.out / "evaluation.csv")
    evaluation = (
        args.firmware,
        args.control_hz,
        eval_seed,
        args.eval_s,
        args.out / "sitl" / "eval",
    )
    try:
        results = {
            "learned": fly(learned, *evaluation, recorder),
            "random": fly(
                lambda _o: random_actions.uniform(-1, 1, 4).astype(np.float32), *evaluation
            ),
            "hand-written": fly(hand_policy, *evaluation),
        }
    finally:
        recorder.close()
    recorder.plot(args.out / "evaluation.png", title="bfsitl/Hover-v0: the trained policy")
    # More starts and targets than the recorded one: each seed draws its own target.
    others = [
        fly(
            learned,
            args.firmware,
            args.control_hz,
            eval_seed + number,
            args.eval_s,
            args.out / "sitl" / "eval",
        )
        for number in range(1, max(1, args.eval_seeds))
    ]
    every = [results["learned"], *others]
    held = [
        result
        for result in every
        if result["flown_s"] >= args.eval_s - 0.1
        and result["last_10s_max_distance_m"] is not None
        and result["last_10s_max_distance_m"] <= HOLD_WITHIN_M
    ]
    learned_max = results["learned"]["last_10s_max_distance_m"]
    summary = {
        "training": {
            "steps": int(model.num_timesteps),
            "envs": args.envs,  # type: ignore[attr-defined]
            "episodes": len(episodes),
            "wall_s": None if args.evaluate else round(train_s, 1),
            "firmware": args.firmware,
            "control_hz": args.control_hz,
            # With --resume: the earlier runs' training time too.
            "total_wall_s": round(episodes[-1][2] if episodes else train_s, 1),
            "resumed_from": str(args.resume) if args.resume else None,
            "evaluated_from": str(args.evaluate) if args.evaluate else None,
        },
        "evaluation": results,
        "learned_on_every_seed": {
            "seeds": [eval_seed + number for number in range(len(every))],
            "last_10s_max_distance_m": [result["last_10s_max_distance_m"] for result in every],
            "held_within_0_3_m": f"{len(held)} of {len(every)}",
        },
        "holds_within_0_3_m_for_10_s": (
            learned_max is not None
            and results["learned"]["flown_s"] >= args.eval_s - 0.1
            and learned_max <= HOLD_WITHIN_M
        ),
    }
    (args.out / "evaluation.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
