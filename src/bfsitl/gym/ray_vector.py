"""The learning environment on a Ray cluster: one Ray actor per environment, each with its
SITL on the actor's node, stepped together like :class:`~bfsitl.gym.vector.FlightVectorEnv`.

    envs = RayVectorEnv("bfsitl.gym.env:HoverEnv", num_envs=8, address="HEAD:6379",
                        control_hz=100)

It is a :class:`FlightVectorEnv` whose workers are Ray actors instead of forked processes:
the same observations, rewards, flags and info (``final_obs`` / ``final_info`` at an
episode's end, Gymnasium's ``SAME_STEP`` autoreset), the same step in each environment (the
actor runs the worker's own code, :func:`~bfsitl.gym.vector.handle_command`). The firmware
travels as scenario runs' does (:mod:`bfsitl.sitl.firmware_parcel`): the driver ships the
build once, by its hash, and each node keeps it. An actor takes one CPU of its node and pins
its environment and SITL to a core there; the nodes need ``bfsitl[ray,gym]``, nothing else.

A step costs a Ray call per environment on top of the flight (about a millisecond on one
machine), so it pays when the environments are spread over machines: the aggregate grows
with the nodes. A lost actor (its node gone) is an error that names the environment; make a
new vector environment to go on.
"""

from __future__ import annotations

import dataclasses
import traceback
from importlib import import_module
from typing import Any

import numpy as np

from bfsitl.errors import EnvironmentConfigError
from bfsitl.gym.env import DEFAULT_FIRMWARE, DEFAULT_SITL
from bfsitl.gym.option_checks import check_group
from bfsitl.gym.vector import (
    _DONE,
    _FAILED,
    _READY,
    _STEP,
    FlightVectorEnv,
    _Shared,
    _sort_answer,
    handle_command,
)
from bfsitl.mission.session import SitlLaunch
from bfsitl.sitl.firmware_parcel import FirmwareParcel, pack_firmware, unpack_firmware

#: How long close() waits for the actors to close their SITLs.
_CLOSE_WAIT_S = 30.0


class EnvironmentActor:
    """One environment on a node (made remote by :class:`RayVectorEnv`): its firmware from
    the parcel, its numbers in a block of its own, sent back whole after every command."""

    def __init__(
        self, index: int, entry_point: str, options: dict[str, Any], parcel: FirmwareParcel
    ) -> None:
        import ray

        binary = unpack_firmware(parcel, ray.get)
        module_name, class_name = entry_point.split(":")
        self.index = index
        sitl = options.get("sitl", DEFAULT_SITL)
        self.env = getattr(import_module(module_name), class_name)(
            **{**options, "sitl": dataclasses.replace(sitl, firmware=str(binary))}
        )
        self.shared = _Shared(1, bytearray(_Shared.size(1)))

    def ready(self) -> bytes:
        return _READY

    def handle(self, message: bytes, action: np.ndarray | None) -> tuple[bytes, bytes]:
        if action is not None:
            self.shared.actions[0] = action
        try:
            answer = handle_command(self.env, self.shared, 0, message)
        except Exception as exc:  # noqa: BLE001 - reported to the driver, which raises it
            answer = (
                _FAILED
                + (
                    f"environment {self.index}: {type(exc).__name__}: {exc}\n"
                    f"{traceback.format_exc()}"
                ).encode()
            )
        return answer, bytes(self.shared.block)

    def close(self) -> None:
        self.env.close()


class RayVectorEnv(FlightVectorEnv):
    """``num_envs`` copies of ``entry_point`` (``module:Class``) as Ray actors on the cluster
    at ``address``; every other keyword goes to each copy (module docstring)."""

    def __init__(
        self, entry_point: str, num_envs: int = 2, *, address: str = "auto", **options: Any
    ) -> None:
        try:
            import ray
        except ImportError as exc:
            raise EnvironmentConfigError(
                "RayVectorEnv needs Ray: pip install 'bfsitl[ray]'"
            ) from exc
        sitl = options.get("sitl", DEFAULT_SITL)
        check_group("sitl", sitl, SitlLaunch)
        if sitl.workdir is not None:
            raise EnvironmentConfigError(
                "sitl.workdir: a Ray actor's SITL runs in a temporary directory of its node"
            )
        firmware = str(DEFAULT_FIRMWARE if sitl.firmware is None else sitl.firmware)
        self._set_up(num_envs, options)
        self._ray = ray
        self._shared = _Shared(num_envs, bytearray(_Shared.size(num_envs)))
        self._connections = []
        self._processes = []
        self._actors: list[Any] = []
        try:
            ray.init(address=address, log_to_driver=False, ignore_reinit_error=True)
        except (ConnectionError, RuntimeError, ValueError) as exc:
            raise EnvironmentConfigError(
                f"cannot reach the Ray cluster at {address}: {exc}"
            ) from exc
        try:
            parcel = pack_firmware(ray, [firmware])[firmware]
            actor = ray.remote(num_cpus=1, max_restarts=0)(EnvironmentActor)
            self._actors = [
                actor.remote(index, entry_point, options, parcel) for index in range(num_envs)
            ]
            self._gather([a.ready.remote() for a in self._actors], expect=_READY)
        except BaseException:
            self.close()
            raise

    # -- the transport: Ray calls instead of pipes ------------------------------------------
    def _exchange(self, messages: list[bytes]) -> dict[int, tuple[np.ndarray, dict[str, Any]]]:
        try:
            refs = [
                actor.handle.remote(
                    message, self._shared.actions[index].copy() if message == _STEP else None
                )
                for index, (actor, message) in enumerate(zip(self._actors, messages, strict=True))
            ]
            return self._gather(refs, expect=_DONE)
        except BaseException:
            self.close()
            raise

    def _gather(
        self, refs: list[Any], *, expect: bytes
    ) -> dict[int, tuple[np.ndarray, dict[str, Any]]]:
        """Every actor's answer, its numbers copied into this side's block."""
        finals: dict[int, tuple[np.ndarray, dict[str, Any]]] = {}
        failures: list[str] = []
        shared = self._shared
        for index, ref in enumerate(refs):
            try:
                reply = self._ray.get(ref)
            except self._ray.exceptions.RayError as exc:
                failures.append(
                    f"environment {index}: its Ray actor failed or was lost "
                    f"({type(exc).__name__}: {str(exc).splitlines()[0]})"
                )
                continue
            if isinstance(reply, bytes):  # ready
                _sort_answer(index, reply, expect, finals, failures)
                continue
            answer, block = reply
            row = _Shared(1, bytearray(block))
            shared.observations[index] = row.observations[0]
            shared.rewards[index] = row.rewards[0]
            shared.terminated[index] = row.terminated[0]
            shared.truncated[index] = row.truncated[0]
            shared.info[index] = row.info[0]
            _sort_answer(index, answer, expect, finals, failures)
        if failures:
            raise EnvironmentConfigError("; ".join(failures))
        return finals

    def close_extras(self, **kwargs: Any) -> None:
        if self._closed_workers:
            return
        self._closed_workers = True
        ray = self._ray
        try:
            if self._actors:
                closing = [actor.close.remote() for actor in self._actors]
                ray.wait(closing, num_returns=len(closing), timeout=_CLOSE_WAIT_S)
            for actor in self._actors:
                ray.kill(actor)  # its namespace agent ends the SITL with it
        finally:
            ray.shutdown()
