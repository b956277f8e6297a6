"""Train a hover policy through the real Betaflight with Stable-Baselines3 (CPU torch), in minutes.

    pip install torch==2.13.0 'bfsitl[sitl,learn]'   # torch: the CPU build (see pyproject)
    bfsitl firmware build --gps --lockstep
    python examples/train_hover.py --minutes 5 --out hover-run/

The policy sees ``bfsitl/Hover-v0`` through :class:`bfsitl.gym.scaled.ScaledEnv`: observations
scaled to about one, and three actions (roll, pitch, throttle) that move the sticks at most as
far as a hover needs, about the vehicle's hover throttle.  Training runs for ``--minutes`` of
wall time and saves the policy every ``--checkpoint-s`` seconds; then every checkpoint is
flown from ``--eval-seeds`` starts and targets it never saw, and the first one that holds
within 0.3 m for the last 10 s of every flight gives the **time to criterion**.

What it writes in ``--out``:

* ``learning_curve.csv`` and ``learning_curve.png``: each training episode's return against
  wall time, and each checkpoint's flights held out of ``--eval-seeds``;
* ``checkpoints/``: the policy at each checkpoint; ``policy.zip``: the last one, and
  ``policy.onnx``: the same exported (:mod:`bfsitl.gym.policy_export`), observation to sticks,
  which the evaluation flight flies with onnxruntime;
* ``evaluation.csv``, ``evaluation.png`` and ``evaluation.json``: the last policy's
  evaluation flight of ``--eval-s`` seconds (the same columns and plot as ``bfsitl fly``),
  next to a random policy's and the hand-written one's (``bfsitl.gym.baseline``) on the same
  seed; the JSON also holds every checkpoint's verdict and the time to criterion.

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
from typing import Any

import numpy as np

import bfsitl.gym  # noqa: F401  (registers the environments)
from bfsitl.backend.options import World
from bfsitl.gym.baseline import hand_policy, hover_stick
from bfsitl.gym.env import DEFAULT_FIRMWARE, HoverEnv
from bfsitl.gym.observation import OBSERVATION_SIZE
from bfsitl.gym.recording import EpisodeRecorder
from bfsitl.gym.scaled import ScaledEnv
from bfsitl.mission.session import SitlLaunch

#: The verdict on a flight: the distance to the target over its last seconds.
HOLD_WINDOW_S = 10.0
HOLD_WITHIN_M = 0.3
#: The training episodes' length: Hover-v0's 10 s, whatever the control rate (the
#: environment's limit counts steps).
TRAINING_EPISODE_S = 10.0
#: The evaluation's seeds start here: training draws its own, never these.
EVAL_SEED = 10_000
METHODS = ("ppo", "sac", "td3")

Policy = Callable[[np.ndarray], np.ndarray]


def make_envs(args: argparse.Namespace) -> Any:
    """``--envs`` environments of ``args.env_id`` for SB3: bfsitl's vector environment (a
    worker pinned to a core with its SITL each, the numbers in shared memory), seen scaled
    with ``args.limits`` (None: --raw, the environment's own observation and the sticks'
    whole travel, the measured comparison in docs/gym.md); ``args.env_options`` are the
    environment's own (examples/train_recover.py trains through this too)."""
    import gymnasium

    from bfsitl.gym.sb3_vector import Sb3VectorEnv

    return Sb3VectorEnv(
        gymnasium.make_vec(
            args.env_id,
            num_envs=args.envs,
            sitl=SitlLaunch(firmware=args.firmware, workdir=args.out / "sitl" / "train"),
            control_hz=args.control_hz,
            max_episode_steps=round(args.episode_s * args.control_hz),
            **args.env_options,
        ),
        limits=args.limits,
    )


def latency(args: argparse.Namespace) -> Any:
    """``--latency-steps`` and ``--altitude-latency-steps`` as the environment's Latency."""
    from bfsitl.gym.latency import Latency

    return Latency(steps=args.latency_steps, altitude_steps=args.altitude_latency_steps)


def step_range(text: str) -> tuple[int, int]:
    """``LOW-HIGH`` (or one number) of whole control steps."""
    low, _, high = text.partition("-")
    try:
        return (int(low), int(high or low))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected LOW-HIGH, e.g. 0-2") from None


