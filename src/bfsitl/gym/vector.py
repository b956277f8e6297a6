"""Many environments at once, cheaply: one worker process per environment, each pinned to a
core with its SITL, and the numbers of every step passed through shared memory.

    envs = gymnasium.make_vec("bfsitl/Hover-v0", num_envs=2, control_hz=100)

(``make_vec`` picks this class for bfsitl's ids by itself; ``vectorization_mode="async"``
gives Gymnasium's ``AsyncVectorEnv`` instead.)  ``AsyncVectorEnv`` runs the same
environments, but pickles each step's ``info`` through a pipe and merges it key by key in the
parent; with this environment's info (the truth and the FC's state in nested dicts) that is
about a quarter of a millisecond of the parent's time per step, on the same cores the
firmwares need.  Here a step is: the parent writes the actions into shared memory and sends
each worker one byte; each worker steps its environment and writes the observation, the
reward, the flags and the info's numbers back; one message back says it is done.  What is
not a number a step (why an episode ended, the full info with the truth, the FC's flight
modes and blockers) travels only at the end of an episode, in ``info["final_info"]``, with
``info["final_obs"]``: the autoreset is Gymnasium's ``SAME_STEP`` (the observation returned
for an ended episode is the first of the next, as Stable-Baselines3 also expects), and
``final_info`` is batched key by key with ``_key`` masks, as Gymnasium's own vector
environments batch it.

A run directory (``sitl=SitlLaunch(workdir=...)``) becomes one folder per environment below it
(``env0``, ``env1``, ...).
Each step's ``info`` holds, per environment, ``time_s``, ``distance_m``, ``waypoint``,
``armed``, ``failsafe``, the ``target`` (north, east, up) and the truth's ``position_m`` and
``velocity_m_s`` (north, east, up), each with Gymnasium's ``_key`` mask.

With ``render_mode="rgb_array"`` every worker's environment draws its frames
(:mod:`~bfsitl.gym.render`) and :meth:`~FlightVectorEnv.render` returns one per
environment, as Gymnasium's own vector environments do; a frame travels through the pipe,
pickled, only when it is asked for.

The workers are forked by default, as Gymnasium's own vector environments do on Linux;
``context="spawn"`` or ``"forkserver"`` starts fresh interpreters instead (then the options,
a ``disturbances`` hook included, must be picklable, and the script needs the
``if __name__ == "__main__":`` guard).  An option no environment takes is raised when the
vector environment is made.  A worker whose parent dies finds its pipe closed and closes its
environment (and so its SITL); one that is terminated does the same.  Anything that
interrupts a step in the parent (Ctrl-C, a worker's failure) closes the vector environment.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import multiprocessing.connection
import pickle
import signal
import traceback
from importlib import import_module
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from bfsitl.backend.options import Timing
from bfsitl.errors import EnvironmentConfigError
from bfsitl.gym.env import DEFAULT_CONTROL_HZ, DEFAULT_WORLD
from bfsitl.gym.observation import OBSERVATION_SIZE, observation_space
from bfsitl.gym.render import RENDER_MODES, check_render_mode
from bfsitl.mission.session import SitlLaunch

#: The numbers of each step's info, in their slots of the shared block.
INFO_NUMBERS = ("time_s", "distance_m", "waypoint", "armed", "failsafe")
_VECTORS = ("target", "position_m", "velocity_m_s")
_INFO_WIDTH = len(INFO_NUMBERS) + 3 * len(_VECTORS)
#: What the parent says to a worker (a reset carries its seed and options, pickled), and what
#: a worker answers (an ended episode carries its last observation and info, a frame the
#: environment's render() beside an empty info, a failure its message): one pipe message
#: each, so an answer is never half read.
_STEP, _RESET, _RENDER, _CLOSE = b"s", b"r", b"v", b"c"
_READY, _DONE, _ENDED, _FRAME, _FAILED = b"y", b"d", b"e", b"i", b"f"
#: How long close() waits for a worker to end its SITL before it is terminated.
_CLOSE_WAIT_S = 10.0


class _Shared:
    """The numbers of every step, for every environment, in one block of shared memory."""

    def __init__(self, count: int, block: Any) -> None:
        self.block = block
        buffer = memoryview(block).cast("B")
        offset = 0

        def view(dtype: Any, shape: tuple[int, ...]) -> np.ndarray:
            nonlocal offset
            size = int(np.prod(shape)) * np.dtype(dtype).itemsize
            array = np.frombuffer(
                buffer, dtype=dtype, count=int(np.prod(shape)), offset=offset
            ).reshape(shape)
            offset += (size + 7) // 8 * 8
            return array

        self.actions = view(np.float32, (count, 4))
        self.observations = view(np.float32, (count, OBSERVATION_SIZE))
        self.rewards = view(np.float64, (count,))
        self.terminated = view(np.bool_, (count,))
        self.truncated = view(np.bool_, (count,))
        self.info = view(np.float64, (count, _INFO_WIDTH))

    @staticmethod
    def size(count: int) -> int:
        def aligned(nbytes: int) -> int:
            return (nbytes + 7) // 8 * 8

        return (
            aligned(count * 4 * 4)
            + aligned(count * OBSERVATION_SIZE * 4)
            + aligned(count * 8)
            + 2 * aligned(count)
            + aligned(count * _INFO_WIDTH * 8)
        )


def _info_row(info: dict[str, Any]) -> list[float]:
    truth = info["truth"]
    return [
        float(info["time_s"]),
        float(info["distance_m"]),
        float(info["waypoint"]),
        float(info["armed"]),
        float(info["failsafe"]),
        *info["target"],
        truth["north_m"],
        truth["east_m"],
        truth["alt_m"],
        truth["v_north_m_s"],
        truth["v_east_m_s"],
        truth["v_up_m_s"],
    ]


def handle_command(env: Any, shared: _Shared, index: int, message: bytes) -> bytes:
    """One step or reset of one environment: its numbers into row ``index`` of ``shared``,
    and the answer (an ended episode's last observation and info ride in it; the autoreset
    is SAME_STEP), or the frame asked for.  What a worker process and a Ray actor
    (bfsitl.gym.ray_vector) both do."""
    command = message[:1]
    if command == _RENDER:
        # Drawing changes nothing of the flight: the shared numbers stay as they are.
        return _FRAME + pickle.dumps((env.render(), {}))
    if command == _STEP:
        observation, reward, terminated, truncated, info = env.step(shared.actions[index])
        shared.rewards[index] = reward
        shared.terminated[index] = terminated
        shared.truncated[index] = truncated
        answer = _DONE
        if terminated or truncated:
            answer = _ENDED + pickle.dumps((observation, info))
            observation, info = env.reset()
    elif command == _RESET:
        seed, reset_options = pickle.loads(message[1:])
        observation, info = env.reset(seed=seed, options=reset_options)
        answer = _DONE
    else:
        raise EnvironmentConfigError(f"environment {index}: unknown command {command!r}")
    shared.observations[index] = observation
    shared.info[index] = _info_row(info)
    return answer


def _end_on_terminate(_signal: int, _frame: object) -> None:
    raise SystemExit(0)  # so that the worker's finally closes its SITL


def _worker(
    index: int,
    entry_point: str,
    options: dict[str, Any],
    block: Any,
    count: int,
    connection: multiprocessing.connection.Connection,
    parents_ends: list[multiprocessing.connection.Connection],
) -> None:
    """One environment: steps when the parent says, until it says close or goes away."""
    # A forked worker holds copies of the parent's ends of the pipes made so far: closed, so
    # that the parent's death closes this worker's pipe (and the read below ends).
    for end in parents_ends:
        end.close()
    signal.signal(signal.SIGTERM, _end_on_terminate)
    shared = _Shared(count, block)
    env = None
    sitl = options.get("sitl")
    if isinstance(sitl, SitlLaunch) and sitl.workdir is not None:
        # One run directory each: two SITLs must not share an EEPROM file.
        options = {
            **options,
            "sitl": dataclasses.replace(sitl, workdir=Path(sitl.workdir) / f"env{index}"),
        }
    try:
        module_name, class_name = entry_point.split(":")
        env = getattr(import_module(module_name), class_name)(**options)
        connection.send_bytes(_READY)
        while True:
            try:
                message = connection.recv_bytes()
            except (EOFError, OSError):
                break  # the parent is gone: close the SITL and end
            if message[:1] == _CLOSE:
                break
            connection.send_bytes(handle_command(env, shared, index, message))
    except KeyboardInterrupt:
        pass  # Ctrl-C reaches the whole process group: the parent decides what follows
    except Exception as exc:  # noqa: BLE001 - reported to the parent, which raises it
        report = f"environment {index}: {type(exc).__name__}: {exc}\n{traceback.format_exc()}"
        try:
            connection.send_bytes(_FAILED + report.encode())
        except OSError:
            pass  # the parent is gone too
    finally:
        if env is not None:
            env.close()
        connection.close()


class FlightVectorEnv(VectorEnv[np.ndarray, np.ndarray, np.ndarray]):
    """``num_envs`` copies of one environment (``entry_point``, ``module:Class``), stepped
    together; every other keyword goes to each copy (see the module docstring)."""

    metadata: dict[str, Any] = {
        "autoreset_mode": AutoresetMode.SAME_STEP,
        "render_modes": list(RENDER_MODES),
        "render_fps": DEFAULT_CONTROL_HZ,
    }

    def __init__(
        self, entry_point: str, num_envs: int = 2, *, context: str = "fork", **options: Any
    ) -> None:
        self._set_up(num_envs, options)
        mp: Any = multiprocessing.get_context(context)
        self._shared = _Shared(num_envs, mp.RawArray("b", _Shared.size(num_envs)))
        self._connections: list[multiprocessing.connection.Connection] = []
        self._processes: list[Any] = []
        try:
            for index in range(num_envs):
                parent_end, child_end = mp.Pipe()
                forked = context == "fork"
                process = mp.Process(
                    target=_worker,
                    name=f"bfsitl-gym-{index}",
                    daemon=True,
                    args=(
                        index,
                        entry_point,
                        options,
                        self._shared.block,
                        num_envs,
                        child_end,
                        [*self._connections, parent_end] if forked else [],
                    ),
                )
                process.start()
                child_end.close()
                self._connections.append(parent_end)
                self._processes.append(process)
            self._collect(expect=_READY)  # an option no environment takes is raised here
        except BaseException:
            self.close()
            raise

    def _set_up(self, num_envs: int, options: dict[str, Any]) -> None:
        """The count, the spaces and the workers' defaults (pinned, not spinning), checked."""
        if not 1 <= num_envs <= 256:
            raise EnvironmentConfigError(f"num_envs {num_envs} is outside 1..256")
        # Checked here too, so that a wrong mode is said once, not by every worker; the
        # workers' environments get it as an option and draw the frames.
        self.render_mode = options.get("render_mode")
        check_render_mode(self.render_mode)
        self.metadata = {
            **type(self).metadata,
            "render_modes": list(RENDER_MODES),
            "render_fps": options.get("control_hz", DEFAULT_CONTROL_HZ),
        }
        options.setdefault("pin_core", True)
        # Workers share the cores: no spinning unless told (a group given as something else
        # is left for the environment to refuse, with what it takes).
        timing = options.get("timing", Timing())
        if isinstance(timing, Timing) and timing.lockstep_spin is None:
            options["timing"] = dataclasses.replace(timing, lockstep_spin=False)
        self.num_envs = num_envs
        #: The flight's world, the quad in it (every environment's: an adapter reads the
        #: vehicle's hover throttle here without asking a worker).
        self.world = options.get("world", DEFAULT_WORLD)
        self.single_observation_space = observation_space()
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        # The single action space, without making an environment (and a SITL) here.
        self.single_action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._closed_workers = False
        self._reset_once = False

    # -- the vector environment ----------------------------------------------------------------
    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        self._check_open()
        if seed is None or isinstance(seed, int):
            seeds: list[int | None] = (
                [None] * self.num_envs
                if seed is None
                else [seed + index for index in range(self.num_envs)]
            )
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise EnvironmentConfigError(f"{len(seeds)} seeds for {self.num_envs} environments")
        self._exchange([_RESET + pickle.dumps((env_seed, options)) for env_seed in seeds])
        self._reset_once = True
        return self._shared.observations.copy(), self._info()

    def step(
        self, actions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        self._check_open()
        actions = np.asarray(actions, dtype=np.float32)
        if actions.shape != (self.num_envs, 4):
            raise EnvironmentConfigError(
                f"actions are {self.num_envs} x 4 sticks, got shape {actions.shape}"
            )
        self._shared.actions[:] = actions
        finals = self._exchange([_STEP] * self.num_envs)
        shared = self._shared
        info = self._info()
        for index, (observation, env_info) in finals.items():
            info = self._add_info(info, {"final_obs": observation, "final_info": env_info}, index)
        return (
            shared.observations.copy(),
            shared.rewards.copy(),
            shared.terminated.copy(),
            shared.truncated.copy(),
            info,
        )

    def render(self) -> tuple[np.ndarray, ...] | None:
        """Each environment's frame of its last step (:mod:`~bfsitl.gym.render`), or None
        without a ``render_mode``."""
        if self.render_mode is None:
            return None
        self._check_open()
        if not self._reset_once:
            # Refused here: a worker's refusal would close every environment and SITL.
            raise EnvironmentConfigError("render() before reset(): call envs.reset() first")
        frames = self._exchange([_RENDER] * self.num_envs)
        return tuple(frames[index][0] for index in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        if self._closed_workers:
            return
        self._closed_workers = True
        for connection in self._connections:
            try:
                connection.send_bytes(_CLOSE)
            except OSError:
                pass  # that worker has already gone
        for process in self._processes:
            process.join(_CLOSE_WAIT_S)
            if process.is_alive():
                process.terminate()  # its SIGTERM handler still closes the SITL
                process.join(_CLOSE_WAIT_S)
            if process.is_alive():
                process.kill()  # its namespace agent ends the SITL with it
                process.join(1.0)
        for connection in self._connections:
            connection.close()

    # -- parts -------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed_workers:
            raise EnvironmentConfigError("this vector environment is closed: make a new one")

    def _exchange(self, messages: list[bytes]) -> dict[int, tuple[np.ndarray, dict[str, Any]]]:
        """Send each worker its message and collect every answer.  Anything that interrupts
        this (Ctrl-C in the parent only, a failure) closes the environment: half a step's
        answers left in the pipes would be read as the next step's."""
        try:
            for connection, message in zip(self._connections, messages, strict=True):
                try:
                    connection.send_bytes(message)
                except OSError:
                    pass  # a worker that has ended: its answer, or its end, is read below
            return self._collect(expect=_DONE)
        except BaseException:
            self.close()
            raise

    def _collect(self, *, expect: bytes) -> dict[int, tuple[np.ndarray, dict[str, Any]]]:
        """Every worker's answer; the (final observation, info) of episodes that ended.  A
        worker that failed or ended raises here, with its own message."""
        finals: dict[int, tuple[np.ndarray, dict[str, Any]]] = {}
        failures: list[str] = []
        for index, connection in enumerate(self._connections):
            try:
                answer = connection.recv_bytes()
            except (EOFError, OSError):
                process = self._processes[index]
                process.join(1.0)  # the pipe closes a moment before the exit code is known
                failures.append(
                    f"environment {index}: its worker process ended (exit code {process.exitcode})"
                )
                continue
            _sort_answer(index, answer, expect, finals, failures)
        if failures:
            raise EnvironmentConfigError("; ".join(failures))
        return finals

    def _info(self) -> dict[str, Any]:
        numbers = self._shared.info
        info: dict[str, Any] = {}
        for column, name in enumerate(INFO_NUMBERS):
            values = numbers[:, column].copy()
            info[name] = values.astype(bool) if name in ("armed", "failsafe") else values
        first = len(INFO_NUMBERS)
        for number, name in enumerate(_VECTORS):
            info[name] = numbers[:, first + 3 * number : first + 3 * number + 3].copy()
        info["waypoint"] = info["waypoint"].astype(np.int64)
        for name in (*INFO_NUMBERS, *_VECTORS):
            info[f"_{name}"] = np.ones(self.num_envs, dtype=bool)
        return info


def _sort_answer(
    index: int,
    answer: bytes,
    expect: bytes,
    finals: dict[int, tuple[np.ndarray, dict[str, Any]]],
    failures: list[str],
) -> None:
    """An environment's answer: an ended episode's (observation, info), or a frame beside an
    empty info, into ``finals``; a failure's text into ``failures``."""
    kind = answer[:1]
    if kind in (_ENDED, _FRAME):
        finals[index] = pickle.loads(answer[1:])
    elif kind == _FAILED:
        failures.append(answer[1:].decode(errors="replace"))
    elif kind != expect:
        failures.append(f"environment {index}: answered {kind!r}, not {expect!r}")


class HoverVectorEnv(FlightVectorEnv):
    """``bfsitl/Hover-v0``, ``num_envs`` at once (``gymnasium.make_vec(...,
    vectorization_mode="vector_entry_point")``)."""

    def __init__(self, num_envs: int = 2, **options: Any) -> None:
        super().__init__("bfsitl.gym.env:HoverEnv", num_envs, **options)


class WaypointsVectorEnv(FlightVectorEnv):
    """``bfsitl/Waypoints-v0``, ``num_envs`` at once."""

    def __init__(self, num_envs: int = 2, **options: Any) -> None:
        super().__init__("bfsitl.gym.env:WaypointsEnv", num_envs, **options)


class RecoverVectorEnv(FlightVectorEnv):
    """``gymnasium.make_vec("bfsitl/Recover-v0", num_envs=N)``."""

    def __init__(self, num_envs: int = 2, **options: Any) -> None:
        super().__init__("bfsitl.gym.env:RecoverEnv", num_envs, **options)
