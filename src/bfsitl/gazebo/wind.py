"""Gazebo's own wind, set while it flies: its WindEffects system through ``gz topic``.

The world bfsitl writes for a flight with a wind (:func:`bfsitl.gazebo.world.write_session_world`)
loads WindEffects and lets every link of the quad feel it; the wind is then changed by
publishing a ``gz.msgs.Wind`` on ``/world/<name>/wind``.  That topic carries one velocity:
a constant wind.  Gusts, and a wind for a world started without one, are refused with
:class:`~bfsitl.errors.DisturbanceUnavailableError`, saying what to do instead.
"""

from __future__ import annotations

import re
import signal
from collections.abc import Callable, Mapping
from pathlib import Path

from bfsitl.errors import DisturbanceUnavailableError, GazeboError
from bfsitl.physics.frames import ned_to_enu
from bfsitl.physics.wind import Wind
from bfsitl.sitl.network import Network, ProcessHandle

#: ``gz topic -p`` discovers the subscriber, publishes once and exits within a second or two;
#: ``gz service`` answers in about 0.4 s.
PUBLISH_TIMEOUT_S = 10.0
#: ``gz topic -p`` waits a fixed time for discovery and publishes once: on a busy machine
#: WindEffects can miss it (seen twice in a row here), so the wind Gazebo reports is read
#: back and the message sent again, this many times at most.
PUBLISH_TRIES = 4
#: The wind read back matches the one asked within this (m/s): Gazebo prints doubles.
MATCH_M_S = 1e-3


def wind_message(wind: Wind | None) -> str:
    """The ``gz.msgs.Wind`` text for ``wind`` (ENU, the world's frame; None is still air)."""
    east, north, up = _velocity_enu_m_s(wind)
    return f"linear_velocity: {{x: {east:.6f}, y: {north:.6f}, z: {up:.6f}}}, enable_wind: true"


def _velocity_enu_m_s(wind: Wind | None) -> tuple[float, float, float]:
    """The air's velocity in the world's frame (ENU), m/s; None is still air."""
    return ned_to_enu(wind.velocity_ned_m_s if wind is not None else (0.0, 0.0, 0.0))


class GazeboWind:
    """The wind of one running Gazebo world (see the module docstring)."""

    def __init__(
        self,
        spawn: Callable[[list[str], Path], ProcessHandle],
        gz: Path,
        world_name: str,
        log_dir: Path,
        started_with: Wind | None,
    ) -> None:
        self._spawn = spawn
        self._gz = gz
        self._topic = f"/world/{world_name}/wind"
        self._service = f"/world/{world_name}/wind_info"
        self._log = log_dir / "gazebo-wind.log"
        self._reply = log_dir / "gazebo-wind-info.txt"
        self._felt = started_with is not None
        self._wind = started_with

    @classmethod
    def in_network(
        cls,
        network: Network,
        env: Mapping[str, str],
        gz: Path,
        world_name: str,
        log_dir: Path,
        started_with: Wind | None,
    ) -> GazeboWind:
        def spawn(argv: list[str], log: Path) -> ProcessHandle:
            return network.spawn(argv, log_dir, log, env=env)

        return cls(spawn, gz, world_name, log_dir, started_with)

    @property
    def wind(self) -> Wind | None:
        return self._wind

    def set_wind(self, wind: Wind | None) -> None:
        if not self._felt:
            raise DisturbanceUnavailableError(
                "the wind cannot be disturbed with Gazebo's physics in a flight started "
                "without one: start it with a wind (--wind, or World(wind=Wind()) for still "
                "air) so that bfsitl's world loads WindEffects and the quad's links feel it"
            )
        if wind is not None and wind.gust_std_m_s > 0:
            raise DisturbanceUnavailableError(
                "gusts cannot be disturbed with Gazebo's physics: its wind topic sets a constant "
                "wind (give gust_std_m_s = 0, or use the embedded physics)"
            )
        asked = _velocity_enu_m_s(wind)
        reported: tuple[float, float, float] | None = None
        for _ in range(PUBLISH_TRIES):
            self._run(
                ["topic", "-t", self._topic, "-m", "gz.msgs.Wind", "-p", wind_message(wind)],
                self._log,
            )
            reported = self._reported()
            if all(abs(a - b) <= MATCH_M_S for a, b in zip(asked, reported, strict=True)):
                self._wind = wind
                return
        raise GazeboError(
            f"Gazebo's WindEffects did not take the wind {asked} m/s (ENU) in "
            f"{PUBLISH_TRIES} tries: {self._service} reports {reported}; see {self._log}"
        )

    def _reported(self) -> tuple[float, float, float]:
        """The wind WindEffects blows now (ENU, m/s), from its ``wind_info`` service."""
        self._reply.unlink(missing_ok=True)
        self._run(
            ["service", "-s", self._service, "--reqtype", "gz.msgs.Empty"]
            + ["--reptype", "gz.msgs.Wind", "--timeout", "3000", "--req", ""],
            self._reply,
        )
        return parse_wind_reply(self._reply.read_text(errors="replace"))

    def _run(self, args: list[str], log: Path) -> None:
        process = self._spawn([str(self._gz), *args], log)
        code = process.wait(PUBLISH_TIMEOUT_S)
        if code != 0:
            process.signal_group(signal.SIGKILL)
            raise GazeboError(
                f"gz {args[0]} {args[2]} failed (exit {'timeout' if code is None else code}); "
                f"see {log}"
            )


def parse_wind_reply(text: str) -> tuple[float, float, float]:
    """The ``linear_velocity`` of a ``gz.msgs.Wind`` as ``gz service`` prints it (protobuf
    text: a component that is 0 is left out, so still air is ``linear_velocity {}``)."""
    block = re.search(r"linear_velocity\s*\{([^}]*)\}", text)
    if block is None:
        if "enable_wind" in text:
            return (0.0, 0.0, 0.0)  # the whole velocity left out: still air
        raise GazeboError(f"gz service gave no wind: {text.strip()[:200]!r}")
    values = dict(re.findall(r"([xyz])\s*:\s*(\S+)", block.group(1)))
    try:
        return (
            float(values.get("x", 0.0)),
            float(values.get("y", 0.0)),
            float(values.get("z", 0.0)),
        )
    except ValueError as exc:
        raise GazeboError(f"gz service gave an unreadable wind: {block.group(0)!r}") from exc


def wind_enu_m_s(wind: Wind) -> tuple[float, float, float]:
    """The world file's ``<wind><linear_velocity>`` for a flight started in ``wind``."""
    if wind.gust_std_m_s > 0:
        raise DisturbanceUnavailableError(
            "gusts cannot be disturbed with Gazebo's physics: its WindEffects is given one "
            "constant wind here (give gust_std_m_s = 0, or use the embedded physics)"
        )
    return ned_to_enu(wind.velocity_ned_m_s)