def wall_clock_schedule(
    args: argparse.Namespace, clock: dict[str, float]
) -> Callable[[float], float]:
    """``--learning-rate``, constant or (``--lr-schedule linear``) falling to a twentieth over
    the ``--minutes`` of wall time from ``clock["started"]``: SB3's own schedules count steps,
    and a run bounded by wall time does not know how many it will take."""

    def rate(_progress_remaining: float) -> float:
        if args.lr_schedule == "constant" or not args.minutes or "started" not in clock:
            return float(args.learning_rate)
        elapsed = (time.monotonic() - clock["started"]) / (args.minutes * 60.0)
        return float(args.learning_rate) * max(0.05, 1.0 - elapsed)

    return rate


def new_model(method: str, envs: object, args: argparse.Namespace, clock: dict[str, float]) -> Any:
    """The learner, with the settings the measurements in docs/gym.md chose."""
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.noise import NormalActionNoise

    actions = int(envs.action_space.shape[0])  # type: ignore[attr-defined]
    common: dict[str, Any] = {"gamma": args.gamma, "seed": args.seed, "device": "cpu"}
    net = {"net_arch": [64, 64]}
    if method == "ppo":
        # A narrower start than SB3's (std 0.37 of the scaled stick instead of 1).
        return PPO(
            "MlpPolicy",
            envs,
            n_steps=args.n_steps,
            batch_size=min(256, args.n_steps * args.envs),
            learning_rate=wall_clock_schedule(args, clock),
            policy_kwargs={**net, "log_std_init": -1.0},
            **common,
        )
    off_policy = {
        "learning_rate": wall_clock_schedule(args, clock),
        "buffer_size": 300_000,
        "batch_size": 256,
        "learning_starts": min(1000, args.steps // 2),
        "policy_kwargs": net,
    }
    if method == "sac":
        return SAC("MlpPolicy", envs, **off_policy, **common)
    return TD3(
        "MlpPolicy",
        envs,
        action_noise=NormalActionNoise(np.zeros(actions), np.full(actions, 0.1)),
        **off_policy,
        **common,
    )


def model_class(method: str) -> Any:
    from stable_baselines3 import PPO, SAC, TD3

    return {"ppo": PPO, "sac": SAC, "td3": TD3}[method]


def train(args: argparse.Namespace) -> tuple[Any, list[tuple[float, int, float]]]:
    """Train for ``--minutes`` (or ``--steps``), saving a checkpoint every ``--checkpoint-s``."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger

    # One thread for the learner: a network this small gains nothing from a second, and
    # torch's idle threads would spin on the cores the environments are pinned to.
    torch.set_num_threads(1)
    clock: dict[str, float] = {}
    episodes: list[tuple[float, int, float]] = read_curve(args.resume) if args.resume else []
    already_s = episodes[-1][2] if episodes else 0.0
    checkpoints = args.out / "checkpoints"
    checkpoints.mkdir(parents=True, exist_ok=True)
    if not args.resume:
        for stale in checkpoints.glob("*.zip"):  # an earlier run's, in the same --out
            stale.unlink()
    envs = make_envs(args)
    try:
        if args.resume:
            schedule = wall_clock_schedule(args, clock)
            model = model_class(args.method).load(
                args.resume / "policy.zip",
                env=envs,
                device="cpu",
                custom_objects={"learning_rate": schedule, "lr_schedule": schedule},
            )
        else:
            model = new_model(args.method, envs, args, clock)
    except BaseException:
        envs.close()
        raise
    started = clock["started"] = time.monotonic()
    deadline = started + args.minutes * 60.0 if args.minutes else math.inf
    next_checkpoint = [started + args.checkpoint_s]

    def save_checkpoint(steps: int) -> None:
        wall_s = already_s + time.monotonic() - started
        model.save(checkpoints / f"{wall_s:07.1f}s-{steps}steps.zip")

    class Progress(BaseCallback):
        def _on_step(self) -> bool:
            now = time.monotonic()
            for info in self.locals["infos"]:
                if "episode" in info:
                    episode = info["episode"]
                    episodes.append((episode["r"], episode["l"], already_s + now - started))
            if now >= next_checkpoint[0]:
                next_checkpoint[0] += args.checkpoint_s
                save_checkpoint(self.num_timesteps)
                recent = [r for r, _l, _t in episodes[-20:]]
                print(
                    f"[train] {now - started:.0f} s, {self.num_timesteps} steps, "
                    f"{len(episodes)} episodes, mean return of the last 20: "
                    f"{np.mean(recent) if recent else 0.0:.1f}",
                    flush=True,
                )
            return now < deadline  # --minutes: stop training then

    # SB3 makes an empty SB3-<date> folder in the temporary directory on every learn() unless
    # it is given a logger: one that writes nothing leaves nothing behind.
    model.set_logger(Logger(folder=None, output_formats=[]))
    try:
        model.learn(
            total_timesteps=args.steps, callback=Progress(), reset_num_timesteps=not args.resume
        )
    finally:
        save_checkpoint(model.num_timesteps)
        model.save(args.out / "policy.zip")
        envs.close()
    return model, episodes


def train_or_load(args: argparse.Namespace) -> tuple[Any, list[tuple[float, int, float]], float]:
    """Train (:func:`train`), or with ``--evaluate-only`` load the policy an earlier run left
    in ``--out``: the model, the episodes' curve and the training's wall seconds."""
    if getattr(args, "evaluate_only", False):
        model = model_class(args.method).load(args.out / "policy.zip", device="cpu")
        episodes = read_curve(args.out)
        return model, episodes, episodes[-1][2] if episodes else 0.0
    started = time.monotonic()
    model, episodes = train(args)
    return model, episodes, time.monotonic() - started


def training_figures(
    args: argparse.Namespace, model: Any, episodes: list[tuple[float, int, float]], train_s: float
) -> dict[str, Any]:
    """What every example's evaluation.json says of its training."""
    return {
        "method": args.method,
        "steps": int(model.num_timesteps),
        "envs": args.envs,
        "episodes": len(episodes),
        "wall_s": round(train_s, 1),
        "firmware": args.firmware,
        "control_hz": args.control_hz,
        "seed": args.seed,
        "resumed_from": str(args.resume) if args.resume else None,
    }


def write_summary(
    out: Path, summary: dict[str, Any], exported: Policy | None, shown: tuple[str, ...]
) -> None:
    """``summary`` with the exported policy's inference time, as ``evaluation.json`` in
    ``out``; its ``shown`` keys printed."""
    summary["policy_onnx"] = (
        None
        if exported is None
        else {"file": "policy.onnx", "inference_us_median": round(inference_us(exported), 1)}
    )
    (out / "evaluation.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps({k: summary[k] for k in shown}, indent=2))


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


def checkpoint_wall_s(path: Path) -> float:
    return float(path.name.split("s-", 1)[0])


def write_curve(
    episodes: list[tuple[float, int, float]],
    verdicts: list[dict[str, Any]],
    out: Path,
    title: str,
    verdict_label: str = f"flights held within {HOLD_WITHIN_M} m",
) -> None:
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
    wall_s = np.array([t for _r, _l, t in episodes])
    window = max(1, min(50, len(returns) // 10))
    smooth = np.convolve(returns, np.ones(window) / window, mode="valid")
    figure, axis = plt.subplots(figsize=(8, 4))
    axis.plot(wall_s, returns, ".", alpha=0.3, label="episode return")
    axis.plot(wall_s[window - 1 :], smooth, label=f"mean of {window}")
    axis.set_xlabel("wall time of training, s")
    axis.set_ylabel("return")
    axis.set_title(title)
    if verdicts:
        held = axis.twinx()
        held.plot(
            [v["wall_s"] for v in verdicts],
            [v["held"] for v in verdicts],
            "o-",
            drawstyle="steps-post",
            color="tab:green",
            label=f"checkpoint: {verdict_label}",
        )
        held.set_ylabel(verdict_label, color="tab:green")
        held.set_ylim(-0.2, max(v["flights"] for v in verdicts) + 0.2)
        held.legend(loc="lower right")
    axis.legend(loc="upper left")
    figure.tight_layout()
    figure.savefig(out / "learning_curve.png", dpi=100)
    plt.close(figure)


def fly(
    policy: Policy,
    env: HoverEnv,
    seed: int,
    seconds: float,
    *,
    scaled: bool,
    recorder: EpisodeRecorder | None = None,
) -> dict[str, Any]:
    """One evaluation flight; the distances over its last HOLD_WINDOW_S seconds."""
    flown: Any = ScaledEnv(env) if scaled else env
    observation, info = flown.reset(seed=seed)
    distances: list[tuple[float, float]] = []
    total = 0.0
    while True:
        action = policy(observation)
        observation, reward, terminated, truncated, info = flown.step(action)
        total += reward
        distances.append((info["time_s"], info["distance_m"]))
        if recorder is not None:
            recorder.record(env)
        if terminated or truncated:
            break
    window = [d for t, d in distances if t >= seconds - HOLD_WINDOW_S]
    held = info["time_s"] >= seconds - 0.1 and bool(window) and max(window) <= HOLD_WITHIN_M
    return {
        "return": round(total, 2),
        "flown_s": round(info["time_s"], 2),
        "ended_because": info["ended_because"],
        "last_10s_max_distance_m": round(max(window), 3) if window else None,
        "last_10s_rms_distance_m": round(math.sqrt(np.mean(np.square(window))), 3)
        if window
        else None,
        "held": held,
    }


def export(model: Any, args: argparse.Namespace) -> Any:
    """policy.onnx beside policy.zip, loaded back as it would be anywhere else."""
    from bfsitl.gym.onnx_policy import OnnxPolicy
    from bfsitl.gym.policy_export import export_policy
    from bfsitl.gym.scaled import DEFAULT_LIMITS

    path = export_policy(
        model,
        args.out / "policy.onnx",
        limits=DEFAULT_LIMITS,
        hover_throttle=hover_stick(World().quad),
        control_hz=args.control_hz,
        description=f"bfsitl/Hover-v0, {args.method.upper()}, examples/train_hover.py",
    )
    return OnnxPolicy(path)


def inference_us(policy: Policy, calls: int = 2000) -> float:
    """The median time of one call of ``policy`` on one observation, microseconds."""
    observation = np.zeros(OBSERVATION_SIZE, dtype=np.float32)
    times = []
    for _ in range(calls):
        began = time.perf_counter()
        policy(observation)
        times.append(time.perf_counter() - began)
    return float(np.median(times) * 1e6)


def learned_policy(model: Any) -> Policy:
    def act(observation: np.ndarray) -> np.ndarray:
        action, _state = model.predict(observation, deterministic=True)
        return np.asarray(action, dtype=np.float32)

    return act


def judge_checkpoints(
    args: argparse.Namespace, env: HoverEnv, seeds: list[int]
) -> list[dict[str, Any]]:
    """Every checkpoint flown from every evaluation seed, in the order they were saved."""
    verdicts = []
    for path in sorted((args.out / "checkpoints").glob("*.zip"), key=checkpoint_wall_s):
        policy = learned_policy(model_class(args.method).load(path, device="cpu"))
        flights = [fly(policy, env, seed, args.eval_s, scaled=not args.raw) for seed in seeds]
        verdict = {
            "checkpoint": path.name,
            "wall_s": checkpoint_wall_s(path),
            "flights": len(flights),
            "held": sum(flight["held"] for flight in flights),
            "last_10s_max_distance_m": [f["last_10s_max_distance_m"] for f in flights],
        }
        print(
            f"[evaluate] {path.name}: held {verdict['held']} of {len(flights)}, largest "
            f"distances {verdict['last_10s_max_distance_m']}",
            flush=True,
        )
        verdicts.append(verdict)
    return verdicts


def add_learner_arguments(
    parser: argparse.ArgumentParser,
    *,
    control_hz: float,
    gamma: float,
    lr_schedule: str,
    minutes: float,
    checkpoint_s: float,
    n_steps: int,
) -> None:
    """The options every training example takes (the firmware, the learner and its budget),
    with each example's defaults."""
    parser.add_argument("--firmware", default=DEFAULT_FIRMWARE)
    parser.add_argument("--method", choices=METHODS, default="ppo")
    parser.add_argument("--envs", type=int, default=2)
    parser.add_argument("--control-hz", type=float, default=control_hz, help="the policy's rate")
    parser.add_argument("--gamma", type=float, default=gamma)
    parser.add_argument(
        "--learning-rate",
        type=float,
        default=None,
        help="the learner's step size (default: the example's for PPO, 1e-3 for SAC and TD3)",
    )
    parser.add_argument(
        "--lr-schedule",
        choices=("constant", "linear"),
        default=lr_schedule,
        help="linear: fall to a twentieth over --minutes",
    )
    parser.add_argument("--minutes", type=float, default=minutes, help="wall time of training")
    parser.add_argument("--steps", type=int, default=10**9, help="stop after this many steps")
    parser.add_argument("--checkpoint-s", type=float, default=checkpoint_s)
    parser.add_argument("--n-steps", type=int, default=n_steps, help="PPO rollout per env")
    parser.add_argument("--seed", type=int, default=0)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    # 50 Hz: each step sees more of the flight.
    add_learner_arguments(
        parser,
        control_hz=50.0,
        gamma=0.98,
        lr_schedule="constant",
        minutes=5.0,
        checkpoint_s=30.0,
        n_steps=512,
    )
    parser.add_argument("--eval-s", type=float, default=15.0)
    parser.add_argument(
        "--eval-seeds",
        type=int,
        default=5,
        help="fly each checkpoint from this many starts and targets",
    )
    parser.add_argument(
        "--latency-steps",
        type=step_range,
        default=(0, 0),
        metavar="LOW-HIGH",
        help="the observation this many control steps late, drawn per episode (default "
        "0-0: none; 0-2 trains a policy that flies outside the lockstep: docs/gym.md)",
    )
    parser.add_argument(
        "--altitude-latency-steps",
        type=step_range,
        default=(0, 0),
        metavar="LOW-HIGH",
        help="the height and climb this many steps later again (the barometer's lag; default 0-0)",
    )
    parser.add_argument(
        "--rc-frame-per-step",
        action="store_true",
        help="one RC frame per control step, as a companion computer sends them: the FC "
        "smooths the sticks as it does outside the lockstep (default: a frame in every fdm "
        "packet, no smoothing)",
    )
    parser.add_argument("--out", type=Path, default=Path("hover-run"))
    parser.add_argument(
        "--resume",
        type=Path,
        default=None,
        metavar="DIR",
        help="go on training the policy an earlier run left in DIR (its policy.zip and "
        "learning curve; the same --method)",
    )
    parser.add_argument(
        "--raw",
        action="store_true",
        help="train on the environment's own observation and the sticks' whole travel, "
        "without ScaledEnv (the comparison in docs/gym.md); no policy.onnx",
    )
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="a few hundred steps: the pipeline works, nothing is learned",
    )
    args = parser.parse_args()
    if args.learning_rate is None:
        args.learning_rate = 5e-4 if args.method == "ppo" else 1e-3
    from bfsitl.gym.scaled import DEFAULT_LIMITS

    args.env_id, args.episode_s = "bfsitl/Hover-v0", TRAINING_EPISODE_S
    args.limits = None if args.raw else DEFAULT_LIMITS
    args.env_options = {"latency": latency(args), "rc_frame_per_step": args.rc_frame_per_step}
    if args.smoke:
        args.steps, args.n_steps, args.eval_s, args.eval_seeds = 256, 64, 2.0, 1
        args.minutes, args.checkpoint_s = 0.0, 1e9
    args.out.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    model, episodes = train(args)
    train_s = time.monotonic() - started

    # A policy of raw sticks is not exported (the file's sticks are the scaled policy's).
    exported = None if args.raw else export(model, args)
    seeds = [EVAL_SEED + args.seed * 100 + number for number in range(args.eval_seeds)]
    env = HoverEnv(
        sitl=SitlLaunch(firmware=args.firmware, workdir=args.out / "sitl" / "eval"),
        control_hz=args.control_hz,
        max_episode_steps=round(args.eval_s * args.control_hz),
        latency=latency(args),
        rc_frame_per_step=args.rc_frame_per_step,
    )
    random_actions = np.random.default_rng(args.seed)
    recorder = EpisodeRecorder(args.out / "evaluation.csv")
    try:
        verdicts = judge_checkpoints(args, env, seeds)
        results = {
            # The exported file, as it would fly anywhere: the raw observation in, the sticks out.
            "learned": fly(
                learned_policy(model) if exported is None else exported,
                env,
                seeds[0],
                args.eval_s,
                scaled=False,
                recorder=recorder,
            ),
            "random": fly(
                lambda _o: random_actions.uniform(-1, 1, 4).astype(np.float32),
                env,
                seeds[0],
                args.eval_s,
                scaled=False,
            ),
            "hand-written": fly(hand_policy, env, seeds[0], args.eval_s, scaled=False),
        }
    finally:
        recorder.close()
        env.close()
    title = f"bfsitl/Hover-v0 through Betaflight 4.6.0 ({args.method.upper()})"
    write_curve(episodes, verdicts, args.out, title)
    recorder.plot(args.out / "evaluation.png", title="bfsitl/Hover-v0: the trained policy")
    reached = next((v for v in verdicts if v["held"] == v["flights"]), None)
    summary = {
        "training": {
            **training_figures(args, model, episodes, train_s),
            "latency_steps": list(args.latency_steps),
            "altitude_latency_steps": list(args.altitude_latency_steps),
            "rc_frame_per_step": args.rc_frame_per_step,
            # With --resume: the earlier runs' training time too.
            "total_wall_s": round(episodes[-1][2] if episodes else train_s, 1),
        },
        "criterion": f"within {HOLD_WITHIN_M} m for the last {HOLD_WINDOW_S:g} s of a "
        f"{args.eval_s:g} s flight, on every one of {len(seeds)} unseen seeds",
        "evaluation_seeds": seeds,
        "time_to_criterion_s": reached["wall_s"] if reached else None,
        "checkpoints": verdicts,
        "evaluation": results,
    }
    write_summary(args.out, summary, exported, ("training", "time_to_criterion_s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
